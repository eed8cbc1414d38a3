"""Pictures of the closed form: the shaded spans are the complement of the feasible set, the curves pass FK."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from legends import missing_labels, unexplained
from matplotlib.axes import Axes
from matplotlib.patches import Rectangle
from PIL import Image

import qpik
from qpik.plots import closed_form as plots

CLOSED_FORM = ("nammoto7", "iiwa14")


def _pose(robot: qpik.Robot, seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).uniform(0.8 * robot.q_min, 0.8 * robot.q_max)
    return robot.fk(q)


def _spans(ax: Axes) -> list[tuple[float, float]]:
    """x extents (data coordinates) of the shaded infeasible spans of one axes."""
    out = []
    for patch in ax.patches:
        if patch.get_gid() == plots.INFEASIBLE_GID:
            assert isinstance(patch, Rectangle)
            out.append((patch.get_x(), patch.get_x() + patch.get_width()))
    return sorted(out)


@pytest.mark.parametrize("name, seed", [("nammoto7", 3), ("iiwa14", 5)])
def test_selfmotion_shading_is_complement_of_feasible_intervals(name: str, seed: int) -> None:
    robot = qpik.load_robot(name)
    T = _pose(robot, seed)
    fi = qpik.feasible_intervals(robot, T)
    for b in (int(fi.branch[0]), int(fi.branch[-1])):
        fig = plots.selfmotion_map(robot, T, shade_branch=b, num=181)
        joint_axes = fig.axes[: robot.dof]
        spans = _spans(joint_axes[0])
        for ax in joint_axes[1:]:
            assert _spans(ax) == spans  # the same shading on every joint panel
        # complement: shaded length + feasible length = 2π, and no overlap
        shaded = sum(hi - lo for lo, hi in spans)
        assert shaded + fi.measure(b) == pytest.approx(2 * np.pi, abs=1e-9)
        x = np.linspace(-np.pi, np.pi, 4001)
        in_span = np.zeros_like(x, dtype=bool)
        for lo, hi in spans:
            in_span |= (x > lo) & (x < hi)
        feasible = np.asarray(fi.contains(b, x))
        assert not np.any(in_span & feasible)
        edges = np.array([e for iv in fi[b] for e in iv] + [e for s in spans for e in s])
        away = np.min(np.abs(x[:, None] - edges[None]), axis=1) > 1e-9 if edges.size else np.ones_like(in_span)
        assert np.all(in_span[away] | feasible[away])


@pytest.mark.parametrize("name, seed", [("nammoto7", 11), ("iiwa14", 12)])
def test_selfmotion_curves_reach_the_pose(name: str, seed: int) -> None:
    """Points read back from the drawn lines (one per joint panel) are IK solutions: FK gives the pose."""
    robot = qpik.load_robot(name)
    T = _pose(robot, seed)
    fig = plots.selfmotion_map(robot, T, num=181)
    joint_axes = fig.axes[: robot.dof]
    rng = np.random.default_rng(seed)
    checked = 0
    for line in joint_axes[0].get_lines():
        label = line.get_label()
        if not label.startswith("branch "):
            continue
        xs = np.asarray(line.get_xdata(), float)
        for x in rng.choice(xs[np.isfinite(np.asarray(line.get_ydata(), float))], 3, replace=False):
            q = []
            for ax in joint_axes:
                (same,) = [ln for ln in ax.get_lines() if ln.get_label() == label]
                xd, yd = np.asarray(same.get_xdata(), float), np.asarray(same.get_ydata(), float)
                q.append(yd[np.flatnonzero(xd == x)[0]])
            F = robot.fk(np.array(q))
            np.testing.assert_allclose(F, T, atol=1e-9)
            checked += 1
    assert checked >= 3


def test_selfmotion_rejects_arm_without_closed_form() -> None:
    robot = qpik.load_robot("zheng7")
    with pytest.raises(qpik.NoClosedFormError):
        plots.selfmotion_map(robot, robot.fk(robot.q_home))


def _nonblank(path) -> bool:
    img = np.asarray(Image.open(path).convert("RGB"), dtype=float) / 255.0
    return img.ndim == 3 and float(img.std()) > 0.02


@pytest.mark.parametrize("gl", [True, False])
def test_branch_pictures_written_with_or_without_gl(tmp_path, monkeypatch, gl: bool) -> None:
    import qpik.render.pictures

    robot = qpik.load_robot("nammoto7")
    sols = qpik.ik(robot, _pose(robot, 2), 0.3)
    if not gl:

        def no_gl(*args, **kwargs):
            raise qpik.render.pictures.RenderUnavailable("no GL in this test")

        monkeypatch.setattr(qpik.render.pictures, "render_configurations", no_gl)
    path = tmp_path / "branches.png"
    how = plots.branch_pictures(robot, sols, path)
    assert path.is_file() and _nonblank(path)
    if not gl:
        assert how == "sticks"
    else:
        assert how in ("render", "sticks")


def test_stick_figures_end_at_the_hand() -> None:
    """The last point of every stick (ee) is the FK position; the overlay's x-y panel is its projection."""
    robot = qpik.load_robot("nammoto7")
    T = _pose(robot, 4)
    deltas = np.array([-0.5, 0.0, 0.5])
    sols = qpik.ik(robot, np.repeat(T[None], 3, axis=0), deltas)
    qs = sols.q[:, 0][sols.valid[:, 0]]
    fig = plots.stick_overlay(robot, qs, [f"{d}" for d in deltas[sols.valid[:, 0]]])
    xy = fig.axes[1]
    ends = [(ln.get_xdata()[-1], ln.get_ydata()[-1]) for ln in xy.get_lines() if not ln.get_label().startswith("_")]
    np.testing.assert_allclose(np.array(ends), np.tile(T[:2, 3], (len(qs), 1)), atol=1e-12)


def test_sweep_figure_marks_points_outside_limits() -> None:
    robot = qpik.load_robot("iiwa14")
    x = np.linspace(0.0, 1.0, 5)
    q = np.zeros((5, 7))
    q[2, 3] = robot.q_max[3] + 0.1  # one point outside the limits
    fig = plots.sweep_figure(robot, x, [("a", q, np.ones(5, bool))], "x", "t")
    crosses = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() == "x" and len(ln.get_xdata())]
    assert len(crosses) == 1 and crosses[0].get_xdata()[0] == x[2]


def test_infeasible_spans_of_empty_and_full_sets() -> None:
    assert plots.infeasible_spans([]) == [(-np.pi, np.pi)]
    assert plots.infeasible_spans([(-np.pi, np.pi)]) == []
    assert plots.infeasible_spans([(-1.0, 0.0), (1.0, np.pi)]) == [(-np.pi, -1.0), (0.0, 1.0)]


@pytest.mark.parametrize("name, seed", [("nammoto7", 3), ("iiwa14", 5)])
def test_selfmotion_legend_names_every_line_span_and_tick(name: str, seed: int) -> None:
    """The legends name the branches, the limits (dashed), the singular values (dotted), the shaded spans and the
    feasible panel's singular ticks: no drawn style is left unexplained."""
    robot = qpik.load_robot(name)
    fig = plots.selfmotion_map(robot, _pose(robot, seed), num=181)
    assert not missing_labels(fig) and not unexplained(fig)
    labels = {t.get_text() for t in fig.legends[0].get_texts()}
    assert "joint limits" in labels and any(label.startswith("branch ") for label in labels)


def test_sweep_figure_legend_names_the_crosses_and_the_limits_it_draws() -> None:
    """A joint that leaves its limits gets its limits drawn (dashed, at the robot's limits) and crosses, all named."""
    robot = qpik.load_robot("nammoto7")
    x = np.linspace(0.0, 1.0, 5)
    q = np.zeros((5, 7))
    q[1:3, 5] = robot.q_max[5] + 0.1
    curves = [("a", q, np.ones(5, bool)), ("b", np.zeros((5, 7)), np.ones(5, bool))]
    fig = plots.sweep_figure(robot, x, curves, "x", "t")
    assert not missing_labels(fig) and not unexplained(fig)
    dashed = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert sorted({float(ln.get_ydata()[0]) for ln in dashed}) == [robot.q_min[5], robot.q_max[5]]
    assert "θ6 limits" in {t.get_text() for t in fig.legends[0].get_texts()}


def _origins(robot: qpik.Robot, q: np.ndarray) -> np.ndarray:
    return robot.frames(q)[..., :3, 3]


@pytest.mark.parametrize("name, seed", [("nammoto7", 6), ("iiwa14", 7)])
def test_branches_drawn_as_one_picture_put_every_link_at_the_same_place(name: str, seed: int) -> None:
    """same_links groups the branches whose DH frame origins coincide (checked here with Robot.frames, not with the
    capsules it compares) and keeps apart those that differ; the wrist flip (θ5 + π, −θ6, θ7 + π), applied here to a
    configuration, reaches the same pose, joins its group and is named."""
    robot = qpik.load_robot(name)
    T = _pose(robot, seed)
    sols = qpik.ik(robot, T, 0.2)
    qs = sols.q[sols.valid]
    groups = plots.same_links(robot, qs)
    assert sorted(k for g in groups for k in g) == list(range(len(qs)))
    o = _origins(robot, qs)
    for g in groups:
        assert np.abs(o[g] - o[g[0]]).max() < 1e-9
    for a, b in itertools.combinations(groups, 2):
        assert np.abs(o[a[0]] - o[b[0]]).max() > 1e-6
    flipped = qs[0].copy()
    flipped[4], flipped[5], flipped[6] = flipped[4] + np.pi, -flipped[5], flipped[6] + np.pi
    np.testing.assert_allclose(robot.fk(flipped), T, atol=1e-9)
    assert plots.same_links(robot, np.array([qs[0], flipped])) == [[0, 1]]
    assert plots.flip(qs[0], flipped) == "θ5+π, −θ6, θ7+π (wrist flip)"
    lines = plots.flip_lines(sols.branch[sols.valid].tolist(), qs, groups)
    assert any(line.startswith("θ5+π, −θ6, θ7+π (wrist flip): ") for line in lines)


def test_branch_picture_titles_and_caption_say_which_branches_share_a_picture(monkeypatch) -> None:
    """Without GL: one stick figure per group of same_links, its title the group's branch ids (large type), the
    caption the flips, and a legend for the base, the sticks and the hand."""
    import qpik.render.pictures

    def no_gl(*args, **kwargs):
        raise qpik.render.pictures.RenderUnavailable("no GL in this test")

    figures = []
    monkeypatch.setattr(qpik.render.pictures, "render_configurations", no_gl)
    monkeypatch.setattr(plots, "save", lambda fig, path: figures.append(fig))
    robot = qpik.load_robot("nammoto7")
    sols = qpik.ik(robot, _pose(robot, 2), 0.3)
    assert plots.branch_pictures(robot, sols, "unused.png") == "sticks"
    (fig,) = figures
    groups = plots.same_links(robot, sols.q[sols.valid])
    ids = sols.branch[sols.valid]
    titles = [ax.get_title() for ax in fig.axes]
    assert len(titles) == len(groups)
    for title, g in zip(titles, groups):
        assert title.splitlines()[0].split(" ", 1)[1] == ", ".join(str(ids[k]) for k in g)
    assert min(ax.title.get_fontsize() for ax in fig.axes) >= 12
    assert "wrist flip" in fig._supxlabel.get_text()
    assert not missing_labels(fig) and not unexplained(fig)
