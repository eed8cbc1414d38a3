"""What the viewer shows for one target pose, computed by qpik alone (no web server).

:func:`solve_view` gathers, for a pose and a value of the redundancy parameter: every closed-form branch
(:func:`qpik.ik`), the exact feasible sets of every branch (:func:`qpik.feasible_intervals`), the best
answer of :func:`qpik.solve_best` for an objective, and the clearances of the shown configuration to the
obstacles. An arm whose branches :func:`qpik.ik` finds by a search (no expressions of the parameter: no feasible
sets, no certified best answer) gets its branches, and the solid configuration is the within-limits branch nearest
the last configuration shown. An arm without :func:`qpik.ik` (or without a branch within the limits) gets the
numerical IK's answer (:class:`qpik.nlp.ik.IKSolver`, Levenberg–Marquardt from the last configuration shown, within
its iteration budget).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qpik.analytic import FeasibleIntervals, IKSolutions, feasible_intervals, ik
from qpik.analytic.intervals import apart
from qpik.geometry.distance import Distances, ObstacleSet, distances
from qpik.nlp import BestResult, solve_best
from qpik.nlp.best import build_search
from qpik.nlp.ik import IKResult
from qpik.nlp.ik import ik_solver_for as ik_solver
from qpik.nlp.options import BestOptions
from qpik.robots.robot import Robot


@dataclass
class ViewState:
    """One pose's answers.

    Attributes:
        pose: (4, 4) the target, base frame.
        param: the redundancy parameter of the ghosts (δ, ψ or the locked joint, rad); None without :func:`qpik.ik`.
        branches: every branch at ``param`` (None without :func:`qpik.ik`).
        intervals: the feasible sets of every branch (None without a closed form).
        best: :func:`qpik.solve_best`'s answer (None without a closed form).
        numerical: the numerical IK's answer (None where the solid configuration is a closed form's answer or a
            branch).
        q: (n,) the configuration drawn solid, rad: the best answer, the branch nearest ``q_seed``, or the
            numerical IK's.
        clearance: capsule–obstacle distances at ``q`` (:class:`qpik.geometry.Distances`, None without obstacles).
        certify: whether :func:`qpik.solve_best` was asked for its certificate.
        slot: the index in ``branches`` of the solid configuration where it is a branch (an arm whose branches are
            found by a search: no feasible sets, no certified best answer), else None.
    """

    pose: np.ndarray
    param: float | None
    branches: IKSolutions | None
    intervals: FeasibleIntervals | None
    best: BestResult | None
    numerical: IKResult | None
    q: np.ndarray
    clearance: Distances | None
    certify: bool
    slot: int | None = None


def solve_view(
    robot: Robot,
    pose: np.ndarray,
    param: float,
    objective: str = "margin",
    obstacles: ObstacleSet | None = None,
    d_safe: float = 0.02,
    certify: bool = True,
    q_seed: np.ndarray | None = None,
) -> ViewState:
    """The answers for target ``pose`` (4, 4) with the ghosts at redundancy parameter ``param`` (rad).

    ``objective`` and ``d_safe`` (m) are :func:`qpik.solve_best`'s (the ``"distance"`` objective's
    reference is ``q_seed``); ``q_seed`` (n,) is also where the numerical IK starts (default the home
    configuration).
    """
    obstacles = obstacles if obstacles is not None else ObstacleSet(())
    seed = robot.q_home if q_seed is None else np.asarray(q_seed, dtype=float)
    param_, branches, intervals, best, numerical, slot = None, None, None, None, None, None
    if robot.closed_form is not None:
        param_ = float(param)
        branches = ik(robot, pose, param_)
    if robot.branch_functions:
        intervals = feasible_intervals(robot, pose)
        q_ref = seed if objective == "distance" else None
        best = solve_best(robot, pose, objective, obstacles, q_ref, d_safe=d_safe, options=BestOptions(certify=certify))
        q = best.q
    elif branches is not None and branches.within_limits.any():
        slot = int(np.argmin(np.where(branches.within_limits, apart(branches.q, seed), np.inf)))
        q = branches.q[slot]
    else:
        numerical = ik_solver(robot).solve(pose, seed)  # its iteration budget, not a time: the same answer anywhere
        q = numerical.q
    clearance = distances(robot.capsule_segments(q), robot.capsule_radii, obstacles) if len(obstacles) else None
    return ViewState(np.asarray(pose, dtype=float), param_, branches, intervals, best, numerical, q, clearance,
                     certify, slot)  # fmt: skip


def prepare_search(robot: Robot, state: ViewState, objective: str, obstacles: ObstacleSet, d_safe: float) -> None:
    """Build what a later drag may call that ``state`` (``robot``'s answer of :func:`solve_view`) did not: the
    search of :func:`qpik.solve_best`, for poses its level sets do not settle (out of reach, or among obstacles),
    without and with the arm's capsule pairs (:func:`qpik.nlp.best.build_search`), then one search without
    certificate at ``state``'s pose; its answer is not kept."""
    if state.best is None:
        return
    q_ref = state.q if objective == "distance" else None
    build_search(robot, state.pose, objective, obstacles, q_ref, d_safe=d_safe)
    options = BestOptions(method="search", certify=False)
    solve_best(robot, state.pose, objective, obstacles, q_ref, d_safe=d_safe, options=options)
