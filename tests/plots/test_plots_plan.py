"""The plan figures (qpik.plots.plan): the self-motion map draws the plan's parameter on its branch's panel over
the infeasible states, the joint plot every joint against its limits, the strip the arm (or None without GL)."""

from __future__ import annotations

import numpy as np
import pytest
from legends import missing_labels, unexplained
from matplotlib.colors import to_rgba

import qpik
from qpik.geometry import Sphere
from qpik.planning.baselines import constant_parameter
from qpik.plots import save
from qpik.plots.plan import joint_trajectories, plan_map, render_plan
from qpik.render.pictures import unavailable_reason

IIWA = qpik.load_robot("iiwa14")


@pytest.fixture(scope="module")
def plan():
    T = IIWA.fk(IIWA.q_home + np.linspace(0.0, 1.0, 15)[:, None] * np.array([0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.3]))
    return qpik.plan_self_motion(
        IIWA, T, obstacles=[Sphere((0.45, 0.35, 0.7), 0.08)], options=qpik.PlanOptions(max_joint_step=0.2)
    )


def test_plan_map_draws_the_plan_on_its_branch_over_the_feasible_states(plan, tmp_path):
    fig = plan_map(plan)
    axes = [ax for ax in fig.axes if ax.images]
    assert len(axes) == 8
    panel = axes[int(plan.branch[0])]  # iiwa14: branch b is grid row b
    line = next(ln for ln in panel.get_lines() if ln.get_label() == plan.label)
    y = np.asarray(line.get_ydata(), float)
    assert np.allclose(y[plan.branch == plan.branch[0]], plan.param[plan.branch == plan.branch[0]])
    # under every point of the plan the map is feasible (clear), around it some states are not (grey)
    image = panel.images[0].get_array()
    G = image.shape[0]
    idx = np.floor((plan.param + np.pi) / (2 * np.pi / G)).astype(int).clip(0, G - 1)
    assert image[idx, np.arange(len(plan.q))].all() and not image.all()
    assert save(fig, tmp_path / "map.png").stat().st_size > 0


def test_joint_plot_shades_the_limits_and_draws_every_plan(plan):
    base = constant_parameter(plan, 0.0, int(plan.branch[0]), mujoco=False)
    fig = joint_trajectories(plan, [base])
    axes = fig.axes[: IIWA.dof]
    for j, ax in enumerate(axes):
        lines = {ln.get_label(): np.asarray(ln.get_ydata()) for ln in ax.get_lines()}
        assert np.array_equal(lines[plan.label], plan.q[:, j]) and np.array_equal(lines[base.label], base.q[:, j])
        red = [p for p in ax.patches if np.allclose(p.get_facecolor()[:3], to_rgba("tab:red")[:3])]
        edges = sorted({round(v, 9) for p in red for v in (p.get_y(), p.get_y() + p.get_height())})
        assert round(IIWA.q_min[j], 9) in edges and round(IIWA.q_max[j], 9) in edges


def test_render_plan_draws_the_arm_or_says_none(plan, tmp_path):
    out = render_plan(plan, tmp_path / "strip.png", frames=3)
    if unavailable_reason():
        assert out is None
    else:
        from PIL import Image

        img = np.asarray(Image.open(out).convert("L"), dtype=float)
        assert img.shape[1] == 3 * 360 and img.std() > 5


def test_the_map_draws_the_baselines_and_every_figure_names_its_marks(plan):
    """A constant-ψ baseline is drawn (dashed) at its ψ on its branch's panel; the map's and the joint plot's legends
    name every line, marker and shading."""
    b = int(plan.branch[0])
    base = constant_parameter(plan, 0.3, b, mujoco=False)
    fig = plan_map(plan, others=[base])
    panel = [ax for ax in fig.axes if ax.images][b]
    (line,) = [ln for ln in panel.get_lines() if ln.get_label() == base.label]
    assert line.get_linestyle() == "--" and np.allclose(np.asarray(line.get_ydata(), float), 0.3)
    assert not missing_labels(fig) and not unexplained(fig)
    labels = {t.get_text() for t in fig.legends[0].get_texts()}
    assert {base.label, plan.label, "DP"} <= labels and any(t.startswith("infeasible") for t in labels)
    joints = joint_trajectories(plan, [base])
    assert not missing_labels(joints) and not unexplained(joints)
    assert "beyond the joint limits" in {t.get_text() for t in joints.legends[0].get_texts()}
