"""Bench: :func:`qpik.plan_self_motion` on a 1,000-waypoint iiwa14 path with one obstacle.

The path is the ``wipe`` formula of :mod:`qpik.problems.paths` (the tool pointing down, four sideways
strokes along 0.6 m in 20 s, sampled at 1,000 even times, so the joint steps are also bounded by
v_max · 20 ms) past the post of ``problems/iiwa_wiping_plan.toml`` (a capsule; the table is left out).
The DP grids 720 values of ψ on each of the 8 branches at every waypoint (5.76 M states) inside the
exact feasible intervals; the DP and the NLP are timed separately (``Plan.timings``), after one
warm-up run that compiles and caches the functions. Rows: the DP (grid, feasible intervals, states,
transitions, backtracking), the NLP (building the sparse NLP and IPOPT), and the same DP without the
obstacle. With ``--repeat`` below 1,000 the path has 100 waypoints and runs once (a quick
look). Descartes' 65 s for 900 points without collision checking (its issue #55) is quoted, not measured.
"""

from __future__ import annotations

import argparse

import numpy as np

from qpik.bench import Row
from qpik.geometry.shapes import Capsule
from qpik.planning import PlanOptions, plan_self_motion
from qpik.problems.paths import wipe
from qpik.robots.loader import load_robot

TITLE = "Self-motion planning: 1,000-waypoint iiwa14 path, 720 ψ values × 8 branches (qpik.plan_self_motion)"
WAYPOINTS = 1000
POST = Capsule((0.38, 0.0, 0.10), (0.38, 0.0, 0.42), 0.03)
DESCARTES = "Descartes (ROS-Industrial, issue #55): 65 s for 900 points without collision checks (quoted, not measured)"


def path(waypoints: int = WAYPOINTS) -> tuple[np.ndarray, np.ndarray]:
    """The bench's waypoints (N, 4, 4) and times (N,), s."""
    robot = load_robot("iiwa14")
    formula = wipe(robot, {"center": [0.6, 0.0, 0.22], "amplitude": 0.08, "length": 0.6, "strokes": 4,
                           "duration": 20.0})  # fmt: skip
    times = np.linspace(0.0, formula.duration, waypoints)
    return formula.pose(times), times


def run(args: argparse.Namespace) -> list[Row]:
    robot = load_robot("iiwa14")
    full = int(getattr(args, "repeat", 2000)) >= 1000
    count = WAYPOINTS if full else WAYPOINTS // 10  # a quick look with --repeat below 1000
    T, times = path(count)
    repeat = 3 if full else 1
    runs = {"obstacle": [], "free": []}
    checked, dp_only = PlanOptions(mujoco=False), PlanOptions(refine=False, mujoco=False)
    plan_self_motion(robot, T, obstacles=[POST], times=times, options=checked)  # compiles and caches
    plan_self_motion(robot, T, times=times, options=dp_only)
    for _ in range(repeat):
        runs["obstacle"].append(plan_self_motion(robot, T, obstacles=[POST], times=times, options=checked))
        runs["free"].append(plan_self_motion(robot, T, times=times, options=dp_only))
    last = runs["obstacle"][-1]
    dp = np.median([p.timings["dp"] for p in runs["obstacle"]])
    nlp = np.median([p.timings["nlp"] for p in runs["obstacle"]])
    free = np.median([p.timings["dp"] for p in runs["free"]])
    checks = "all checks hold" if last.ok else "CHECKS FAIL: " + "; ".join(c.text for c in last.checks if not c.ok)
    note = (f"{count} waypoints × 8 branches × 720 ψ; {last.summary()};"
            f" NLP {last.cost:.6g} vs DP {last.dp_cost:.6g}; {checks}; median of {repeat}")  # fmt: skip
    return [
        Row("DP, 1 obstacle (iiwa14)", float(dp), note=DESCARTES),
        Row("NLP from the DP, 1 obstacle (iiwa14)", float(nlp), note=note),
        Row("DP, no obstacle (iiwa14)", float(free), note=f"{runs['free'][-1].summary()}"),
    ]
