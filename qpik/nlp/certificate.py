r"""A certificate that the answer of :func:`qpik.solve_best` is the global minimum (to a tolerance).

The claim, for a pose with answer value :math:`f^*`: every ψ of every searched branch that keeps
the joints inside their limits, every link capsule at least :math:`d_s` from every obstacle and the capsules of
every pair of :attr:`~qpik.scene.Scene.self_pairs` at least :math:`d_s` apart has
:math:`f(\psi) \ge f^* - \varepsilon`, with :math:`\varepsilon = tol \cdot \max(1, |f^*|)`. Proof by
branch and bound over the exact feasible intervals (:func:`qpik.feasible_intervals`, whose ends are
the analytic limit crossings):

1. Move every interval's ends onto its feasible side (:func:`inside_ends`: an end exact to 1e-9 rad may lie past
   where a joint leaves its limits, where the joint is already its other representative q ± 2π), then cover every
   interval with cells of width :data:`FIRST_CELL` or less.
2. For each cell [a, b], the Taylor model of the branch's closed form over it
   (:meth:`~qpik.nlp.selfmotion.SelfMotion.models`: with :math:`t = (\psi - \psi_{mid})/h`, every
   joint lies within :math:`c + s\,t \pm r` and within [lo, hi] for every ψ of the cell), composed
   with the Taylor models of the objective's split and of the clearances (capsule–obstacle and capsule pairs)
   (:class:`qpik.scene.bounds.BoundFunction`), gives :func:`lower_bound`: a convex piecewise-linear
   function of t below f on the whole cell, whose minimum over [−1, 1] is the cell's bound. Its
   error is second order in the cell's width (the slopes carry the correlation that a plain
   interval extension loses), so kinks (where the epigraph terms switch) and smooth minima are
   proved with cells of a few milliradians.
3. A cell whose bound is :math:`\ge f^* - \varepsilon`, or where some clearance is surely below
   :math:`d_s` (its upper bound is), holds nothing better: it is dropped. The others are cut in
   :data:`SPLIT` and examined again, down to :data:`SMALLEST_CELL`.

If every cell is dropped, the answer is certified: its :attr:`~qpik.nlp.best_result.BestResult.gap`
(:math:`f^*` minus the smallest bound met) is at most ε. A cell that cannot be dropped at the
smallest width, or more than :data:`MAX_CELLS` cells, leaves it uncertified (the flag says so;
the answer is still the best found). The test point (the middle) of a cell that is kept, if it is
feasible and better than :math:`f^* - \varepsilon`, is returned as a new start for the search,
which then certifies again.

What the proof assumes: the feasible intervals are exact (up to :data:`qpik.analytic.intervals.SAME`,
1e-9 rad, below which a gap is not classified); the closed form is continuous on each interval
(it is, between the analytic breakpoints, where every joint crossing a limit or wrapping through
±π is a breakpoint; a joint whose limits hold every angle of (−π, π] has no breakpoint where it wraps: in a cell
where one such joint passes ±π, its value is its angle θ in (0, 2π] or θ − 2π at every ψ, both continuous, and the
cell's bound is the smaller of the two bounds, :func:`cell_bounds`); the
Taylor models are evaluated in round-to-nearest arithmetic (their bounds
may be off by a few units in the last place, far below ε); the objective is
:attr:`~qpik.objectives.Objective.bounded` and every operation of it has a Taylor-model rule
(:func:`qpik.algebra.enclosure.taylor_function`; otherwise it is never certified, and the reason says so:
the manipulability, a user expression without rules).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qpik.analytic.intervals import SAME
from qpik.nlp.run import BestRun, Points
from qpik.nlp.search import Pieces
from qpik.scene.bounds import BoundFunction

FIRST_CELL = 0.4
"""Width (rad) of the first cells."""
SPLIT = 4
"""A cell that is kept is cut in this many."""
FOCUS_LEVELS = 2
"""The first cell holding the answer is cut into ``SPLIT ** FOCUS_LEVELS`` at once (:func:`certify`)."""
SMALLEST_CELL = 1e-9
"""Cells are not cut below this width (rad): one kept there leaves the answer uncertified."""
MAX_CELLS = 3_000
"""Most cells examined per pose."""
INWARD_RUNGS = 24
"""Values :func:`inside_ends` tries inside an end: SAME · 2^-k for k < 24, down to 1.2e-16 rad (one call)."""
INSET = 1e-12
"""rad: how far inside its set :func:`inside_ends` puts every end, beyond the last feasible value."""
BISECTIONS = 20
"""Bisection steps of :func:`lower_bound` on t ∈ [−1, 1]."""
NO_BOUND = "the objective has no lower bound (the manipulability, or an operation without a Taylor-model rule)"


@dataclass
class Certificate:
    """Per pose: ``certified`` (bool), ``bound`` (the smallest lower bound met; -inf if none), ``cells``
    examined, ``reason`` (why not certified, "" if certified) and the feasible test points better than
    the answer (``better``, rows of :class:`Points` with values only: :meth:`BestRun.values`)."""

    certified: np.ndarray
    bound: np.ndarray
    cells: np.ndarray
    reason: list[str]
    better: Points | None


def lower_bound(models: list[np.ndarray], sizes: tuple[int, ...], decide: np.ndarray | None = None) -> np.ndarray:
    r"""(M,): a lower bound of :math:`\min_{t \in [-1, 1]} \ell_s(t) + \sum_k w_k \max_i \ell_{k,i}(t)` per row.

    ``models``: ``[centre, slope, radius, lo, hi]`` of the values
    ``[s, w_1..w_K, h_1 (m_1), ..., h_K (m_K), ...]`` (each (M, L); :class:`~qpik.scene.bounds.BoundFunction`),
    ``sizes``: (m_1..m_K). Each :math:`\ell(t) = \max(lo, c + s\,t - r)` lies below its value, so the
    function is below f; it is convex and piecewise linear. Its minimum is bracketed by bisection on
    the sign of a subgradient, and bounded from below by the crossing of the supporting lines at the
    two ends of the bracket (sound whatever the number of steps; exact to the bracket's width after
    :data:`BISECTIONS` steps). ``decide`` (M,): a row stops as soon as its bound is ≥ ``decide`` or a
    value of the function is below it (then the bound returned is below ``decide``, and the cell is
    kept whatever its exact value). A row with a non-finite value, or a negative weight, gets −inf.
    """
    c, s, r, lo, _ = models
    K = len(sizes)
    w = c[:, 1 : 1 + K]
    ends = np.cumsum((1 + K, *sizes))
    groups = [(np.ones((len(c), 1)), slice(0, 1))]
    groups += [(w[:, k : k + 1], slice(ends[k], ends[k + 1])) for k in range(K)]
    parts = [(weight, c[:, g] - r[:, g], s[:, g], lo[:, g]) for weight, g in groups]

    def value_and_slope(t: np.ndarray, parts: list[tuple[np.ndarray, ...]]) -> tuple[np.ndarray, np.ndarray]:
        """The function and a subgradient at t (one per row of ``parts``)."""
        total, slope = np.zeros(len(t)), np.zeros(len(t))
        rows = np.arange(len(t))
        for weight, base, sl, floor in parts:
            line = base + sl * t[:, None]
            flat = floor > line
            low = np.where(flat, floor, line)
            i = low.argmax(axis=1)
            total += weight[:, 0] * low[rows, i]
            slope += weight[:, 0] * np.where(flat[rows, i], 0.0, sl[rows, i])
        return total, slope

    def crossing(a, va, sa, b, vb, sb) -> np.ndarray:
        """The bound from a bracket [a, b] with sa < 0 < sb: where the supporting lines at a and b cross."""
        cross = (vb - va + sa * a - sb * b) / (sa - sb)
        return va + sa * (np.clip(cross, a, b) - a)

    ones = np.ones(len(c))
    (va, sa), (vb, sb) = value_and_slope(-ones, parts), value_and_slope(ones, parts)
    out = np.where(sa >= 0, va, vb)  # monotone on the cell: the minimum is at an end
    at = np.flatnonzero((sa < 0) & (sb > 0))
    a, b = -ones[at], ones[at]
    va, sa, vb, sb = va[at], sa[at], vb[at], sb[at]
    limit = None if decide is None else decide[at]
    inside = [tuple(x[at] for x in part) for part in parts]
    for step in range(BISECTIONS + 1):
        inner = (sa < 0) & (sb > 0)
        safe_a, safe_b = np.where(inner, sa, -1.0), np.where(inner, sb, 1.0)
        low = np.where(inner, crossing(a, va, safe_a, b, vb, safe_b), np.where(sa >= 0, va, vb))
        out[at] = low
        go = inner if limit is None else inner & (low < limit) & (np.minimum(va, vb) >= limit)
        if not go.any() or step == BISECTIONS:
            break
        if not go.all():
            k = np.flatnonzero(go)
            at, a, b, va, sa, vb, sb = at[k], a[k], b[k], va[k], sa[k], vb[k], sb[k]
            limit = None if limit is None else limit[k]
            inside = [tuple(x[k] for x in part) for part in inside]
        m = 0.5 * (a + b)
        vm, sm = value_and_slope(m, inside)
        right = sm < 0  # the minimum lies right of m
        a, va, sa = np.where(right, m, a), np.where(right, vm, va), np.where(right, sm, sa)
        b, vb, sb = np.where(right, b, m), np.where(right, vb, vm), np.where(right, sb, sm)
    bad = ~np.isfinite(np.concatenate(models[:4], axis=1)).all(axis=1) | (w < 0).any(axis=1)
    return np.where(bad | np.isnan(out), -np.inf, out)


def certify(
    scene: BestRun,
    pieces: Pieces,
    best: np.ndarray,
    tol: np.ndarray,
    poses: np.ndarray,
    focus: tuple[np.ndarray, np.ndarray] | None = None,
) -> Certificate:
    """Try to certify ``best`` (N,) to the tolerances ``tol`` (N,) for the poses ``poses`` (indices) over ``pieces``.

    ``focus``: (branch row (N,), ψ (N,)) of each pose's answer; the first cell holding it is cut
    :data:`FOCUS_LEVELS` times at once (a cell holding the answer is kept until its bound reaches
    the answer − tol, so it would be cut as many times anyway, one round each)."""
    N = len(scene.poses)
    certified = np.zeros(N, bool)
    bound = np.full(N, np.inf)
    cells_used = np.zeros(N, int)
    reason = [""] * N
    todo = np.zeros(N, bool)
    todo[poses] = True
    bounds = scene.build_certificate()
    if bounds is None:
        for i in poses:
            reason[i] = NO_BOUND
        return Certificate(certified, np.full(N, -np.inf), cells_used, reason, None)
    sel = todo[pieces.pose]
    first, last = inside_ends(scene, pieces.pose[sel], pieces.row[sel], pieces.lo[sel], pieces.hi[sel])
    width = last - first
    count = np.maximum(1, np.ceil(width / FIRST_CELL).astype(int))
    pose = np.repeat(pieces.pose[sel], count)
    row = np.repeat(pieces.row[sel], count)
    j = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    lo = np.repeat(first, count) + j * np.repeat(width / count, count)
    hi = np.minimum(lo + np.repeat(width / count, count), np.repeat(last, count))
    if focus is not None:
        at = (row == focus[0][pose]) & (lo <= focus[1][pose]) & (focus[1][pose] <= hi)
        parts = np.where(at, SPLIT**FOCUS_LEVELS, 1)
        k = np.arange(parts.sum()) - np.repeat(np.cumsum(parts) - parts, parts)
        step = np.repeat((hi - lo) / parts, parts)
        pose, row, end = np.repeat(pose, parts), np.repeat(row, parts), np.repeat(hi, parts)
        lo = np.repeat(lo, parts) + k * step
        hi = np.where(k == np.repeat(parts, parts) - 1, end, lo + step)  # the last part ends at the cell's end
    failed = np.zeros(N, bool)
    better: list[Points] = []
    while len(lo):
        np.add.at(cells_used, pose, 1)
        lb, blocked = cell_bounds(scene, bounds, pose, row, lo, hi, best[pose] - tol[pose])
        open_ = np.flatnonzero(~blocked & ~(lb >= best[pose] - tol[pose]))  # only these can hold a better point
        pts = scene.values(pose[open_], row[open_], 0.5 * (lo[open_] + hi[open_]))
        good = pts.valid & (pts.c >= 0) & (pts.f < best[pts.pose] - tol[pts.pose])
        if good.any():
            better.append(pts.take(good))
            failed[pts.pose[good]] = True
        keep = ~blocked & ~(lb >= best[pose] - tol[pose]) & ~failed[pose]
        dropped = ~blocked & ~keep
        np.minimum.at(bound, pose[dropped], lb[dropped])
        small = keep & (hi - lo <= SMALLEST_CELL)
        for i in np.unique(pose[small]):
            failed[i] = True
            reason[i] = f"a cell of width {SMALLEST_CELL:g} rad keeps a bound below the answer − tol"
        over = cells_used > MAX_CELLS
        for i in np.flatnonzero(over & ~failed & todo):
            failed[i] = True
            reason[i] = f"the bounds did not reach the tolerance within {MAX_CELLS} cells"
        keep &= ~failed[pose]
        if not keep.any():
            break
        k = np.flatnonzero(keep)
        step = (hi[k] - lo[k]) / SPLIT
        pose, row = np.repeat(pose[k], SPLIT), np.repeat(row[k], SPLIT)
        part = np.tile(np.arange(SPLIT), len(k))
        lo, hi = np.repeat(lo[k], SPLIT) + part * np.repeat(step, SPLIT), np.repeat(hi[k], SPLIT)
        hi = np.where(part == SPLIT - 1, hi, lo + np.repeat(step, SPLIT))  # the last part ends at the cell's end
    for i in np.flatnonzero(todo):
        if not failed[i]:
            certified[i] = True
        elif not reason[i]:
            reason[i] = "a feasible point better than the answer was found"
    bound[~certified] = -np.inf
    return Certificate(certified, bound, cells_used, reason, Points.join(better) if better else None)


def inside_ends(
    scene: BestRun, pose: np.ndarray, row: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The ends ``lo``, ``hi`` (M,) of pieces (pose, branch row (M,)) moved onto their feasible side.

    An end is exact to :data:`~qpik.analytic.intervals.SAME` (1e-9 rad) on either side of where the branch leaves
    the limits. On the far side a joint is already past its limit, where the closed form gives another representative
    (q ± 2π) of the joint, and a cell reaching there holds that jump: its bounds stay loose at any width. An end whose
    configuration is not valid inside the limits is moved to the nearest of the values end ∓ SAME · 2^-k
    (:data:`INWARD_RUNGS`) that is, all of them in one call (an end where none is stays). Every end then moves
    :data:`INSET` further inside: a joint at its limit to rounding still lets a cell's model (whose radius is a few
    rounding errors) reach past it. Ends at ±π, where a set wrapping through them is split, are not ends and stay.
    The certificate covers the pieces up to these ends; what it leaves out lies within the sets' own accuracy
    (SAME), which the proof assumes (module docstring)."""
    robot, n = scene.robot, len(lo)
    P, R = np.tile(pose, 2), np.tile(row, 2)
    t = np.concatenate([lo, hi])
    inward = np.concatenate([np.ones(n), -np.ones(n)]) * np.tile(np.minimum(SAME, 0.5 * (hi - lo)), 2)

    def feasible(k: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The branch valid with every joint inside the limits (the closed form alone: no objective, no clearance)."""
        if not len(x):
            return np.zeros(0, bool)
        q, valid = scene.selfmotion.values(R[k], scene.columns[P[k]], x)
        return valid & ((q >= robot.q_min) & (q <= robot.q_max)).all(axis=1)

    seam = np.abs(t) == np.pi  # a set wrapping through ±π is split there: not an end
    out = np.flatnonzero(~seam & ~feasible(np.arange(2 * n), t))
    rungs = 0.5 ** np.arange(INWARD_RUNGS)  # the fractions of [end ∓ SAME, end] tried, from the far end in
    k = np.repeat(out, INWARD_RUNGS)
    ok = feasible(k, t[k] + np.tile(rungs, len(out)) * inward[k]).reshape(len(out), INWARD_RUNGS)
    last = INWARD_RUNGS - 1 - np.argmax(ok[:, ::-1], axis=1)  # the rung nearest the end that is feasible
    move = ok.any(axis=1)
    t[out[move]] += rungs[last[move]] * inward[out[move]]
    t += np.where(seam, 0.0, np.sign(inward) * np.minimum(INSET, 0.25 * np.abs(inward)))
    return t[:n], t[n:]


def cell_bounds(
    scene: BestRun,
    bounds: BoundFunction,
    pose: np.ndarray,
    row: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    decide: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """For cells (pose, branch row, [lo, hi]) (M,): the lower bound of f (:func:`lower_bound`, refined until it
    decides whether it is below ``decide`` (M,)) and whether the clearance constraint surely fails on the whole
    cell (some clearance's upper bound below d_s: a capsule–obstacle pair or a pair of the arm's own capsules).
    A cell where one joint of :attr:`~qpik.nlp.selfmotion.SelfMotion.turned` passes ±π (its bounds more than π
    apart) is also bounded with that joint's angle θ in (0, 2π] and with θ − 2π: the smaller bound holds too."""
    q = scene.selfmotion.models(row, scene.columns[pose], lo, hi)
    lb, blocked = _bounds(scene, bounds, q, pose, decide)
    turned = scene.selfmotion.turned
    jumps = (q[4][:, turned] - q[3][:, turned] > np.pi) if turned.size else np.zeros((len(lo), 0), bool)
    cells = np.flatnonzero(jumps.sum(axis=1) == 1)
    if cells.size:
        # one joint of the cell passes ±π, where its wrapped angle jumps by 2π: at every ψ it is θ or θ − 2π, θ its
        # angle in (0, 2π] (continuous there), so f is at least the smaller of the two bounds
        j = turned[jumps[cells].argmax(axis=1)]
        theta = scene.selfmotion.models(row[cells], scene.columns[pose[cells]], lo[cells], hi[cells], turned=True)
        sides = []
        for shift in (0.0, -2.0 * np.pi):
            side = [x[cells].copy() for x in q]
            for k, (a, b) in enumerate(zip(side, theta)):
                a[np.arange(cells.size), j] = b[np.arange(cells.size), j] + (shift if k in (0, 3, 4) else 0.0)
            sides.append(_bounds(scene, bounds, side, pose[cells], decide[cells]))
        (lb1, blocked1), (lb2, blocked2) = sides
        lb[cells] = np.maximum(lb[cells], np.minimum(lb1, lb2))
        blocked[cells] |= blocked1 & blocked2
    return lb, blocked


def _bounds(
    scene: BestRun, bounds: BoundFunction, q: list[np.ndarray], pose: np.ndarray, decide: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cell_bounds` from the joints' Taylor models ``q`` (centre, slope, radius, lo, hi; (M, n) each)."""
    models = scene.bound_rows(bounds, *q, pose)
    lb = lower_bound(models, bounds.sizes, decide)
    if not bounds.n_clear:
        return lb, np.zeros(len(lb), bool)
    d_hi = models[4][:, -bounds.n_clear :]
    return lb, (d_hi < scene.d_safe).any(axis=1)
