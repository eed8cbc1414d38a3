"""Bench: the closed form — one pose, a batch of poses, the feasible intervals — beside ssik.

For each arm with a closed form (``nammoto7``: δ, ``iiwa14``: ψ), poses are
``fk(q)`` of configurations drawn uniformly inside the joint limits (seed 0)
and the parameter of each is the one of its configuration. Rows, in seconds
per pose (median over calls):

- ``qpik.ik`` on one pose (all 16 / 8 branches; input checks included);
- ``qpik.ik`` on a batch of ``BATCH`` poses with (N,) parameters, divided by N;
- ``qpik.feasible_intervals`` on one pose (every branch's exact δ/ψ set);
- ``ssik.prebuilt.kuka.iiwa14_ik.solve(T)`` on the same iiwa poses (the
  reference: it enumerates the arm-angle self-motion, so it answers a larger
  question; it is the fastest published analytic iiwa solver we can call).

Targets (issue): single ≤ 50 µs and ≥ 8x faster than ssik; batched ≤ 3 µs/pose;
intervals ≤ 300 µs/pose. Nammoto & Kosuge report 31.3 µs per solution set
(compiled code, Core i7 965, 2012): a note, not a measurement.
"""

from __future__ import annotations

import argparse

import numpy as np

from qpik.analytic.api import feasible_intervals, ik, redundancy_parameter
from qpik.bench import Row, time_calls
from qpik.robots.catalog import load_robot

TITLE = "Closed-form IK (per pose)"
ARMS = ("nammoto7", "iiwa14")
POSES = 64  # distinct poses cycled through by the single-pose rows
BATCH = 10_000
SSIK = "ssik iiwa14_ik.solve (iiwa14)"
PAPER_NOTE = "(paper: 31.3 µs, compiled, 2012 Core i7 965; quoted, not measured)"


def _cycle(fn, items):
    """A no-argument callable that applies ``fn`` to the next item of ``items`` each call."""
    state = {"i": 0}

    def call():
        i = state["i"]
        state["i"] = (i + 1) % len(items)
        return fn(items[i])

    return call


def run(args: argparse.Namespace) -> list[Row]:
    repeat = max(20, int(getattr(args, "repeat", 2000)))
    rows: list[Row] = []
    ssik_row = _ssik_row(repeat)
    if ssik_row is not None:
        rows.append(ssik_row)
    for name in ARMS:
        rows += _arm_rows(name, repeat, SSIK if name == "iiwa14" and ssik_row is not None else None)
    return rows


def _arm_rows(name: str, repeat: int, ref: str | None) -> list[Row]:
    """Single, batched and intervals rows of one arm."""
    robot = load_robot(name)
    q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (BATCH, robot.dof))
    T = robot.fk(q)
    par = np.asarray(redundancy_parameter(robot, q)[0])
    cases = list(zip(T[:POSES], par[:POSES].tolist()))
    t1 = time_calls(_cycle(lambda c: ik(robot, c[0], c[1]), cases), repeat)
    tb = time_calls(lambda: ik(robot, T, par), max(3, repeat // 400), warmup=1) / BATCH
    ti = time_calls(_cycle(lambda c: feasible_intervals(robot, c[0]), cases), max(10, repeat // 10), warmup=3)
    return [
        _row(f"qpik.ik, 1 pose ({name})", t1, ref, PAPER_NOTE if name == "nammoto7" else ""),
        _row(f"qpik.ik, batch of {BATCH} ({name}), per pose", tb, ref),
        _row(f"qpik.feasible_intervals ({name})", ti, ref),
    ]


def _row(label: str, t: np.ndarray, ref: str | None, note: str = "") -> Row:
    return Row(label, float(np.median(t)), ref, float(np.percentile(t, 99)), float(t.max()), note)


def _ssik_row(repeat: int) -> Row | None:
    """ssik on fk(q) of the same iiwa configurations (ssik's iiwa14 matches qpik's FK)."""
    try:
        from ssik.prebuilt.kuka import iiwa14_ik
    except ImportError:
        return None
    robot = load_robot("iiwa14")
    q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    T = list(robot.fk(q))
    t = time_calls(_cycle(iiwa14_ik.solve, T), max(20, repeat // 20), warmup=5)
    return _row(SSIK, t, None)
