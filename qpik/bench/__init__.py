"""``qpik bench``: timings of qpik next to its peers, measured in the same process.

Each module here defines ``TITLE`` and ``run(args) -> list[Row]``, where a row is
a label and a time per call; the CLI prints them with ratios to the
reference row of the same bench.
"""

from __future__ import annotations

import gc
import importlib
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import ModuleType

import numpy as np

BENCHES = ("kinematics", "analytic", "controller", "ik", "nlp", "plan", "batch", "view")


@dataclass
class Row:
    """One measured line: ``seconds`` per call (median), optional p99/worst."""

    label: str
    seconds: float
    ref: str | None = None  # label of the row this one is compared with
    p99: float | None = None
    worst: float | None = None
    note: str = ""


def import_peer(name: str) -> ModuleType:
    """The peer library ``name``, imported with its DeprecationWarnings silenced (the pinocchio that placo pins
    imports hppfcl by its old name, which warns); ImportError as ``import`` raises it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return importlib.import_module(name)


def cycle(fn: Callable[[object], object], items: Sequence) -> Callable[[], object]:
    """A no-argument callable that applies ``fn`` to the next item of ``items`` each call (round robin): the
    single-pose rows time distinct poses, hot."""
    state = {"i": 0}

    def call():
        i = state["i"]
        state["i"] = (i + 1) % len(items)
        return fn(items[i])

    return call


def time_calls(fn: Callable[[], object], repeat: int, warmup: int = 20, block: int = 1) -> np.ndarray:
    """Wall-clock seconds per call of ``fn``: ``repeat`` samples (after ``warmup`` calls), each a block of
    ``block`` calls divided by ``block``."""
    return time_interleaved({"": fn}, repeat, warmup, block=block)[""]


def time_interleaved(
    fns: dict[str, Callable[[], object]],
    repeat: int,
    warmup: int = 20,
    cpu: dict[str, np.ndarray] | None = None,
    block: int = 1,
) -> dict[str, np.ndarray]:
    """Seconds of ``repeat`` calls of each peer, interleaved: one call of every peer per round.

    A busy spell of the machine then falls on every peer alike, so the ratios
    between rows stay meaningful on a shared machine. Python's garbage
    collector is paused while timing (for every peer alike), as a 1 kHz control
    loop in Python would run it: what is timed is the call, not the collector.
    Returns wall-clock seconds; if ``cpu`` is a dict, it is filled with the same
    calls' thread CPU seconds, which leave out the time the host took the CPU away.
    With ``block`` > 1 each sample is a block of that many calls of one peer ("hot"),
    divided by ``block``: for calls of about a µs, whose single timing would be mostly
    the clocks' own cost.
    """
    for _ in range(warmup):
        for fn in fns.values():
            fn()
    out = {label: np.empty(repeat) for label in fns}
    used = {label: np.empty(repeat) for label in fns}
    clock, thread = time.perf_counter, time.thread_time
    items = [(fn, out[label], used[label]) for label, fn in fns.items()]
    calls = range(block)
    enabled = gc.isenabled()
    gc.disable()
    try:
        for i in range(repeat):
            for fn, t, u in items:
                t0, u0 = clock(), thread()
                for _ in calls:
                    fn()
                u[i] = (thread() - u0) / block
                t[i] = (clock() - t0) / block
    finally:
        if enabled:
            gc.enable()
    if cpu is not None:
        cpu.update(used)
    return out


def fmt_time(s: float) -> str:
    if s < 1e-3:
        return f"{s * 1e6:9.2f} µs"
    if s < 1:
        return f"{s * 1e3:9.3f} ms"
    return f"{s:9.3f} s "


def ratio_text(ref_seconds: float, seconds: float, ref: str) -> str:
    """How a row of ``seconds`` compares with its reference ``ref`` of ``ref_seconds``: "N.NNx faster than ref", or
    "N.NNx slower than ref" where it is slower (never a ratio below 1 called faster)."""
    if seconds <= ref_seconds:
        return f"{ref_seconds / seconds:6.2f}x faster than {ref}"
    return f"{seconds / ref_seconds:6.2f}x slower than {ref}"


def render(title: str, rows: list[Row]) -> str:
    """The rows as a text table, with the ratio to each row's reference."""
    by = {r.label: r for r in rows}
    lines = [f"## {title}", f"{'':44} {'median':>12} {'p99':>12} {'worst':>12}  ratio"]
    for r in rows:
        ratio = ""
        if r.ref and r.ref in by:
            ratio = ratio_text(by[r.ref].seconds, r.seconds, r.ref)
        p99 = fmt_time(r.p99) if r.p99 is not None else ""
        worst = fmt_time(r.worst) if r.worst is not None else ""
        lines.append(f"{r.label:44} {fmt_time(r.seconds):>12} {p99:>12} {worst:>12}  {ratio} {r.note}".rstrip())
    return "\n".join(lines)
