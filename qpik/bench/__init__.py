"""``qpik bench``: timings of qpik next to its peers, measured in the same process.

Each module here defines ``TITLE`` and ``run(args) -> list[Row]``, where a row is
a label and a time per call; the CLI prints them with ratios to the
reference row of the same bench.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

BENCHES = ("kinematics", "analytic", "controller")


@dataclass
class Row:
    """One measured line: ``seconds`` per call (median), optional p99/worst."""

    label: str
    seconds: float
    ref: str | None = None  # label of the row this one is compared with
    p99: float | None = None
    worst: float | None = None
    note: str = ""


def time_calls(fn: Callable[[], object], repeat: int, warmup: int = 20) -> np.ndarray:
    """Wall-clock seconds of ``repeat`` calls of ``fn`` (after ``warmup`` calls)."""
    for _ in range(warmup):
        fn()
    out = np.empty(repeat)
    clock = time.perf_counter
    for i in range(repeat):
        t0 = clock()
        fn()
        out[i] = clock() - t0
    return out


def fmt_time(s: float) -> str:
    if s < 1e-3:
        return f"{s * 1e6:9.2f} µs"
    if s < 1:
        return f"{s * 1e3:9.3f} ms"
    return f"{s:9.3f} s "


def render(title: str, rows: list[Row]) -> str:
    """The rows as a text table, with the ratio to each row's reference."""
    by = {r.label: r for r in rows}
    lines = [f"## {title}", f"{'':44} {'median':>12} {'p99':>12} {'worst':>12}  ratio"]
    for r in rows:
        ratio = ""
        if r.ref and r.ref in by:
            ratio = f"{by[r.ref].seconds / r.seconds:6.2f}x faster than {r.ref}"
        p99 = fmt_time(r.p99) if r.p99 is not None else ""
        worst = fmt_time(r.worst) if r.worst is not None else ""
        lines.append(f"{r.label:44} {fmt_time(r.seconds):>12} {p99:>12} {worst:>12}  {ratio} {r.note}".rstrip())
    return "\n".join(lines)
