"""Feasible redundancy-parameter sets: types and the shared interval assembly.

A solver finds, analytically, every parameter value where something can
change for a branch: a joint reaching a limit, a joint jumping (wrap or a
singular point), the branch becoming invalid. Between two consecutive such
*breakpoints* a branch is either feasible throughout or nowhere, so one
evaluation at each gap's midpoint classifies the gap. This is not
sampling: the boundaries are the analytic breakpoints themselves.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from qpik import symbolic as sy

TWO_PI = 2.0 * np.pi

Interval = tuple[float, float]


@dataclass
class FeasibleIntervals:
    """Per branch, the parameter values (rad, in (-pi, pi]) where all joints are within limits.

    Attributes:
        param_name: ``"delta"`` or ``"psi"``.
        branch: public branch ids, shape (B,).
        intervals: per branch, sorted disjoint closed intervals ``(lo, hi)`` with
            ``lo <= hi``; a set that wraps through ±pi is split in two.
        singular: per branch, parameter values where some joint is singular.
    """

    param_name: str
    branch: np.ndarray
    intervals: list[list[Interval]]
    singular: list[list[float]] = field(default_factory=list)

    def __getitem__(self, b: int) -> list[Interval]:
        """Intervals of the branch with public id ``b``."""
        return self.intervals[self.index(b)]

    def index(self, b: int) -> int:
        hits = np.flatnonzero(self.branch == b)
        if hits.size == 0:
            raise KeyError(f"no branch {b}; branches are {self.branch.tolist()}")
        return int(hits[0])

    def contains(self, b: int, value: float | np.ndarray, tol: float = 0.0) -> np.ndarray | bool:
        """Whether ``value`` (rad, any shape) lies in branch ``b``'s feasible set."""
        v = np.asarray(value, dtype=float)
        out = np.zeros(v.shape, dtype=bool)
        for lo, hi in self[b]:
            out |= (v >= lo - tol) & (v <= hi + tol)
        return bool(out) if out.ndim == 0 else out

    def measure(self, b: int) -> float:
        """Total length (rad) of branch ``b``'s feasible set."""
        return float(sum(hi - lo for lo, hi in self[b]))


def wrap(x: np.ndarray | float) -> np.ndarray:
    """Wrap angles (rad, any shape) to (-pi, pi]: :meth:`qpik.symbolic.Ops.wrap` on a float array."""
    return sy.NUMPY.wrap(np.asarray(x, dtype=float))


def assemble_many(breaks: np.ndarray, feasible_at: Callable[[np.ndarray], np.ndarray]) -> list[list[Interval]]:
    """Feasible intervals on the circle of B branches from shared breakpoints and a midpoint test.

    Args:
        breaks: parameter values (rad, any order, any branch of 2π) where the
            feasibility of some branch may change.
        feasible_at: maps parameter values (M,) to booleans (M, B); one call
            classifies every gap of every branch (one batched IK evaluation).

    Returns:
        Per branch, sorted disjoint closed intervals in [-pi, pi].
    """
    b = np.unique(np.round(wrap(np.asarray(breaks, dtype=float).ravel()), 15))
    if b.size == 0:
        ok = np.asarray(feasible_at(np.array([0.0])), dtype=bool)[0]
        return [[(-np.pi, np.pi)] if o else [] for o in ok]
    # gaps (b[i], b[i+1]) and the wrap-around gap (b[-1], b[0] + 2π)
    lo = b
    hi = np.append(b[1:], b[0] + TWO_PI)
    ok = np.asarray(feasible_at(wrap(0.5 * (lo + hi))), dtype=bool)
    return _merge(lo, hi, ok)


def _merge(lo: np.ndarray, hi: np.ndarray, ok: np.ndarray) -> list[list[Interval]]:
    """Join the feasible gaps (lo[i], hi[i]) (ok (G, B)) into sorted disjoint intervals of [-pi, pi] per branch.

    The gaps tile the circle, so each branch's set is its runs of feasible gaps
    (a run may continue from the last gap into the first); a run that ends past
    π is split at ±π.
    """
    B = ok.shape[1]
    start = ok & ~np.roll(ok, 1, axis=0)  # first gap of a run
    end = ok & ~np.roll(ok, -1, axis=0)  # last gap of a run
    s_branch, s_gap = np.nonzero(start.T)
    e_gap = np.nonzero(end.T)[1]
    counts = np.bincount(s_branch, minlength=B).tolist()
    seam = (ok[0] & ok[-1]).tolist()  # a run crosses from gap G-1 into gap 0
    full = ok.all(axis=0).tolist()
    lo_l, hi_l, s_l, e_l = lo.tolist(), hi.tolist(), s_gap.tolist(), e_gap.tolist()
    out: list[list[Interval]] = []
    k = 0
    for j in range(B):
        m = counts[j]
        starts, ends = s_l[k : k + m], e_l[k : k + m]
        k += m
        if full[j]:
            out.append([(-np.pi, np.pi)])
            continue
        if seam[j]:
            ends = ends[1:] + ends[:1]  # the run starting last ends in the first gaps
        ivs = [(lo_l[s], hi_l[e]) for s, e in zip(starts, ends)]
        if ivs and (ends[-1] < starts[-1] or ivs[-1][1] > np.pi):  # only the last run can pass π
            a, c = ivs.pop()
            ivs = [(-np.pi, c if ends[-1] < starts[-1] else c - TWO_PI), *ivs, (a, np.pi)]
        out.append(ivs)
    return out
