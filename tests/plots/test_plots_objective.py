"""The objective plot: the star is the answer, the curves are the measured quantity (the margin itself, not the −margin
that is minimised) of configurations on the pose, and the legend names every line and marker."""

from __future__ import annotations

import numpy as np
import pytest
from legends import missing_labels, unexplained

import qpik
from qpik.geometry import Sphere
from qpik.nlp import solve_best
from qpik.nlp.options import BestOptions
from qpik.plots.objective import OPTIMUM_GID, objective_map
from qpik.scene import Scene


def _margin(robot, q):
    """The smallest distance to a joint limit over the half range, from its definition."""
    half = 0.5 * (robot.q_max - robot.q_min)
    return np.minimum((q - robot.q_min) / half, (robot.q_max - q) / half).min(axis=-1)


def test_star_at_the_answer_and_curves_from_the_closed_form():
    robot = qpik.load_robot("iiwa14")
    pose = robot.fk(np.random.default_rng(2).uniform(0.7 * robot.q_min, 0.7 * robot.q_max))
    best = solve_best(robot, pose, options=BestOptions(certify=False))
    fig = objective_map(Scene.of(robot), pose, best, num=181)
    top, bottom = fig.axes[:2]
    stars = [ln for ln in top.lines if ln.get_gid() == OPTIMUM_GID]
    assert len(stars) == 1
    margin = _margin(robot, best.q)
    assert margin > 0 and best.objective == pytest.approx(-margin, abs=1e-12)
    np.testing.assert_allclose(stars[0].get_xydata()[0], (best.param, margin), atol=1e-12)
    assert top.get_ylabel().startswith("margin")
    # each branch's curve: the margin of its closed-form configuration (NaN outside the limits)
    sols = qpik.ik(robot, np.broadcast_to(pose, (181, 4, 4)), np.linspace(-np.pi, np.pi, 181))
    f = _margin(robot, sols.q)
    curves = [ln for ln in top.lines if (ln.get_label() or "").startswith("branch ")]
    assert len(curves) == 8
    for k, ln in enumerate(curves):
        y = ln.get_ydata()
        ok = sols.within_limits[:, k]
        np.testing.assert_allclose(y[ok], f[ok, k])
        assert np.isnan(y[~ok]).all()
    assert bottom.collections  # the feasible bars
    assert margin >= np.nanmax(np.where(sols.within_limits, f, np.nan)) - 1e-12
    assert not missing_labels(fig) and not unexplained(fig)


def test_every_line_and_marker_is_in_the_legend_with_obstacles():
    """With an obstacle the dotted parts (a link closer than d_s) and the star are named in the legend; the label at
    the star says the margin."""
    robot = qpik.load_robot("iiwa14")
    pose = robot.fk(np.array([0.1, 0.9, 0.2, -1.2, 0.3, 0.8, 0.1]))
    ball = Sphere(robot.frames(np.array([0.1, 0.9, 0.2, -1.2, 0.3, 0.8, 0.1]))[4, :3, 3] + [0.1, 0.0, 0.0], 0.06)
    best = solve_best(robot, pose, "margin", [ball], d_safe=0.03, options=BestOptions(certify=False))
    fig = objective_map(Scene.of(robot, [ball], d_safe=0.03), pose, best, num=181)
    top = fig.axes[0]
    assert any(ln.get_linestyle() == ":" and len(ln.get_xdata()) for ln in top.lines)  # the ball is close somewhere
    assert not missing_labels(fig) and not unexplained(fig)
    texts = [t.get_text() for t in top.texts]
    assert any(f"margin {best.reported:.4g}" in t for t in texts)
