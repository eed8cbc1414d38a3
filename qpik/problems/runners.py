"""Runners: what ``qpik run`` does with a problem of each kind.

A runner is ``fn(problem, out) -> str``: it solves the :class:`~qpik.problems.schema.Problem`,
may write files (pictures, CSV) under the folder ``out``, and returns the
report as text (Markdown). Modules register runners with the decorator::

    from qpik.problems.runners import runner

    @runner("ik")
    def run_ik(problem: Problem, out: Path) -> str:
        ...

and are listed in :data:`RUNNER_MODULES`, which :func:`get_runner` imports on
first use (so that loading problems does not import every solver).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from pathlib import Path

from qpik.core.errors import QpikError
from qpik.problems.schema import Problem

Runner = Callable[[Problem, Path], str]

#: modules that register runners when imported
RUNNER_MODULES: tuple[str, ...] = ("qpik.problems.ik", "qpik.problems.control", "qpik.problems.plan")

#: kind -> runner, filled by :func:`runner`
RUNNERS: dict[str, Runner] = {}


def runner(kind: str) -> Callable[[Runner], Runner]:
    """Decorator: register ``fn(problem, out) -> report`` as the runner of ``kind``."""

    def register(fn: Runner) -> Runner:
        RUNNERS[kind] = fn
        return fn

    return register


def get_runner(kind: str) -> Runner:
    """The runner of ``kind``, importing :data:`RUNNER_MODULES` first; ``QpikError`` if none."""
    for module in RUNNER_MODULES:
        importlib.import_module(module)
    if kind not in RUNNERS:
        raise QpikError(f"no runner for kind {kind!r} yet (registered: {', '.join(sorted(RUNNERS)) or 'none'})")
    return RUNNERS[kind]


def run_problem(problem: Problem, out: Path) -> str:
    """Solve ``problem`` with the runner of its kind; files go under ``out`` (created). Returns the report."""
    fn = get_runner(problem.kind)
    out.mkdir(parents=True, exist_ok=True)
    return fn(problem, out)
