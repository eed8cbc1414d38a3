r"""Pictures of the closed form: every function returns a matplotlib ``Figure`` (no pyplot state).

- :func:`selfmotion_map` — the self-motion of one pose: each joint against the
  redundancy parameter (δ, ψ, or a locked joint's angle) over (-π, π], one curve per branch, the joint
  limits, the parameter ranges where a chosen branch leaves the limits (the
  complement of :func:`qpik.feasible_intervals`) shaded, singular values marked,
  and a panel with every branch's feasible set (:mod:`qpik.plots.feasible`).
- :func:`sweep_figure` — joint angles of one branch along a sweep (a position
  coordinate or the parameter), one panel per curve set (Nammoto & Kosuge 2012, Figs. 15/16).
- :func:`stick_grid` — one 3-D stick figure per configuration (Nammoto & Kosuge 2012, Fig. 10).
- :func:`stick_overlay` — configurations overlaid in 3-D and projected on the
  x-y plane (Nammoto & Kosuge 2012, Figs. 12/13).
- :func:`branch_pictures` — the branch poses as a PNG, rendered by
  :mod:`qpik.render.pictures` when OpenGL is available, else by :func:`stick_grid`.

Stick figures join the origins of the DH frames ``[base, frame_1..frame_n, ee]``
(``Robot.frames``); lengths in metres, world (base) frame.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from qpik.analytic.api import IKSolutions, feasible_intervals, ik, symbol
from qpik.analytic.intervals import Interval, wrap
from qpik.plots.feasible import feasible_panel
from qpik.plots.files import save
from qpik.robots.robot import Robot

PI = np.pi
INFEASIBLE_GID = "infeasible"  # gid of the shaded spans (for readers of the figure)
SINGULAR_GID = "singular"


def branch_colors(branches: Sequence[int]) -> dict[int, tuple]:
    """One distinct colour per branch id (tab20 for up to 20 branches)."""
    cmap = matplotlib.colormaps["tab20" if len(branches) > 10 else "tab10"]
    return {int(b): cmap(i % cmap.N) for i, b in enumerate(branches)}


def infeasible_spans(intervals: list[Interval]) -> list[Interval]:
    """Complement in [-π, π] of sorted disjoint closed intervals (open ends dropped)."""
    out: list[Interval] = []
    start = -PI
    for lo, hi in intervals:
        if lo > start:
            out.append((start, lo))
        start = max(start, hi)
    if start < PI:
        out.append((start, PI))
    return out


def selfmotion_samples(robot: Robot, pose: np.ndarray, num: int = 721, project: bool = False) -> IKSolutions:
    """Every branch at ``num`` parameter values evenly spaced over [-π, π], one batched call.

    Returns batched :class:`IKSolutions` (``q`` (num, B, n), ``param`` (num,)).
    """
    T = np.broadcast_to(np.asarray(pose, dtype=float), (num, 4, 4))
    return ik(robot, T, np.linspace(-PI, PI, num), project=project)


def _broken(x: np.ndarray, y: np.ndarray, ok: np.ndarray, jump: float = PI / 2) -> tuple[np.ndarray, np.ndarray]:
    """``y`` with NaN where not ``ok``, and a NaN gap inserted at every jump larger than ``jump`` (wraps)."""
    y = np.where(ok, y, np.nan)
    cut = np.flatnonzero(np.abs(np.diff(y)) > jump) + 1
    return np.insert(x, cut, np.nan), np.insert(y, cut, np.nan)


def selfmotion_map(
    robot: Robot,
    pose: np.ndarray,
    branches: Sequence[int] | None = None,
    shade_branch: int | None = None,
    num: int = 721,
    project: bool = False,
    title: str | None = None,
) -> Figure:
    """Self-motion map of one pose: q_j(param) per branch, limits, infeasible ranges, singular values.

    Args:
        robot: an arm with a closed form.
        pose: end-effector pose (4, 4) in the base frame.
        branches: public branch ids to draw (default: all).
        shade_branch: the branch whose infeasible parameter ranges are shaded
            (grey spans, ``gid="infeasible"``; default: the first drawn branch).
            They are the complement in [-π, π] of ``feasible_intervals(robot, pose)``
            for that branch — its breakpoints, not the sampled curves (not proved for some arms, and the last
            panel's title then says so: :func:`qpik.plots.feasible.feasible_panel`).
        num: parameter samples over [-π, π] for the curves.
        project: project a non-orthonormal rotation onto SO(3).

    Layout: a 4×2 grid; panels 1–7 are the joints (rad against rad, one line per
    branch labelled ``"branch b"``, limits dashed, singular values of the drawn
    branches dotted vertical lines with ``gid="singular"``); panel 8 shows the
    feasible set of every branch as bars.
    """
    sols = selfmotion_samples(robot, pose, num, project)
    fi = feasible_intervals(robot, pose, project=project)
    ids = [int(b) for b in sols.branch]
    draw = ids if branches is None else [int(b) for b in branches]
    shade = draw[0] if shade_branch is None else int(shade_branch)
    colors = branch_colors(ids)
    x = np.asarray(sols.param)
    sym = symbol(sols.param_name)
    spans = infeasible_spans(fi[shade])
    singular = sorted({float(s) for b in draw for s in fi.singular[fi.index(b)]}) if fi.singular else []

    fig = Figure(figsize=(12, 13), layout="constrained")
    axes = fig.subplots(4, 2, sharex=True)
    for j, ax in enumerate(axes.flat[: robot.dof]):
        first = j == 0  # the legend's entries come from the first panel; the others repeat its styles
        for k, (lo, hi) in enumerate(spans):
            ax.axvspan(lo, hi, color="0.85", zorder=0, gid=INFEASIBLE_GID,
                       label=f"{sym} where branch {shade} leaves the limits" if first and not k else None)  # fmt: skip
        for k, s in enumerate(singular):
            ax.axvline(s, color="k", ls=":", lw=1.0, gid=SINGULAR_GID,
                       label=f"singular {sym}" if first and not k else None)  # fmt: skip
        for b in draw:
            i = ids.index(b)
            xs, ys = _broken(x, sols.q[:, i, j], sols.valid[:, i])
            top = b == shade
            ax.plot(xs, ys, color=colors[b], lw=2.4 if top else 1.1, zorder=3 if top else 2, label=f"branch {b}")
        for k, lim in enumerate((robot.q_min[j], robot.q_max[j])):
            ax.axhline(lim, color="firebrick", ls="--", lw=1.0, label="joint limits" if first and not k else None)
        ax.set_ylim(-3.3, 3.3)
        ax.set_ylabel(f"θ{j + 1} [rad]" if sols.param_name == "delta" else f"q{j + 1} [rad]")
        ax.grid(alpha=0.3)
    feasible_panel(axes.flat[7], fi, draw, shade, colors)
    for ax in axes[-1]:
        ax.set_xlabel(f"{sym} [rad]")
        ax.set_xlim(-PI, PI)
        ax.set_xticks(np.linspace(-PI, PI, 5), ["−π", "−π/2", "0", "π/2", "π"])
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right center", fontsize=8)
    p = np.asarray(pose, dtype=float)[:3, 3]
    fig.suptitle(title or f"{robot.name}: self-motion in {sym} at p = ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m",
                 fontsize=11)  # fmt: skip
    return fig


def sweep_figure(
    robot: Robot,
    x: np.ndarray,
    curves: Sequence[tuple[str, np.ndarray, np.ndarray]],
    xlabel: str,
    title: str,
) -> Figure:
    """Joint angles along a sweep, one panel per curve set (Nammoto & Kosuge 2012, Figs. 15 and 16).

    Args:
        x: sweep coordinate (S,), e.g. p_z in metres.
        curves: ``(panel title, q (S, n) rad, ok (S,) bool)``; points with
            ``ok`` False (branch invalid) are not drawn; points outside the
            joint limits are marked with a cross, and the limits of every joint
            that leaves them somewhere are drawn dashed in the joint's colour.
        xlabel, title: axis label and figure title.

    The legend (right) names every curve, the crosses and the limit lines.
    """
    fig = Figure(figsize=(6 * len(curves) + 1.5, 4.8), layout="constrained")
    axes = fig.subplots(1, len(curves), sharey=True, squeeze=False)
    cmap = matplotlib.colormaps["tab10"]
    lo, hi = np.asarray(robot.q_min, float), np.asarray(robot.q_max, float)
    outside = [ok[:, None] & ((q < lo) | (q > hi)) for _, q, ok in curves]
    leaves = np.flatnonzero(np.any([o.any(axis=0) for o in outside], axis=0)) if curves else []
    crossed = False
    for k, (ax, (label, q, ok), bad) in enumerate(zip(axes[0], curves, outside)):
        for j in range(q.shape[1]):
            xs, ys = _broken(x, q[:, j], ok)
            ax.plot(xs, ys, color=cmap(j), lw=1.8, label=f"θ{j + 1}" if not k else None)
        for j in range(q.shape[1]):
            if bad[:, j].any():
                ax.plot(x[bad[:, j]], q[bad[:, j], j], "x", color=cmap(j), ms=7, mew=2,
                        label=None if crossed else "outside its limits")  # fmt: skip
                crossed = True
        for j in leaves:
            for m, lim in enumerate((lo[j], hi[j])):
                ax.axhline(lim, color=cmap(j), ls="--", lw=1.0, label=f"θ{j + 1} limits" if not (k or m) else None)
        ax.set_title(label, fontsize=10)
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("joint angle [rad]")
    fig.legend(*legend_entries(fig), loc="outside right center", fontsize=9)
    fig.suptitle(title, fontsize=11)
    return fig


def legend_entries(fig: Figure) -> tuple[list, list[str]]:
    """The labelled artists of every axes of ``fig`` (the first of each label), for one figure legend."""
    handles, labels = [], []
    for ax in fig.axes:
        for h, text in zip(*ax.get_legend_handles_labels()):
            if text not in labels:
                handles.append(h)
                labels.append(text)
    return handles, labels


def stick_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Origins of ``[base, frame_1..frame_n, ee]`` (m, world frame): (n+2, 3); batched (K, n+2, 3)."""
    return robot.frames(q)[..., :3, 3]


def _draw_stick(ax: Axes, pts: np.ndarray, color, label: str | None = None, dims: tuple[int, ...] = (0, 1, 2)):
    ax.plot(*(pts[:, d] for d in dims), "-o", color=color, lw=2, ms=3, label=label)
    ax.plot(*(pts[-1:, d] for d in dims), "s", color=color, ms=6)


def _equal_3d(ax, pts: np.ndarray) -> None:
    """Equal scales on a 3-D axes: a cube around every point of ``pts`` (..., 3)."""
    lo, hi = pts.reshape(-1, 3).min(axis=0), pts.reshape(-1, 3).max(axis=0)
    c, r = 0.5 * (lo + hi), 0.55 * max(hi - lo)
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))


def stick_grid(robot: Robot, qs: np.ndarray, labels: Sequence[str], cols: int = 4, title: str = "") -> Figure:
    """One 3-D stick figure per configuration ``qs`` (K, n), same axes limits (Nammoto & Kosuge 2012, Fig. 10)."""
    pts = stick_points(robot, np.atleast_2d(qs))
    K = pts.shape[0]
    rows = -(-K // cols)
    fig = Figure(figsize=(3.2 * cols, 3.2 * rows + 0.6), layout="constrained")
    for k in range(K):
        ax = fig.add_subplot(rows, cols, k + 1, projection="3d")
        ax.plot([0.0], [0.0], [0.0], "k^", ms=6)
        _draw_stick(ax, pts[k], "tab:blue")
        _equal_3d(ax, pts)
        ax.set_title(labels[k], fontsize=9)
        ax.tick_params(labelsize=6)
        ax.view_init(elev=25, azim=-60)
    fig.suptitle(title, fontsize=11)
    return fig


def stick_overlay(robot: Robot, qs: np.ndarray, labels: Sequence[str], title: str = "") -> Figure:
    """Configurations ``qs`` (K, n) overlaid: 3-D (left) and projected on the x-y plane (right).

    Nammoto & Kosuge 2012, Figs. 12/13: the same end-effector pose at several δ; the elbow
    sweeps while the hand stays put.
    """
    pts = stick_points(robot, np.atleast_2d(qs))
    cmap = matplotlib.colormaps["viridis"]
    colors = [cmap(k / max(1, len(pts) - 1)) for k in range(len(pts))]
    fig = Figure(figsize=(13, 6.2), layout="constrained")
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    for k, p in enumerate(pts):
        _draw_stick(ax3, p, colors[k], labels[k])
        _draw_stick(ax2, p, colors[k], labels[k], dims=(0, 1))
    ax3.plot([0.0], [0.0], [0.0], "k^", ms=7)
    ax2.plot([0.0], [0.0], "k^", ms=7)
    _equal_3d(ax3, pts)
    ax3.view_init(elev=20, azim=-50)
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_title("3-D", fontsize=10)
    ax2.set_aspect("equal")
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.set_title("projection on the x-y plane", fontsize=10)
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=8, loc="best")
    fig.suptitle(title, fontsize=11)
    return fig


SAME_PLACE = 1e-9
"""m: link capsules this close in every end point are drawn as one picture (:func:`same_links`)."""


def same_links(robot: Robot, qs: np.ndarray) -> list[list[int]]:
    """Groups of the configurations qs (K, n) whose link capsules lie at the same place (every capsule end point
    within :data:`SAME_PLACE`), in order of first appearance: configurations that differ only by turning joints by
    π about their own axes (a wrist flip θ5 + π, −θ6, θ7 + π, ...), which every picture of the arm shows alike."""
    segs = robot.capsule_segments(np.atleast_2d(qs)).reshape(len(np.atleast_2d(qs)), -1)
    groups: list[list[int]] = []
    for k, seg in enumerate(segs):
        for g in groups:
            if np.abs(segs[g[0]] - seg).max() <= SAME_PLACE:
                g.append(k)
                break
        else:
            groups.append([k])
    return groups


def _flips(n: int) -> dict[str, tuple[tuple[int, str], ...]]:
    """The named flips of an n-joint arm (0-based joint, what happens to it): the shoulder's first three joints and
    the wrist's last three, (+π, mirrored, +π)."""
    return {"shoulder flip": ((0, "+π"), (1, "−"), (2, "+π")),
            "wrist flip": ((n - 3, "+π"), (n - 2, "−"), (n - 1, "+π"))}  # fmt: skip


def _turn(q: np.ndarray, how: tuple[tuple[int, str], ...]) -> np.ndarray:
    out = np.array(q, float)
    for j, kind in how:
        out[j] = out[j] + PI if kind == "+π" else -out[j]
    return out


def flip(qa: np.ndarray, qb: np.ndarray, tol: float = 1e-9) -> str:
    """How configuration qb differs from qa (rad, angles modulo 2π), checked numerically.

    The named flips first: the wrist flip (θ5 + π, −θ6, θ7 + π for 7 joints), the shoulder flip (θ1 + π, −θ2, θ3 + π)
    or both, e.g. ``"θ5+π, −θ6, θ7+π (wrist flip)"``; otherwise joint by joint, ``−θj`` (mirrored), ``π−θj``,
    ``θj+π`` or both values."""
    qa, qb = np.asarray(qa, float), np.asarray(qb, float)
    flips = _flips(len(qa))
    for r in (1, 2):
        for names in itertools.combinations(flips, r):
            how = tuple(x for name in names for x in flips[name])
            if len({j for j, _ in how}) == len(how) and np.abs(wrap(_turn(qa, how) - qb)).max() <= tol:
                text = ", ".join(f"θ{j + 1}+π" if kind == "+π" else f"−θ{j + 1}" for j, kind in sorted(how))
                return f"{text} ({' and '.join(names)})"
    parts = []
    for j, (a, b) in enumerate(zip(qa, qb)):
        if abs(wrap(b - a)) <= tol:
            continue
        if abs(wrap(b + a)) <= tol:
            parts.append(f"−θ{j + 1}")
        elif abs(wrap(b + a - PI)) <= tol:
            parts.append(f"π−θ{j + 1}")
        elif abs(wrap(b - a - PI)) <= tol:
            parts.append(f"θ{j + 1}+π")
        else:
            parts.append(f"θ{j + 1} {a:.2f} → {b:.2f}")
    return ", ".join(parts) if parts else "the same joint angles"


def flip_lines(branches: Sequence[int], qs: np.ndarray, groups: list[list[int]]) -> list[str]:
    """One line per way two branches of a group of :func:`same_links` differ (:func:`flip`, each against the
    group's first): ``"θ5+π, −θ6, θ7+π (wrist flip): 2 vs 1, 4 vs 3"``."""
    pairs: dict[str, list[str]] = {}
    for g in groups:
        for k in g[1:]:
            pairs.setdefault(flip(qs[g[0]], qs[k]), []).append(f"{branches[k]} vs {branches[g[0]]}")
    return [f"{how}: {', '.join(p)}" for how, p in pairs.items()]


def branch_pictures(
    robot: Robot, sols: IKSolutions, path: Path, cols: int | None = None, only_valid: bool = True
) -> str:
    """Write the branch poses of one pose's :class:`IKSolutions` to the PNG ``path``, one picture per way the
    branches place the links (:func:`same_links`).

    Branches that put every link at the same place (such as a wrist flip θ5 + π, −θ6, θ7 + π) share a picture,
    titled with their ids (and those outside the joint limits); the caption says how their joint angles differ
    (:func:`flip_lines`). Drawn by :func:`qpik.render.pictures.render_configurations` (MuJoCo, needs OpenGL), else
    as stick figures (:func:`stick_points`). Returns ``"render"``, ``"sticks"`` (what was used) or ``"none"`` (no branch
    reaches the pose: the PNG says so).
    """
    keep = sols.valid if only_valid else np.ones(len(sols), bool)
    qs, ids, inside = sols.q[keep], sols.branch[keep].tolist(), sols.within_limits[keep]
    sym = symbol(sols.param_name)
    par = float(np.asarray(sols.param))
    path = Path(path)
    if not len(qs):
        fig = Figure(figsize=(6, 2))
        fig.text(0.5, 0.5, f"{robot.name}: no branch reaches this pose at {sym} = {par:.2f}", ha="center")
        save(fig, path)
        return "none"
    groups = same_links(robot, qs)
    reps = qs[[g[0] for g in groups]]
    titles = []
    for g in groups:
        out = [str(ids[k]) for k in g if not inside[k]]
        titles.append(("branches " if len(g) > 1 else "branch ") + ", ".join(str(ids[k]) for k in g)
                      + (f"\n({', '.join(out)} outside the joint limits)" if out else ""))  # fmt: skip
    from qpik.render.pictures import RenderUnavailable, Tiles, render_configurations

    size = (480, 400)
    try:
        image = render_configurations(robot, reps, None, tiles=Tiles(cols=len(reps), size=size))
        tiles, how = [image[:, k * size[0] : (k + 1) * size[0]] for k in range(len(reps))], "render"
    except RenderUnavailable:
        tiles, how = None, "sticks"
    cols = cols or min(4 if tiles is None else 2, len(reps))
    rows = -(-len(reps) // cols)
    caption = flip_lines(ids, qs, groups)
    fig = Figure(figsize=(4.8 * cols, 4.3 * rows + 0.9 + 0.22 * len(caption)), layout="constrained")
    pts = stick_points(robot, reps)
    for k, title in enumerate(titles):
        if tiles is not None:
            ax = fig.add_subplot(rows, cols, k + 1)
            ax.imshow(tiles[k])
            ax.set_axis_off()
        else:
            ax = fig.add_subplot(rows, cols, k + 1, projection="3d")
            ax.plot([0.0], [0.0], [0.0], "k^", ms=6, label="base")
            _draw_stick(ax, pts[k], "tab:blue")
            ax.lines[-2].set_label("DH frame origins")
            ax.lines[-1].set_label("hand")
            _equal_3d(ax, pts)
            ax.tick_params(labelsize=7)
            ax.view_init(elev=25, azim=-60)
            if k == 0:
                ax.legend(fontsize=8, loc="upper left")
        ax.set_title(title, fontsize=13)
    shown = "rendered" if tiles is not None else "stick figures"
    head = (f"{robot.name}: the {len(qs)} branches at {sym} = {par:.2f} rad place the links in {len(groups)}"
            f" way{'s' if len(groups) > 1 else ''} ({shown})")  # fmt: skip
    if caption:  # below the pictures, inside the layout
        fig.supxlabel("Branches in one picture put every link at the same place; their joint angles differ by\n"
                      + "\n".join(caption), x=0.01, ha="left", fontsize=10)  # fmt: skip
    fig.suptitle(head, fontsize=13)
    save(fig, path)
    return how
