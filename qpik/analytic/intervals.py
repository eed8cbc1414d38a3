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
    """Wrap angles to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(x, dtype=float), TWO_PI)


def assemble(breaks: np.ndarray, feasible_at: Callable[[np.ndarray], np.ndarray]) -> list[Interval]:
    """Feasible intervals on the circle from breakpoints and a midpoint test.

    Args:
        breaks: parameter values (rad, any order, any branch of 2π) where the
            feasibility may change.
        feasible_at: maps parameter values (M,) to booleans (M,).

    Returns:
        Sorted disjoint closed intervals in [-pi, pi].
    """
    return assemble_many(breaks, lambda m: np.asarray(feasible_at(m), dtype=bool)[:, None])[0]


def assemble_many(breaks: np.ndarray, feasible_at: Callable[[np.ndarray], np.ndarray]) -> list[list[Interval]]:
    """:func:`assemble` for B branches that share breakpoints: ``feasible_at`` maps (M,) to (M, B) booleans.

    One call of ``feasible_at`` classifies every gap of every branch (one
    batched IK evaluation). Returns one interval list per branch.
    """
    b = np.unique(np.round(wrap(np.asarray(breaks, dtype=float).ravel()), 15))
    if b.size == 0:
        ok = np.asarray(feasible_at(np.array([0.0])), dtype=bool)[0]
        return [[(-np.pi, np.pi)] if o else [] for o in ok]
    # gaps (b[i], b[i+1]) and the wrap-around gap (b[-1], b[0] + 2π)
    lo = b
    hi = np.append(b[1:], b[0] + TWO_PI)
    ok = np.asarray(feasible_at(wrap(0.5 * (lo + hi))), dtype=bool)
    return [_merge(lo, hi, ok[:, j]) for j in range(ok.shape[1])]


def _merge(lo: np.ndarray, hi: np.ndarray, ok: np.ndarray) -> list[Interval]:
    """Join the feasible gaps (lo[i], hi[i]) into sorted disjoint intervals of [-pi, pi]."""
    out: list[Interval] = []
    for i in np.flatnonzero(ok):
        a, c = float(lo[i]), float(hi[i])
        if out and abs(out[-1][1] - a) < 1e-15:
            out[-1] = (out[-1][0], c)
        else:
            out.append((a, c))
    # merge the last interval into the first across the seam, then split at ±pi
    if len(out) > 1 and abs(out[-1][1] - TWO_PI - out[0][0]) < 1e-15:
        out[0] = (out[-1][0] - TWO_PI, out[0][1])
        out.pop()
    split: list[Interval] = []
    for a, c in out:
        if c - a >= TWO_PI - 1e-15:
            return [(-np.pi, np.pi)]
        if c > np.pi:
            split += [(a, np.pi), (-np.pi, c - TWO_PI)]
        elif a < -np.pi:
            split += [(a + TWO_PI, np.pi), (-np.pi, c)]
        else:
            split.append((a, c))
    return sorted(split)
