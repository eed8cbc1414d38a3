"""Figures of a self-motion plan (:func:`qpik.plan_self_motion`), on matplotlib ``Figure`` objects.

- :func:`plan_map`: the parameter (vertical) against path progress (horizontal), one panel per
  branch, the infeasible states shaded (outside the joint limits or closer than d_s to an obstacle, as
  the DP's grid saw them), the DP's profile (dots), the plan's (line) and its baselines' (dashed) drawn on the
  branch they use;
- :func:`joint_trajectories`: every joint against path progress with the regions past its limits
  shaded, the plan and its baselines;
- :func:`render_plan`: an image strip of the arm along the plan with the obstacles (MuJoCo offscreen;
  None without OpenGL).

Each figure has one legend that names every line, marker and shading.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from qpik.analytic.intervals import wrap
from qpik.core.errors import InputError
from qpik.planning.plan import Plan
from qpik.plots.closed_form import legend_entries, symbol
from qpik.render.pictures import RenderUnavailable, Tiles, render_configurations

SHADE = ListedColormap([(0.78, 0.78, 0.78, 1.0), (1.0, 1.0, 1.0, 0.0)])
"""Infeasible states grey, feasible ones clear."""


def plan_map(plan: Plan, title: str | None = None, others: Sequence[Plan] = ()) -> Figure:
    """The self-motion map of ``plan`` (a closed-form plan with a DP profile) and, dashed, of the plans ``others``
    (baselines on the same waypoints); see the module docstring."""
    prof = plan.profile
    if prof is None:
        raise InputError("plan: no DP profile (an arm without a closed form, or a baseline)")
    B = prof.ok.shape[1]
    x = plan.progress
    sym = symbol(plan.param_name)
    cols = min(B, 4)
    rows = -(-B // cols)
    fig = Figure(figsize=(3.4 * cols, 2.8 * rows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True, sharey=True)).ravel()
    extent = (x[0], x[-1], -np.pi, np.pi)
    K = len(plan.q)
    row_of, param_of = _rows(plan, list(prof.branches))
    for b, ax in enumerate(axes[:B]):
        ax.imshow(prof.ok[:, b, :].T, origin="lower", aspect="auto", extent=extent, cmap=SHADE, vmin=0, vmax=1,
                  interpolation="nearest")  # fmt: skip
        on = prof.dp_row[:K] == b
        if on.any():
            ax.plot(x[:K][on], prof.dp_param[:K][on], ".", color="tab:orange", ms=2.5, label="DP")
        mine = row_of == b
        if mine.any():
            ax.plot(x[:K], np.where(mine, param_of, np.nan), color="tab:blue", lw=1.4, label=plan.label or "plan")
        for k, other in enumerate(others):
            if not len(other.q) or not len(other.branch):
                continue
            row, param = _rows(other, list(prof.branches))
            if (row == b).any():
                ax.plot(other.progress[: len(other.q)], np.where(row == b, param, np.nan), "--", lw=1.2,
                        color=f"C{k + 2}", label=other.label)  # fmt: skip
        ax.set_title(f"branch {prof.branches[b]}" + (f" (and {prof.branches[b] + B})" if _mirrored(plan, B) else ""),
                     fontsize=9)  # fmt: skip
        ax.set_ylim(-np.pi, np.pi)
        ax.grid(alpha=0.2)
    handles, labels = legend_entries(fig)
    grey = "infeasible: outside the joint limits" + (" or closer than d_s" if len(plan.obstacles) else "")
    fig.legend([*handles, Patch(color=SHADE(0), label=grey)], [*labels, grey], loc="outside lower center",
               ncol=min(4, len(labels) + 1), fontsize=8)  # fmt: skip
    for ax in axes[B:]:
        ax.set_axis_off()
    for ax in axes[(rows - 1) * cols : B]:
        ax.set_xlabel("time [s]" if plan.times is not None else "path progress")
    for ax in axes[::cols]:
        ax.set_ylabel(f"{sym} [rad]")
    fig.suptitle(title or f"{plan.robot.name}: {sym} along the path, one panel per branch")
    return fig


def _mirrored(plan: Plan, B: int) -> bool:
    return len(plan.profile.branches) == B and plan.param_name == "delta"


def _rows(plan: Plan, ids: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The plan's grid row and parameter in the grid's terms, for grid rows of the public branch ids ``ids`` (B,) (a
    mirrored branch b + B at δ is row b at δ + π)."""
    B = len(ids)
    row = np.array([ids.index(b) if b in ids else ids.index(b - B) + B for b in plan.branch])
    far = row >= B
    return np.where(far, row - B, row), np.where(far, wrap(plan.param + np.pi), plan.param)


def joint_trajectories(plan: Plan, others: Sequence[Plan] = (), title: str | None = None) -> Figure:
    """Every joint of ``plan`` (and dashed, of ``others``) against path progress, beyond-limit regions shaded."""
    robot = plan.robot
    n = robot.dof
    fig = Figure(figsize=(13, 2.3 * -(-n // 3) + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(-(-n // 3), 3, sharex=True)).ravel()
    for j in range(n):
        ax = axes[j]
        lo, hi = float(robot.q_min[j]), float(robot.q_max[j])
        allq = np.concatenate([p.q[:, j] for p in (plan, *others) if len(p.q)])
        pad = 0.1 * (hi - lo)
        bottom, top = min(lo, allq.min()) - pad, max(hi, allq.max()) + pad
        ax.axhspan(bottom, lo, color="tab:red", alpha=0.15, lw=0, label="beyond the joint limits" if not j else None)
        ax.axhspan(hi, top, color="tab:red", alpha=0.15, lw=0)
        for k, p in enumerate(others):
            ax.plot(p.progress[: len(p.q)], p.q[:, j], "--", lw=1.0, color=f"C{k + 2}", label=p.label)
        ax.plot(plan.progress[: len(plan.q)], plan.q[:, j], color="C0", lw=1.6, label=plan.label or "plan")
        ax.set_ylim(bottom, top)
        ax.set_title(f"joint {j + 1}", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[n:]:
        ax.set_axis_off()
    for ax in axes[max(0, n - 3) : n]:
        ax.set_xlabel("time [s]" if plan.times is not None else "path progress")
    handles, labels = legend_entries(fig)
    fig.legend(handles, labels, loc="outside lower center", ncol=min(4, len(labels)), fontsize=8)
    fig.suptitle(title or f"{robot.name}: joint angles [rad] along the path")
    return fig


def render_plan(
    plan: Plan, path: str | os.PathLike, frames: int = 6, size: tuple[int, int] = (360, 320)
) -> Path | None:
    """A PNG of ``frames`` snapshots of the arm along the plan (evenly spaced waypoints) with the obstacles;
    None when no OpenGL context can be made."""
    if not len(plan.q):
        return None
    idx = np.unique(np.linspace(0, len(plan.q) - 1, max(1, frames)).round().astype(int))
    unit = "s" if plan.times is not None else ""
    labels = [f"waypoint {i}" + (f", t = {plan.progress[i]:.2f} {unit}" if unit else "") for i in idx]
    extra = [replace(o, name=None).to_mjcf_geom() for o in plan.obstacles.shapes]
    try:
        render_configurations(
            plan.robot,
            plan.q[idx],
            path,
            extra_worldbody=extra,
            tiles=Tiles(cols=min(3, len(idx)), size=size, labels=labels),
        )
    except RenderUnavailable:
        return None
    return Path(path)
