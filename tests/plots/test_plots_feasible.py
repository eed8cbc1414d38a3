"""The feasible-set panel of an arm whose sets are not computed (the 1-D search's Baxter): its bars are the runs of
samples where each branch is within the limits, by single-pose IK calls and the file's limits."""

from __future__ import annotations

import numpy as np
from conftest import model_robot
from legends import missing_labels, unexplained
from matplotlib.axes import Axes

import qpik
from qpik.plots import closed_form as plots

NUM = 121


def _bars(ax: Axes) -> dict[int, list[tuple[float, float]]]:
    """Per row (branch index, top first) of a broken_barh panel, the bars' x extents (data coordinates)."""
    rows: dict[int, list[tuple[float, float]]] = {}
    for collection in ax.collections:
        for path in collection.get_paths():
            v = path.vertices
            rows.setdefault(round(float(v[:, 1].mean())), []).append((float(v[:, 0].min()), float(v[:, 0].max())))
    return {k: sorted(b) for k, b in rows.items()}


def test_the_sampled_panel_bars_the_within_limit_runs_of_a_searched_arm_and_nothing_is_shaded():
    robot = model_robot("erd_baxter")
    q = np.random.default_rng(8).uniform(0.8 * robot.q_min, 0.8 * robot.q_max)
    T = robot.fk(q)
    fig = plots.selfmotion_map(robot, T, num=NUM)
    panel = fig.axes[7]
    assert "no exact sets" in panel.get_title()
    assert not any(p.get_gid() == plots.INFEASIBLE_GID for ax in fig.axes for p in ax.patches)
    assert not missing_labels(fig) and not unexplained(fig)
    x = np.linspace(-np.pi, np.pi, NUM)
    inside = []
    for value in x:
        sol = qpik.ik(robot, T, float(value))
        within = np.all((sol.q >= robot.q_min) & (sol.q <= robot.q_max), axis=1) & sol.valid
        inside.append(within)
    inside = np.array(inside)
    bars = _bars(panel)
    assert inside.any() and bars
    for k in range(inside.shape[1]):
        runs, start = [], None
        for i, flag in enumerate(inside[:, k]):
            if flag and start is None:
                start = i
            if start is not None and (not flag or i == NUM - 1):
                runs.append((x[start], x[i if flag else i - 1]))
                start = None
        np.testing.assert_allclose(bars.get(k, []), runs, atol=1e-12)
