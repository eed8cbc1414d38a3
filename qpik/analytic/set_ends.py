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

from qpik.analytic.intervals import FeasibleIntervals, Interval, gaps, merge, shrunk_limits, wrap

if TYPE_CHECKING:
    from collections.abc import Callable

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
    state = _state(solver, T, margin)
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
        moved = _close(state, k, a, c, fa, fc, ok)
        for (b, i, side, *_), good, x in zip(ends, ok, moved):
            if good:
                lo, hi = new[b][i]
                new[b][i] = (x, hi) if side == 0 else (lo, x)
    intervals: list[list[Interval]] = [[(float(lo), float(hi)) for lo, hi in x] for x in new]
    return FeasibleIntervals(fi.param_name, fi.branch, intervals, fi.singular, proved=False)


def resample(
    fi: FeasibleIntervals,
    solver: BranchSolver,
    T: np.ndarray,
    margin: float,
    pieces: list[list[Interval]],
    spacing: float,
) -> FeasibleIntervals:
    """``fi`` (as :func:`refine_ends`'s) with each branch's set inside its ``pieces`` (per branch of ``fi``'s order,
    sorted disjoint intervals of the parameter, rad) taken from the solver's answers: sampled at its ends and at the
    multiples of ``spacing`` (rad) between them (the pieces of several branches share their samples), every change
    of state between two neighbouring samples moved onto the answers as :func:`refine_ends` moves an end (the two
    samples its bracket); outside the pieces as ``fi``. A stretch where the state changes twice between two samples
    is not seen. ``proved`` False."""
    t, k, piece = [], [], []
    for b, stretch in enumerate(pieces):
        for lo, hi in stretch:
            grid = np.arange(np.floor(lo / spacing) + 1, np.ceil(hi / spacing)) * spacing  # shared by the pieces
            x = np.concatenate([[lo], grid[(grid > lo) & (grid < hi)], [hi]])
            t.append(x)
            k.append(np.full(len(x), b))
            piece.append(np.full(len(x), len(piece)))
    if not t:
        return fi
    state = _state(solver, T, margin)
    t, k, piece = np.concatenate(t), np.concatenate(k), np.concatenate(piece)
    inside, mu = state(t, k)
    i = np.flatnonzero((piece[1:] == piece[:-1]) & (inside[1:] != inside[:-1]))  # a change after sample i
    out = np.where(inside[i], i + 1, i)  # the sample outside, then the one inside
    into = np.where(inside[i], i, i + 1)
    change = np.full(len(t), np.nan)  # after sample i: where the state changes
    change[i] = _close(state, k[i], t[out], t[into], mu[out], mu[into], np.ones(len(i), bool))
    intervals = [list(x) for x in fi.intervals]
    for b, stretch in enumerate(pieces):
        if not stretch:
            continue
        mine = np.flatnonzero(k == b)
        runs, start = [], None  # the runs of the samples inside, their ends moved
        for j in mine:
            if start is None and inside[j]:
                start = t[j] if j == mine[0] or piece[j - 1] != piece[j] else change[j - 1]
            if start is not None and (j == mine[-1] or piece[j + 1] != piece[j] or not inside[j + 1]):
                runs.append((start, t[j] if j == mine[-1] or piece[j + 1] != piece[j] else change[j]))
                start = None
        every = [x for iv in intervals[b] + runs + stretch for x in iv]
        lo, hi = gaps(np.array(every))
        mid = wrap(0.5 * (lo + hi))
        ok = np.where(_within(stretch, mid), _within(runs, mid), _within(intervals[b], mid))
        intervals[b] = merge(lo, hi, ok[:, None])[0]
    out_sets = [[(float(lo), float(hi)) for lo, hi in x] for x in intervals]
    return FeasibleIntervals(fi.param_name, fi.branch, out_sets, fi.singular, proved=False)


def _within(intervals: list[Interval], x: np.ndarray) -> np.ndarray:
    """Whether each of ``x`` (M,) rad lies in one of the closed ``intervals``."""
    out = np.zeros(len(x), bool)
    for lo, hi in intervals:
        out |= (lo <= x) & (x <= hi)
    return out


def _state(solver: BranchSolver, T: np.ndarray, margin: float) -> Callable[[np.ndarray, np.ndarray], tuple]:
    """The state of ``solver``'s branches at the pose ``T`` under the limits shrunk by ``margin``: a function of
    parameters t (M,) rad and branches k (M,) (indices of the sets' order) giving inside (valid and within the
    shrunk limits) and the margin μ (rad; NaN where the branch is not valid), (M,) each."""
    lo_q, hi_q = shrunk_limits(solver.robot.q_min, solver.robot.q_max, margin)

    def state(t: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u, rows = np.unique(t, return_inverse=True)  # branches sampled at one parameter: one answer
        s = solver.solve_many(T, u)
        q, valid = s.q[rows, k], s.valid[rows, k]
        mu = np.where(valid, np.minimum(q - lo_q, hi_q - q).min(axis=-1), np.nan)
        return valid & (mu >= 0), mu

    return state


def _close(
    state: Callable[[np.ndarray, np.ndarray], tuple],
    k: np.ndarray,
    a: np.ndarray,
    c: np.ndarray,
    fa: np.ndarray,
    fc: np.ndarray,
    ok: np.ndarray,
) -> np.ndarray:
    """The middles (rad, (M,)) of the brackets [a, c] (a outside, c inside, (M,) each; μ there ``fa``, ``fc``) of
    branches ``k`` once each is at most :data:`WIDTH` wide (:func:`refine_ends`' steps); only where ``ok``, the others
    as given."""
    a, c, fa, fc = (np.array(x, float) for x in (a, c, fa, fc))
    last = np.zeros(len(a), int)  # +1: c moved last, -1: a moved last (Illinois halves the other's value)
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
    return 0.5 * (a + c)
