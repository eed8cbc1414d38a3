"""The panel of the redundancy parameter's feasible set per branch, in the pictures of :mod:`qpik.plots.closed_form`
and :mod:`qpik.plots.objective`: the sets of :func:`qpik.feasible_intervals`, its title saying where they are not
proved (a near member's, the 1-D search's sampled ones)."""

from __future__ import annotations

from matplotlib.axes import Axes

from qpik.analytic.api import symbol
from qpik.analytic.intervals import FeasibleIntervals


def feasible_panel(ax: Axes, fi: FeasibleIntervals, draw: list[int], shade: int, colors: dict) -> None:
    """Bars of the feasible parameter set of each drawn branch (the intervals of ``fi``; the title says "not proved"
    where ``fi.proved`` is False), its singular values as black ticks (explained in the panel's legend)."""
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
    proof = "" if fi.proved else ", not proved"
    _branch_axis(ax, draw, f"feasible {symbol(fi.param_name)} per branch (within limits{proof})")


def _branch_axis(ax: Axes, draw: list[int], title: str) -> None:
    """The panel's branch axis (one row per drawn branch, the first on top), title and grid."""
    ax.set_yticks(range(len(draw)), [str(b) for b in draw], fontsize=7)
    ax.set_ylim(len(draw) - 0.5, -0.5)
    ax.set_ylabel("branch")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3, axis="x")
