"""qpik.analytic.set_ends.refine_ends: ends moved onto a solver's answers, also across ±π, where the sets are split.

The reference is the exact sets of robosuite's Jaco file (proved; its parameter q1 turns the whole arm about its base
axis, with the limits ±2π): a pose turned about that axis so that an end of a set lies just past −π, and the set cut
so that its end lies just before π instead, as a near member's ideal chain may give it; the refined sets must give
the true end back, the set split at ±π.
"""

from __future__ import annotations

import numpy as np
from conftest import model_robot, mujoco_poses, random_q

import qpik
from qpik.analytic import closed_form_for
from qpik.analytic.intervals import FeasibleIntervals, wrap
from qpik.analytic.set_ends import refine_ends
from qpik.analytic.subproblems import rotation

PAST = 3e-4
"""rad: how far past −π the true end lies."""
CUT = 2e-4
"""rad: how far before π the cut end lies."""


def _turned(robot: qpik.Robot, T: np.ndarray, angle: float) -> np.ndarray:
    """The pose T turned about the arm's first joint axis (base frame) by ``angle`` rad."""
    h, o = robot.chain.axes(np.zeros(robot.dof))
    M = np.eye(4)
    M[:3, :3] = np.array(rotation(tuple(h[0] / np.linalg.norm(h[0])), np.cos(angle), np.sin(angle)), float)
    M[:3, 3] = o[0] - M[:3, :3] @ o[0]
    return M @ T


def test_an_end_moves_past_pi_and_the_set_is_split_there():
    robot = model_robot("robosuite_jaco")
    solver = closed_form_for(robot)
    cases = 0
    for T in mujoco_poses(robot, random_q(robot, 4, 11)):
        fi = qpik.feasible_intervals(robot, T)
        k = next(k for k, x in enumerate(fi.intervals) if any(-np.pi < hi < np.pi for _, hi in x))
        hi = next(hi for _, hi in fi.intervals[k] if -np.pi < hi < np.pi)
        for sign in (1.0, -1.0):  # the parameter moves with the turn one way or the other
            Tt = _turned(robot, T, sign * float(wrap(-np.pi + PAST - hi)))
            turned = qpik.feasible_intervals(robot, Tt)
            true = turned.intervals[k]
            if not (true[0][0] == -np.pi and abs(true[0][1] - (-np.pi + PAST)) < 1e-9 and true[-1][1] == np.pi):
                continue
            cut = [list(x) for x in turned.intervals]
            cut[k] = [*true[1:-1], (true[-1][0], np.pi - CUT)]  # ends before π; the piece past −π gone
            fi_cut = FeasibleIntervals(turned.param_name, turned.branch, cut, [[] for _ in cut])
            got = refine_ends(fi_cut, solver, Tt, 0.0, 2.0 * (PAST + CUT)).intervals[k]
            assert len(got) == len(true) and got[0][0] == -np.pi and got[-1][1] == np.pi, (got, true)
            np.testing.assert_allclose(np.array(got), np.array(true), atol=1e-9)  # every end where it truly is
            cases += 1
    assert cases > 0
