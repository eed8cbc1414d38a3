"""The panel of the redundancy parameter's feasible set per branch, in the pictures of :mod:`qpik.plots.closed_form`
and :mod:`qpik.plots.objective`: the exact sets (:func:`qpik.feasible_intervals`), or, for an arm whose sets are not
computed (the 1-D search's, :mod:`qpik.analytic.search_solver`), the runs of sampled values within the limits."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from qpik.analytic.api import IKSolutions, symbol
from qpik.analytic.intervals import FeasibleIntervals


def feasible_panel(ax: Axes, fi: FeasibleIntervals, draw: list[int], shade: int, colors: dict) -> None:
    """Bars of the feasible parameter set of each drawn branch (exact intervals), its singular values as black ticks
    (explained in the panel's legend)."""
    marked = False
    for k, b in enumerate(draw):
        segs = [(lo, hi - lo) for lo, hi in fi[b]]
        ax.broken_barh(segs, (k - 0.35, 0.7), color=colors[b], alpha=1.0 if b == shade else 0.6)
        for s in fi.singular[fi.index(b)] if fi.singular else []:
            label = None if marked else f"singular {symbol(fi.param_name)} of the branch"
            ax.plot([s, s], [k - 0.45, k + 0.45], color="k", lw=1.5, label=label)
            marked = True
    if marked:
        ax.legend(loc="lower right", fontsize=7, framealpha=0.9)
    _branch_axis(ax, draw, f"feasible {symbol(fi.param_name)} per branch (within limits)")


def sampled_panel(ax: Axes, sols: IKSolutions, draw: list[int], colors: dict) -> None:
    """Bars of the runs of samples where each drawn branch is within the limits: ``sols`` is a batched
    :class:`~qpik.analytic.api.IKSolutions` over increasing parameters (num,) rad, and a run is drawn from its first
    sample to its last (not exact sets: ends are known to the samples' spacing, and a run between two samples is
    missed; the title says so)."""
    x = np.asarray(sols.param, dtype=float)
    ids = [int(b) for b in sols.branch]
    for k, b in enumerate(draw):
        inside = sols.within_limits[:, ids.index(b)].astype(int)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], inside, [0]])))
        segs = [(x[lo], x[hi - 1] - x[lo]) for lo, hi in zip(edges[::2], edges[1::2])]
        ax.broken_barh(segs, (k - 0.35, 0.7), color=colors[b], alpha=0.8)
    sym = symbol(sols.param_name)
    _branch_axis(ax, draw, f"within limits at {len(x)} sampled {sym} (no exact sets for this arm)")


def _branch_axis(ax: Axes, draw: list[int], title: str) -> None:
    """The panel's branch axis (one row per drawn branch, the first on top), title and grid."""
    ax.set_yticks(range(len(draw)), [str(b) for b in draw], fontsize=7)
    ax.set_ylim(len(draw) - 0.5, -0.5)
    ax.set_ylabel("branch")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3, axis="x")
