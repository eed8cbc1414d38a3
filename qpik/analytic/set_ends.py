r"""A near member's feasible sets with their ends moved onto the file's own chain.

A near member's sets (:mod:`qpik.analytic.locked_joint_intervals`) are isolated on its ideal chain, whose branches
differ from the file's by the correction and polish of :mod:`qpik.analytic.locked_joint`: each end of a set is off from
the file's by about that change of the joints over the slope of the joint at its level (milliradians on the Gen3 file,
whose axes miss by 0.35 mm). :func:`refine_ends` moves each end to where the file's branch really enters or leaves the
(shrunk) limits, on the file's answers: branch b at parameter t is *inside* when it is valid and every joint lies within
the limits (:meth:`~qpik.analytic.branch_solver.BranchSolver.solve_many`, every end of every branch moved at once, one
compiled sweep per step).

The bracket of an end is first the values ``reach`` either side of it (the caller's estimate of how far it may move),
else the middle of the gap beside it (outside) and the middle of its own interval (inside), each checked; an end
whose bracket does not hold those states is left where it was. Each step keeps the bracket's states at its ends
(regula falsi where the end is a joint reaching a limit, else bisection; :func:`refine_ends`), so the end found is
where the state changes, to :data:`WIDTH`; where the file's branch enters and leaves the limits more than once in the
bracket, it finds one of the changes. Ends at ±π where a set that wraps through them is split are not ends and stay.

Where the ideal chain's branch is close to a fold (two solutions of a subproblem meet), the file's chain, a little
apart, may fold elsewhere, or have a hole where the ideal chain has none: its branch then stops being valid inside an
interval of the ideal chain's sets, away from every end. :func:`resample` takes the sets inside such stretches from
the file's answers at samples, each change between two samples moved onto the file's chain as an end is. The answer
stays unproved (``proved`` False).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.intervals import (
    FeasibleIntervals,
    Interval,
    gaps,
    merge,
    on_circle,
    shrunk_limits,
    spaced,
    within,
    wrap,
)
from qpik.core.progress import Progress

if TYPE_CHECKING:
    from collections.abc import Callable

    from qpik.analytic.branch_solver import BranchSolver

WIDTH = 1e-11
"""rad: the width of a bracket at which the end is its middle."""
STEPS = 96
"""Most steps per end: every second step halves the bracket, and halving one of 2π to below :data:`WIDTH` takes 40."""
LADDER = np.concatenate([-(4.0 ** -np.arange(1, 5)), 4.0 ** -np.arange(1, 5)])
"""Offsets (in samples' spacings) from a change found by :func:`resample` at which it samples again: ±1/4 to
±1/256."""
ROUNDS = 16
"""Rounds of :func:`resample`'s closing on the changes between neighbouring samples."""
FINE = 1.0 / 64.0
"""Neighbouring samples of :func:`resample` where another branch's validity differs are parted down to this many
spacings."""
CHUNK = 64
"""Parameters per call of the solver's ``solve_many``."""
FLAT = 1e-15
"""rad: a step whose joint-limit margin is this close to 0 is the end itself."""


def refine_ends(
    fi: FeasibleIntervals, solver: BranchSolver, T: np.ndarray, margin: float, reach: float
) -> FeasibleIntervals:
    r"""``fi``, the sets of ``solver`` at the pose ``T`` (4, 4) under the limits shrunk by ``margin``
    (:func:`~qpik.analytic.intervals.shrunk_limits`), with every end moved onto the solver's answers (module
    docstring); the same branches, ``proved`` False. An end may move past ±π, where the set is then split (as the sets
    are), and intervals that come to overlap are one. ``reach`` (rad): about how far an end may
    move; an end's bracket is first the one within ``reach`` of it, where that holds the states it must. An end moved
    to where the branch stops being valid (a fold of the file's chain, where dq/dt is unbounded) is also listed among
    the branch's singular values (``FeasibleIntervals.singular``), which :func:`qpik.solve_best`'s search samples
    closely.

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
            before = intervals[i - 1][1] if i else intervals[-1][1] - 2.0 * np.pi  # around the circle
            after = intervals[i + 1][0] if i + 1 < len(intervals) else intervals[0][0] + 2.0 * np.pi
            if lo > -np.pi:
                ends.append((k, i, 0, lo, 0.5 * (before + lo), mid))
            if hi < np.pi:
                ends.append((k, i, 1, hi, 0.5 * (hi + after), mid))
    new = [list(x) for x in fi.intervals]
    folds: list[list[float]] = [[] for _ in fi.intervals]  # the ends moved where the branch stops being valid
    if ends:
        k = np.array([e[0] for e in ends])
        at, far_a, far_c = (np.array([e[j] for e in ends]) for j in (3, 4, 5))
        a, c = at + np.clip(far_a - at, -reach, reach), at + np.clip(far_c - at, -reach, reach)
        (in_a, fa, _), (in_c, fc, _) = state(a, k), state(c, k)
        ok = ~in_a & in_c
        if (wide := np.flatnonzero(~ok)).size:  # the bracket within ``reach`` does not hold: the middles'
            a[wide], c[wide] = far_a[wide], far_c[wide]
            (in_a, fa[wide], _), (in_c, fc[wide], _) = state(a[wide], k[wide]), state(c[wide], k[wide])
            ok[wide] = ~in_a & in_c
        a, c, fa = _close(state, k, a, c, fa, fc, ok)
        for (b, i, side, *_), good, x, fold in zip(ends, ok, 0.5 * (a + c), np.isnan(fa)):
            if not good:
                continue
            lo, hi = new[b][i]
            new[b][i] = (x, hi) if side == 0 else (lo, x)
            if fold:
                folds[b].append(float(x))
    intervals = [on_circle(x) for x in new]
    return FeasibleIntervals(fi.param_name, fi.branch, intervals, _with(fi.singular, folds), proved=False)


def resample(
    fi: FeasibleIntervals,
    solver: BranchSolver,
    T: np.ndarray,
    margin: float,
    pieces: list[list[Interval]],
    spacing: float,
    progress: str | None = None,
    renumbered: bool = False,
) -> FeasibleIntervals:
    """``fi`` (as :func:`refine_ends`'s) with each branch's set inside its ``pieces`` (per branch of ``fi``'s order,
    sorted disjoint intervals of the parameter, rad) taken from the solver's answers, outside them as ``fi``;
    ``proved`` False.

    The answers are sampled at the ends of each piece and at the multiples of ``spacing`` (rad) between them (the
    pieces of several branches share their samples). Then, for at most :data:`ROUNDS` rounds, a change of a branch's
    state between two neighbouring samples more than :data:`WIDTH` apart (one per pair of samples: an event that
    changes several branches at once is closed on once) is closed on as :func:`refine_ends` closes on an end, its
    bracket's two ends and the values :data:`LADDER` (times ``spacing``) beside it becoming samples of every piece
    that holds them, every branch's state taken there: a branch whose state changes at the same value as another's,
    between two of the other's changes, or soon after one (two solutions appearing together at a fold, one of them
    leaving the limits just after, where the joints move fast), so shows its change to the next round.
    ``renumbered``: the solver's branches are renumbered where another's validity changes (the 1-D search's slots,
    :mod:`qpik.analytic.sampled_sets`), and two neighbouring samples where a branch's state is the same but another's
    validity differs, more than :data:`FINE` spacings apart, get a sample between them. A stretch where no branch's
    state (nor, with ``renumbered``, validity) differs between two neighbouring samples but one changes twice
    between them is not seen. Without ``renumbered``, a change between two samples where the branch's validity
    changes is a singular value too (as :func:`refine_ends` lists them). ``progress``: the work's words for lines on
    stderr
    (:class:`~qpik.core.progress.Progress`: the samples, then each round's steps); None: no lines."""
    t, k, piece = [], [], []
    spans = []  # per piece: its branch, its ends
    for b, stretch in enumerate(pieces):
        for lo, hi in stretch:
            x = spaced(lo, hi, spacing)
            t.append(x)
            k.append(np.full(len(x), b))
            piece.append(np.full(len(x), len(spans)))
            spans.append((b, lo, hi))
    if not t:
        return fi
    state = _state(solver, T, margin)
    t, k, piece = np.concatenate(t), np.concatenate(k), np.concatenate(piece)
    said = Progress(f"{progress}: samples", len(np.unique(t)), progress is not None)
    inside, mu, every = state(t, k, said)
    said.finish()
    for r in range(ROUNDS):
        order = np.lexsort((t, piece))
        t, k, piece, inside, mu, every = t[order], k[order], piece[order], inside[order], mu[order], every[order]
        gap = np.where(piece[1:] == piece[:-1], t[1:] - t[:-1], 0.0)
        i = np.flatnonzero((inside[1:] != inside[:-1]) & (gap > WIDTH))
        if i.size:  # one per pair of samples: one event often changes several branches, closed on together
            i = i[np.unique(np.stack([t[i], t[i + 1]]), axis=1, return_index=True)[1]]
        new = []
        if renumbered:  # another branch's validity changes in there: a look at its middle
            j = (every[1:] != every[:-1]).any(axis=1) & (inside[1:] == inside[:-1]) & (gap > FINE * spacing)
            new.append(0.5 * (t[:-1] + t[1:])[j])
        if i.size:
            out, into = np.where(inside[i], i + 1, i), np.where(inside[i], i, i + 1)  # the sample outside, inside
            words = f"{progress}: round {r + 1}, {len(i)} ends, step (at most {STEPS})"
            said = Progress(words, STEPS, progress is not None)
            a, c, _ = _close(state, k[i], t[out], t[into], mu[out], mu[into], np.ones(len(i), bool), said)
            new += [a, c, (0.5 * (a + c)[:, None] + spacing * LADDER).ravel()]  # narrow stretches cluster beside one
        if not new:
            break
        new = np.unique(np.concatenate(new))
        at = [(p, x) for p, (b, lo, hi) in enumerate(spans) for x in new[(new >= lo) & (new <= hi)]]
        if not at:
            break
        p_new, t_new = (np.array(x) for x in zip(*at))
        k_new = np.array([spans[p][0] for p in p_new])
        in_new, mu_new, every_new = state(t_new, k_new)
        t, k, piece = np.concatenate([t, t_new]), np.concatenate([k, k_new]), np.concatenate([piece, p_new])
        inside, mu, every = (
            np.concatenate([inside, in_new]),
            np.concatenate([mu, mu_new]),
            np.concatenate([every, every_new]),
        )
    order = np.lexsort((t, piece))
    t, k, piece, inside, every = t[order], k[order], piece[order], inside[order], every[order]
    intervals = [list(x) for x in fi.intervals]
    folds: list[list[float]] = [[] for _ in fi.intervals]
    for b, stretch in enumerate(pieces):
        if not stretch:
            continue
        runs = []  # the runs of the samples inside, each end the middle of its last bracket
        for p in {int(x) for x in piece[k == b]}:
            x, ok, valid = t[piece == p], inside[piece == p], every[piece == p, b]
            edges = np.flatnonzero(ok[1:] != ok[:-1])
            cut = 0.5 * (x[edges] + x[edges + 1])
            if not renumbered:  # a change of the branch's validity: where it stops being valid, a singular end
                folds[b] += cut[valid[edges] != valid[edges + 1]].tolist()
            starts = np.concatenate([[x[0]] if ok[0] else [], cut[ok[edges + 1]]])
            stops = np.concatenate([cut[ok[edges]], [x[-1]] if ok[-1] else []])
            runs += list(zip(starts.tolist(), stops.tolist()))
        bounds = [x for iv in intervals[b] + runs + stretch for x in iv]
        lo, hi = gaps(np.array(bounds))
        mid = wrap(0.5 * (lo + hi))
        ok = np.where(within(stretch, mid), within(runs, mid), within(intervals[b], mid))
        intervals[b] = merge(lo, hi, ok[:, None])[0]
    out_sets = [[(float(lo), float(hi)) for lo, hi in x] for x in intervals]
    return FeasibleIntervals(fi.param_name, fi.branch, out_sets, _with(fi.singular, folds), proved=False)


def _with(singular: list[list[float]], folds: list[list[float]]) -> list[list[float]]:
    """The singular values (rad, per branch, sorted) of ``singular`` and ``folds``."""
    return [sorted(set(old) | set(new)) for old, new in zip(singular, folds)]


def _state(solver: BranchSolver, T: np.ndarray, margin: float) -> Callable[..., tuple]:
    """The state of ``solver``'s branches at the pose ``T`` under the limits shrunk by ``margin``: a function of
    parameters t (M,) rad and branches k (M,) (indices of the sets' order) giving inside (valid and within the
    shrunk limits) and the margin μ (rad; NaN where the branch is not valid), (M,) each, and every branch's valid
    flag at each t (M, B); the solver answers each parameter once, in one call, or :data:`CHUNK` at a time, each
    chunk told to a :class:`~qpik.core.progress.Progress` if one is given."""
    lo_q, hi_q = shrunk_limits(solver.robot.q_min, solver.robot.q_max, margin)

    def state(t: np.ndarray, k: np.ndarray, said: Progress | None = None) -> tuple[np.ndarray, ...]:
        u, rows = np.unique(t, return_inverse=True)  # branches sampled at one parameter: one answer
        q, valid = [], []
        for part in np.array_split(u, 1 if said is None else -(-len(u) // CHUNK)):
            s = solver.solve_many(T, part)
            q.append(s.q)
            valid.append(s.valid)
            if said is not None:
                said(sum(len(x) for x in q))
        every = np.concatenate(valid)[rows]
        q, valid = np.concatenate(q)[rows, k], every[np.arange(len(t)), k]
        mu = np.where(valid, np.minimum(q - lo_q, hi_q - q).min(axis=-1), np.nan)
        return valid & (mu >= 0), mu, every

    return state


def _close(
    state: Callable[[np.ndarray, np.ndarray], tuple],
    k: np.ndarray,
    a: np.ndarray,
    c: np.ndarray,
    fa: np.ndarray,
    fc: np.ndarray,
    ok: np.ndarray,
    said: Progress | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The brackets [a, c] (a outside, c inside, rad, (M,) each; μ there ``fa``, ``fc``) of branches ``k`` closed on
    their ends until each is at most :data:`WIDTH` wide (:func:`refine_ends`' steps): their ends a, c and μ at a
    (NaN where the branch is not valid there: the end is where it stops being valid); only where ``ok``, the others
    as given; each step told to ``said``, the last as its :meth:`~qpik.core.progress.Progress.finish`."""
    a, c, fa, fc = (np.array(x, float) for x in (a, c, fa, fc))
    last = np.zeros(len(a), int)  # +1: c moved last, -1: a moved last (Illinois halves the other's value)
    for step in range(STEPS):
        live = np.flatnonzero(ok & (np.abs(c - a) > WIDTH))
        if not live.size:
            break
        if said is not None:
            said(step)
        A, C, FA, FC = a[live], c[live], fa[live], fc[live]
        t = 0.5 * (A + C)
        falsi = np.isfinite(FA) & np.isfinite(FC) & (FC > FA) & (step % 2 == 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            guess = (A * FC - C * FA) / (FC - FA)
        use = falsi & (np.minimum(A, C) < guess) & (guess < np.maximum(A, C))
        t[use] = guess[use]
        now, mu, _ = state(t, k[live])
        fa[live[now & (last[live] == 1)]] *= 0.5  # c moves a second time in a row: halve a's value (Illinois)
        fc[live[~now & (last[live] == -1)]] *= 0.5  # a moves a second time in a row: halve c's value
        into, out = live[now], live[~now]
        c[into], fc[into], last[into] = t[now], mu[now], 1
        a[out], fa[out], last[out] = t[~now], mu[~now], -1
        flat = np.abs(np.nan_to_num(mu, nan=1.0)) <= FLAT
        a[live[flat]] = c[live[flat]] = t[flat]  # a step onto the end itself: the bracket closes on it
    if said is not None:
        said.finish(step)
    return a, c, fa
