"""The feasible-set panel of an arm whose sets are sampled, not proved (the 1-D search's Baxter): its bars are the
sets of qpik.feasible_intervals, its title says they are not proved, the shading of the first branch is their
complement, and single-pose IK calls inside and outside the bars agree with them by the file's limits."""

from __future__ import annotations

import numpy as np
from conftest import model_robot
from legends import missing_labels, unexplained
from matplotlib.axes import Axes

import qpik
from qpik.plots import closed_form as plots

NUM = 61


def _bars(ax: Axes) -> dict[int, list[tuple[float, float]]]:
    """Per row (branch index, top first) of a broken_barh panel, the bars' x extents (data coordinates)."""
    rows: dict[int, list[tuple[float, float]]] = {}
    for collection in ax.collections:
        for path in collection.get_paths():
            v = path.vertices
            rows.setdefault(round(float(v[:, 1].mean())), []).append((float(v[:, 0].min()), float(v[:, 0].max())))
    return {k: sorted(b) for k, b in rows.items()}


def test_the_panel_of_a_searched_arm_bars_its_sampled_sets_and_says_they_are_not_proved():
    robot = model_robot("erd_baxter")
    q = np.random.default_rng(8).uniform(0.8 * robot.q_min, 0.8 * robot.q_max)
    T = robot.fk(q)
    fig = plots.selfmotion_map(robot, T, num=NUM)
    panel = fig.axes[7]
    assert "not proved" in panel.get_title()
    assert not missing_labels(fig) and not unexplained(fig)
    fi = qpik.feasible_intervals(robot, T)
    assert not fi.proved
    bars = _bars(panel)
    assert bars
    for k in range(16):
        np.testing.assert_allclose(bars.get(k, []), fi[k], atol=1e-12)
    shaded = sorted({(p.get_x(), p.get_x() + p.get_width()) for p in fig.axes[0].patches
                     if p.get_gid() == plots.INFEASIBLE_GID})  # fmt: skip
    np.testing.assert_allclose(shaded, plots.infeasible_spans(fi[0]), atol=1e-12)
    x = np.linspace(-np.pi, np.pi, NUM)[1:-1]
    inside = np.array([qpik.ik(robot, T, float(v)).within_limits for v in x])
    assert inside.any()
    for k in range(16):
        ends = np.array([e for iv in fi[k] for e in iv])
        far = ~(np.abs(x[:, None] - ends[None, :]) < 1e-6).any(axis=1) if ends.size else np.ones(len(x), bool)
        np.testing.assert_array_equal(fi.contains(k, x)[far], inside[far, k])
