"""Feasible redundancy-parameter sets: types and the shared interval assembly.

A solver finds, analytically, every parameter value where something can
change for a branch: a joint reaching a limit, a joint jumping (wrap or a
singular point), the branch becoming invalid. Between two consecutive such
*breakpoints* a branch is either feasible throughout or nowhere, so one
evaluation at each gap's midpoint classifies the gap. This is not
sampling: the boundaries are the analytic breakpoints themselves.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from qpik import symbolic as sy

TWO_PI = 2.0 * np.pi
SAME = 1e-9
"""Breakpoints (rad) closer than this are one: a gap narrower than that is not classified, so a
boundary may be off by as much (the equations of nearly coincident breakpoints, such as a validity
test and its tolerant twin, are solved to about this accuracy anyway)."""

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
    lo, hi = gaps(b)
    ok = np.asarray(feasible_at(wrap(0.5 * (lo + hi))), dtype=bool)
    return merge(lo, hi, ok)


def gaps(breaks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gaps ``(lo[i], hi[i])`` (rad) between breakpoints (any order, any branch of 2π, at least one).

    ``lo`` are the breakpoints wrapped to (−π, π] and sorted, one per cluster of breakpoints
    within :data:`SAME` of each other; ``hi`` the next one, the last gap ending at
    ``lo[0] + 2π``: together the gaps tile the circle.
    """
    lo = wrap(np.asarray(breaks, dtype=float).ravel())
    lo.sort()
    lo = lo[np.concatenate(([True], lo[1:] - lo[:-1] > SAME))]  # one breakpoint per cluster within SAME
    hi = np.empty_like(lo)
    hi[:-1], hi[-1] = lo[1:], lo[0] + TWO_PI
    return lo, hi


def merge(lo: np.ndarray, hi: np.ndarray, ok: np.ndarray) -> list[list[Interval]]:
    """Join the feasible gaps (lo[i], hi[i]) (ok (G, B)) into sorted disjoint intervals of [-pi, pi] per branch.

    The gaps tile the circle, so each branch's set is its runs of feasible gaps
    (a run may continue from the last gap into the first); a run that ends past
    π is split at ±π. The runs are found by one regular-expression scan of the
    flags as bytes (C speed; G is of order 100).
    """
    G, B = ok.shape
    W = G + 1
    lo_l, hi_l = lo.tolist(), hi.tolist()
    flags = np.zeros((B, W), np.uint8)  # one row per branch, a 0 after each: runs stay in their row
    flags[:, :G] = ok.T
    runs: list[list[tuple[int, int]]] = [[] for _ in range(B)]
    for m in _RUN.finditer(flags.tobytes()):
        a, b = m.span()
        j = a // W
        runs[j].append((a - j * W, b - 1 - j * W))  # first and last gap of the run
    out: list[list[Interval]] = []
    for r in runs:
        if r and r[0][0] == 0 and r[-1][1] == G - 1:  # feasible in gap 0 and in gap G-1
            if r[0][1] == G - 1:
                out.append([(-np.pi, np.pi)])
                continue
            if len(r) > 1:  # the last run continues into the first, across ±π: split there
                ivs = [(lo_l[s], hi_l[e]) for s, e in r[1:-1]]
                out.append([(-np.pi, hi_l[r[0][1]]), *ivs, (lo_l[r[-1][0]], np.pi)])
                continue
        ivs = [(lo_l[s], hi_l[e]) for s, e in r]
        if ivs and ivs[-1][1] > np.pi:  # only the last run can pass π: split it there
            a, end = ivs.pop()
            ivs = [(-np.pi, end - TWO_PI), *ivs, (a, np.pi)]
        out.append(ivs)
    return out


_RUN = re.compile(b"\x01+")


def shift(intervals: list[Interval], by: float) -> list[Interval]:
    """The set ``intervals`` (sorted, disjoint, in [−π, π]) moved by ``by`` ∈ [0, 2π) on the circle, same form."""
    moved: list[Interval] = []
    for a, b in intervals:
        a, b = a + by, b + by
        if a > np.pi:
            a, b = a - TWO_PI, b - TWO_PI
        moved += [(a, np.pi), (-np.pi, b - TWO_PI)] if b > np.pi else [(a, b)]
    moved.sort()
    out: list[Interval] = []
    for a, b in moved:  # pieces that met at ±π before the move meet inside now
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out
