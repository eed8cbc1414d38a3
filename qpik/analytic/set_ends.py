r"""A near member's feasible sets with their ends moved onto the file's own chain.

A near member's sets (:mod:`qpik.analytic.locked_joint_intervals`) are isolated on its ideal chain, whose branches
differ from the file's by the correction and polish of :mod:`qpik.analytic.locked_joint`: each end of a set is off
from the file's by about that change of the joints over the slope of the joint at its level (milliradians on the
Gen3 file, whose axes miss by 0.35 mm). :func:`refine_ends` moves each end to where the file's branch really enters
or leaves the (shrunk) limits, on the file's answers: branch b at parameter t is *inside* when it is valid and every
joint lies within the limits (:meth:`~qpik.analytic.solver.BranchSolver.solve_many`, every end of every branch moved
at once, one compiled sweep per step).

The bracket of an end is first the values ``reach`` either side of it (the caller's estimate of how far it may move),
else the middle of the gap beside it (outside) and the middle of its own interval (inside), each checked; an end
whose bracket does not hold those states is left where it was. Each step keeps the bracket's states at its ends
(regula falsi where the end is a joint reaching a limit, else bisection; :func:`refine_ends`), so the end found is
where the state changes, to :data:`WIDTH`; where the file's branch enters and leaves the limits more than once in the
bracket, it finds one of the changes. Ends at ±π where a set that wraps through them is split are not ends and stay.
The answer stays unproved (``proved`` False).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.intervals import FeasibleIntervals, Interval, shrunk_limits

if TYPE_CHECKING:
    from qpik.analytic.solver import BranchSolver

WIDTH = 1e-11
"""rad: the width of a bracket at which the end is its middle."""
STEPS = 96
"""Most steps per end: every second step halves the bracket, and halving one of 2π to below :data:`WIDTH` takes 40."""
FLAT = 1e-15
"""rad: a step whose joint-limit margin is this close to 0 is the end itself."""


def refine_ends(
    fi: FeasibleIntervals, solver: BranchSolver, T: np.ndarray, margin: float, reach: float
) -> FeasibleIntervals:
    r"""``fi``, the sets of ``solver`` at the pose ``T`` (4, 4) under the limits shrunk by ``margin``
    (:func:`~qpik.analytic.intervals.shrunk_limits`), with every end moved onto the solver's answers (module
    docstring); the same branches, as many intervals, ``proved`` False. ``reach`` (rad): about how far an end may
    move; an end's bracket is first the one within ``reach`` of it, where that holds the states it must.

    Each bracket [a, c] (a outside, c inside) shrinks by one answer per step, every end's at once. Where the branch
    is valid at both ends, the end is a joint reaching a limit, and every second step is the Illinois variant of
    regula falsi (Dowell & Jarratt 1971) on the branch's joint-limit margin
    :math:`\mu(t) = \min_j \min(q_j - l_j, u_j - q_j)` (rad, < 0 outside), superlinear where μ is continuous across
    the end; the other steps, and every step where the branch stops being valid, take the bracket's middle, so that
    the bracket halves at least every second step (μ jumps where a joint whose limits pass ±π takes another
    representative at its limit)."""
    lo_q, hi_q = shrunk_limits(solver.robot.q_min, solver.robot.q_max, margin)

    def state(t: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """At parameters t (M,) rad, branch k (M,) (indices of the sets' order): inside (valid and within the shrunk
        limits) and the margin μ (rad; NaN where the branch is not valid)."""
        s = solver.solve_many(T, t)
        rows = np.arange(len(t))
        q, valid = s.q[rows, k], s.valid[rows, k]
        mu = np.where(valid, np.minimum(q - lo_q, hi_q - q).min(axis=-1), np.nan)
        return valid & (mu >= 0), mu

    ends = []  # (branch index, interval index, 0 for lo / 1 for hi, the end, the outside point, the inside point)
    for k, intervals in enumerate(fi.intervals):
        for i, (lo, hi) in enumerate(intervals):
            mid = 0.5 * (lo + hi)
            before = intervals[i - 1][1] if i else -np.pi
            after = intervals[i + 1][0] if i + 1 < len(intervals) else np.pi
            if lo > -np.pi:
                ends.append((k, i, 0, lo, 0.5 * (before + lo), mid))
            if hi < np.pi:
                ends.append((k, i, 1, hi, 0.5 * (hi + after), mid))
    new = [list(x) for x in fi.intervals]
    if ends:
        k = np.array([e[0] for e in ends])
        at, far_a, far_c = (np.array([e[j] for e in ends]) for j in (3, 4, 5))
        a, c = at + np.clip(far_a - at, -reach, reach), at + np.clip(far_c - at, -reach, reach)
        (in_a, fa), (in_c, fc) = state(a, k), state(c, k)
        ok = ~in_a & in_c
        if (wide := np.flatnonzero(~ok)).size:  # the bracket within ``reach`` does not hold: the middles'
            a[wide], c[wide] = far_a[wide], far_c[wide]
            (in_a, fa[wide]), (in_c, fc[wide]) = state(a[wide], k[wide]), state(c[wide], k[wide])
            ok[wide] = ~in_a & in_c
        last = np.zeros(len(ends), int)  # +1: c moved last, -1: a moved last (Illinois halves the other's value)
        for step in range(STEPS):
            live = np.flatnonzero(ok & (np.abs(c - a) > WIDTH))
            if not live.size:
                break
            A, C, FA, FC = a[live], c[live], fa[live], fc[live]
            t = 0.5 * (A + C)
            falsi = np.isfinite(FA) & np.isfinite(FC) & (FC > FA) & (step % 2 == 0)
            with np.errstate(invalid="ignore", divide="ignore"):
                guess = (A * FC - C * FA) / (FC - FA)
            use = falsi & (np.minimum(A, C) < guess) & (guess < np.maximum(A, C))
            t[use] = guess[use]
            now, mu = state(t, k[live])
            fa[live[now & (last[live] == 1)]] *= 0.5  # c moves a second time in a row: halve a's value (Illinois)
            fc[live[~now & (last[live] == -1)]] *= 0.5  # a moves a second time in a row: halve c's value
            into, out = live[now], live[~now]
            c[into], fc[into], last[into] = t[now], mu[now], 1
            a[out], fa[out], last[out] = t[~now], mu[~now], -1
            flat = np.abs(np.nan_to_num(mu, nan=1.0)) <= FLAT
            a[live[flat]] = c[live[flat]] = t[flat]  # a step onto the end itself: the bracket closes on it
        for (b, i, side, *_), good, x, y in zip(ends, ok, a, c):
            if good:
                lo, hi = new[b][i]
                moved = 0.5 * (x + y)
                new[b][i] = (moved, hi) if side == 0 else (lo, moved)
    intervals: list[list[Interval]] = [[(float(lo), float(hi)) for lo, hi in x] for x in new]
    return FeasibleIntervals(fi.param_name, fi.branch, intervals, fi.singular, proved=False)
