"""Pictures of closed-loop runs: multi-panel PNGs of a :class:`SimLog`, overlays of several, snapshot strips.

Figures are drawn on :class:`matplotlib.figure.Figure` objects (no pyplot state,
no display needed). Snapshots go through :mod:`qpik.render.pictures`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from qpik.plots.files import save
from qpik.render.pictures import Camera, RenderUnavailable, Tiles, render_configurations
from qpik.robots.robot import Robot
from qpik.sim.log import SimLog

ERROR_FLOOR = 1e-12
"""Errors below this (m, rad) are drawn at this value on log axes."""
TARGET_MARK = '<geom type="sphere" pos="{}" size="0.02" rgba="0.1 0.75 0.2 0.9" contype="0" conaffinity="0"/>'


def plot_log(log: SimLog, path: str | os.PathLike, title: str | None = None) -> Path:
    """One PNG of a run: tracking errors, clearance per link, manipulability, each joint against its limits.

    Panels: position (m) and orientation (rad) error vs time on a log scale;
    each link's distance to its nearest obstacle (m) with ``log.d_safe`` marked;
    manipulability vs time; one small panel per joint (rad) with the region
    past each limit shaded (the first joint's legend says so).
    """
    fig = Figure(figsize=(13, 9), layout="constrained")
    grid = fig.add_gridspec(3, 4)
    _errors(fig.add_subplot(grid[0, :2]), [log], single=True)
    _clearance(fig.add_subplot(grid[0, 2:]), log)
    n = log.q.shape[1]
    slots = [(1 + j // 4, j % 4) for j in range(n)]
    for j, (r, c) in enumerate(slots[: min(n, 7)]):
        _joint(fig.add_subplot(grid[r, c]), log, j, legend=not j)
    ax = fig.add_subplot(grid[2, 3])
    ax.plot(log.t, log.manipulability, color="tab:purple")
    ax.set(xlabel="t (s)", ylabel="manipulability", title="sqrt(det(J Jᵀ))")
    ax.grid(alpha=0.3)
    fig.suptitle(title or log.label)
    return save(fig, path, dpi=100)


def plot_comparison(logs: Sequence[SimLog], path: str | os.PathLike, title: str = "") -> Path:
    """Tracking-error curves of several runs overlaid (log scale): position (m) and orientation (rad)."""
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    ax_p, ax_o = fig.subplots(1, 2)
    _errors(ax_p, logs, which=0)
    _errors(ax_o, logs, which=1)
    if title:
        fig.suptitle(title)
    return save(fig, path, dpi=100)


def render_strip(
    log: SimLog,
    path: str | os.PathLike,
    frames: int = 6,
    size: tuple[int, int] = (360, 320),
    camera: Camera | None = None,
) -> Path | None:
    r"""A PNG of ``frames`` snapshots with the obstacles and the final target (a green dot, which the first label
    names).

    The snapshots are evenly spaced along the joint-space path (arc length
    :math:`\sum \lVert q_{k+1} - q_k \rVert`), so a motion that settles early is
    not drawn as a row of identical pictures; in up to 3 columns.
    Returns the path, or ``None`` when no OpenGL context can be made
    (:func:`qpik.render.pictures.unavailable_reason` says why).
    """
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(log.q, axis=0), axis=1))])
    if arc[-1] > 0:
        idx = np.searchsorted(arc, np.linspace(0.0, arc[-1], max(1, frames)) - 1e-12).clip(0, len(log) - 1)
    else:
        idx = np.linspace(0, len(log) - 1, max(1, frames)).round().astype(int)
    idx = np.unique(idx)
    cols = min(3, len(idx))
    marks = [] if log.target is None else [TARGET_MARK.format(_fmt(log.target[i, :3, 3])) for i in idx[-1:]]
    labels = [f"t = {log.t[i]:.2f} s" for i in idx]
    if marks:
        labels[0] += "  (green dot: the final target)"
    try:
        if isinstance(log.robot, Robot):
            extra = [replace(o, name=None).to_mjcf_geom() for o in log.obstacles] + marks  # names may repeat
            render_configurations(
                log.robot,
                log.q[idx],
                path,
                extra_worldbody=extra,
                tiles=Tiles(cols=cols, size=size, camera=camera, labels=labels),
            )
        else:  # an MJCF arm: its model already holds the obstacles
            render_configurations(
                log.robot, log.q[idx], path, tiles=Tiles(cols=cols, size=size, camera=camera, labels=labels)
            )
    except RenderUnavailable:
        return None
    return Path(path)


# ---- panels ------------------------------------------------------------------


def _errors(ax, logs: Sequence[SimLog], which: int | None = None, single: bool = False) -> None:
    """Position (which=0) and/or orientation (which=1) errors of each log, log scale."""
    for log in logs:
        if log.target is None:
            continue
        e = log.errors
        if which in (None, 0):
            ax.semilogy(log.t, np.maximum(e[0], ERROR_FLOOR), label="position (m)" if single else log.label)
        if which in (None, 1):
            style = "--" if which is None else "-"
            ax.semilogy(log.t, np.maximum(e[1], ERROR_FLOOR), style, label="orientation (rad)" if single else log.label)
    name = {None: "tracking error", 0: "position error (m)", 1: "orientation error (rad)"}[which]
    ax.set(xlabel="t (s)", ylabel=name, title=f"{name}\n(below {ERROR_FLOOR:g}: drawn at {ERROR_FLOOR:g})")
    ax.grid(alpha=0.3, which="both")
    if ax.lines:
        ax.legend(fontsize=8)


def _clearance(ax, log: SimLog) -> None:
    """Each link's distance to its nearest obstacle (m), with d_s."""
    if log.clearance.shape[2] == 0:
        ax.text(0.5, 0.5, "no obstacles", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return
    dmin = log.min_clearance
    for i, name in enumerate(log.link_names):
        ax.plot(log.t, dmin[:, i], lw=1.2, label=name.replace("_capsule", ""))
    if log.d_safe is not None:
        ax.axhline(log.d_safe, color="k", ls="--", lw=1, label=f"d_s = {log.d_safe:g} m")
    ax.axhline(0.0, color="tab:red", lw=0.8, label="contact (0 m)")
    ax.set(xlabel="t (s)", ylabel="clearance (m)", title="clearance per link (MuJoCo)")
    ax.set_ylim(min(-0.01, float(dmin.min()) - 0.01), min(float(dmin.max()) + 0.02, 0.6))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)


def _joint(ax, log: SimLog, j: int, legend: bool = False) -> None:
    """Joint j (rad) against its limits; the regions past the limits shaded (with ``legend``, a legend says so)."""
    lo, hi = float(log.q_min[j]), float(log.q_max[j])
    q = log.q[:, j]
    span = max(hi - lo, float(np.ptp(q)), 1e-3) if np.isfinite(hi - lo) else max(float(np.ptp(q)), 1.0)
    pad = 0.12 * span
    bottom = min(lo, float(q.min())) - pad if np.isfinite(lo) else float(q.min()) - pad
    top = max(hi, float(q.max())) + pad if np.isfinite(hi) else float(q.max()) + pad
    label = "beyond the limits" if legend else None
    if np.isfinite(lo):
        ax.axhspan(bottom, lo, color="tab:red", alpha=0.15, lw=0, label=label)
        label = None
    if np.isfinite(hi):
        ax.axhspan(hi, top, color="tab:red", alpha=0.15, lw=0, label=label)
    ax.plot(log.t, q, color="tab:blue", label="joint angle" if legend else None)
    ax.set_ylim(bottom, top)
    ax.set(title=f"joint {j + 1}", xlabel="t (s)", ylabel="rad")
    ax.grid(alpha=0.3)
    if legend:
        ax.legend(fontsize=7, loc="lower right")


def _fmt(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in values)
