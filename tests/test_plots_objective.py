"""The objective plot: the star is the answer, the curves are the objective of configurations on the pose."""

from __future__ import annotations

import numpy as np

import qpik
from qpik.nlp import solve_best
from qpik.objectives import Evaluator, JointLimitMargin
from qpik.plots.objective import OPTIMUM_GID, objective_map


def test_star_at_the_answer_and_curves_from_the_closed_form():
    robot = qpik.load_robot("iiwa14")
    pose = robot.fk(np.random.default_rng(2).uniform(0.7 * robot.q_min, 0.7 * robot.q_max))
    best = solve_best(robot, pose, certify=False)
    fig = objective_map(robot, pose, "margin", result=best, num=181)
    top, bottom = fig.axes[:2]
    stars = [ln for ln in top.lines if ln.get_gid() == OPTIMUM_GID]
    assert len(stars) == 1
    np.testing.assert_allclose(stars[0].get_xydata()[0], (best.param, best.objective))
    # each branch's curve: the margin of its closed-form configuration (NaN outside the limits)
    sols = qpik.ik(robot, np.broadcast_to(pose, (181, 4, 4)), np.linspace(-np.pi, np.pi, 181))
    f = Evaluator(robot, JointLimitMargin())(sols.q.reshape(-1, 7))[0].reshape(181, -1)
    curves = [ln for ln in top.lines if (ln.get_label() or "").startswith("branch ")]
    assert len(curves) == 8
    for k, ln in enumerate(curves):
        y = ln.get_ydata()
        ok = sols.within_limits[:, k]
        np.testing.assert_allclose(y[ok], f[ok, k])
        assert np.isnan(y[~ok]).all()
    assert bottom.collections  # the feasible bars
    assert best.objective <= np.nanmin(np.where(sols.within_limits, f, np.nan)) + 1e-12
