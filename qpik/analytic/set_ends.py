r"""A near member's feasible sets with their ends moved onto the file's own chain.

A near member's sets (:mod:`qpik.analytic.locked_joint_intervals`) are isolated on its ideal chain, whose branches
differ from the file's by the correction and polish of :mod:`qpik.analytic.locked_joint`: each end of a set is off
from the file's by about that change of the joints over the slope of the joint at its level (milliradians on the
Gen3 file, whose axes miss by 0.35 mm). :func:`refine_ends` moves each end to where the file's branch really enters
or leaves the (shrunk) limits, by bisection on the file's answer: branch b at parameter t is *inside* when it is
valid and every joint lies within the limits (:meth:`~qpik.analytic.solver.BranchSolver.solve_many`, every end of
every branch moved at once, one compiled sweep per step).

The bracket of an end is the middle of the gap beside it (outside) and the middle of its own interval (inside), each
checked first; an end whose bracket does not hold those states is left where it was. Bisection keeps the bracket's
states at its ends, so the end found is where the state changes, to :data:`WIDTH`; where the file's branch enters
and leaves the limits more than once between the two middles, it finds one of the changes. Ends at ±π where a set
that wraps through them is split are not ends and stay. The answer stays unproved (``proved`` False).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.intervals import FeasibleIntervals, Interval, shrunk_limits

if TYPE_CHECKING:
    from qpik.analytic.solver import BranchSolver

WIDTH = 1e-12
"""rad: the width of a bisection bracket at which the end is its middle."""
STEPS = 48
"""Most bisection steps (halving a bracket of 2π to below :data:`WIDTH` needs 43)."""


def refine_ends(fi: FeasibleIntervals, solver: BranchSolver, T: np.ndarray, margin: float) -> FeasibleIntervals:
    """``fi``, the sets of ``solver`` at the pose ``T`` (4, 4) under the limits shrunk by ``margin``
    (:func:`~qpik.analytic.intervals.shrunk_limits`), with every end moved by bisection on the solver's answers
    (module docstring); the same branches, as many intervals, ``proved`` False."""
    lo_q, hi_q = shrunk_limits(solver.robot.q_min, solver.robot.q_max, margin)

    def inside(t: np.ndarray) -> np.ndarray:
        """(M, B) bool at parameters t (M,) rad: each branch valid and within the shrunk limits."""
        s = solver.solve_many(T, t)
        return s.valid & np.all((s.q >= lo_q) & (s.q <= hi_q), axis=-1)

    ends = []  # (branch index, interval index, 0 for lo / 1 for hi, the outside point, the inside point)
    for k, intervals in enumerate(fi.intervals):
        for i, (lo, hi) in enumerate(intervals):
            mid = 0.5 * (lo + hi)
            before = intervals[i - 1][1] if i else -np.pi
            after = intervals[i + 1][0] if i + 1 < len(intervals) else np.pi
            if lo > -np.pi:
                ends.append((k, i, 0, 0.5 * (before + lo), mid))
            if hi < np.pi:
                ends.append((k, i, 1, 0.5 * (hi + after), mid))
    new = [list(x) for x in fi.intervals]
    if ends:
        k = np.array([e[0] for e in ends])
        out, into = np.array([e[3] for e in ends]), np.array([e[4] for e in ends])
        rows = np.arange(len(ends))
        ok = ~inside(out)[rows, k] & inside(into)[rows, k]
        for _ in range(STEPS):
            live = ok & (np.abs(into - out) > WIDTH)
            if not live.any():
                break
            mid = 0.5 * (out + into)
            now = inside(mid[live])[np.arange(int(live.sum())), k[live]]
            into[np.flatnonzero(live)[now]] = mid[live][now]
            out[np.flatnonzero(live)[~now]] = mid[live][~now]
        for (b, i, side, _, _), good, a, c in zip(ends, ok, out, into):
            if good:
                lo, hi = new[b][i]
                end = 0.5 * (a + c)
                new[b][i] = (end, hi) if side == 0 else (lo, end)
    intervals: list[list[Interval]] = [[(float(lo), float(hi)) for lo, hi in x] for x in new]
    return FeasibleIntervals(fi.param_name, fi.branch, intervals, fi.singular, proved=False)
