r"""The 1-D search of :func:`qpik.solve_best`: sample, split at the clearance constraint, polish.

For each pose, every branch's exact feasible set (:func:`qpik.feasible_intervals`) is a union
of closed intervals of δ/ψ. On each:

1. **Sample** ``f`` and ``c`` (:meth:`~qpik.nlp.run.BestRun.values`: no derivatives) every
   :data:`SAMPLE_STEP` rad or closer, both ends included, and more closely next to a singular end.
   All rows of a step, of every pose and branch, go through one compiled call.
2. **Split** at the clearance constraint ``c ≥ 0``: a sign change of ``c`` between two samples
   is refined to its root (:func:`roots`: secant, Newton and bisection steps in a bracket),
   giving the feasible *pieces*. The brackets here and in the polish are evaluated with
   ``f'`` and ``c'`` (:meth:`~qpik.nlp.run.BestRun.evaluate`).
3. **Polish** the discrete local minima of the samples of each piece (:func:`polish_minima`): a
   bracket ``a ≤ m ≤ b`` with ``f(m) ≤ f(a), f(b)`` shrinks around a local minimum. Each round
   tries, on the side where ``f'(m)`` descends, the root of the secant of ``f'`` (exact for a
   quadratic), the crossing of the tangents at the two ends (exact at a kink of the epigraph
   terms, where the slope jumps), its mirror image through m (so that the far end of the bracket
   closes in too, and the tangents meet ever closer to the kink) and the midpoint (a guaranteed
   halving), all evaluated in one compiled call; the best point becomes ``m``. A minimum at a piece's
   end (``f'`` pointing out) is returned as it is.

The local minima found are the candidates; the best is the answer. Whether it is the global
minimum is what :mod:`qpik.nlp.certificate` proves (or fails to).

Why this and not IPOPT (:mod:`qpik.nlp.ipopt`, ``method="ipopt"``): both reach the same local
minima (the tests compare them), but one IPOPT solve per feasible interval costs ~1–5 ms of
setup and iterations (``qpik bench nlp`` measures it), while the bracket steps for all
candidates of all branches share each compiled call; and IPOPT started inside an interval finds
the minimum of its basin, not of the interval, so it still needs the sampling to be global.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from qpik.nlp.run import BestRun, Points

SAMPLE_STEP = 0.1
"""Largest spacing (rad) of the samples of a feasible interval."""
END = 2e-9
"""The first and last samples lie this far (rad) inside a feasible interval: its ends are exact to
:data:`qpik.analytic.intervals.SAME` (1e-9), and the branch may stop reaching the pose just beyond."""
ENDS = (1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 4e-3, 1.6e-2)
"""Extra samples (rad) inside each singular end of a feasible interval (see :func:`sample`): near a fold the joints
move as the square root of the distance to it, and the objective's best can lie microradians from the end (a
bracket reaches no further than the last sample where the branch is valid)."""
SINGULAR_END = 1e-7
"""An end of a feasible interval this close (rad) to a singular parameter of its branch is singular."""
PSI_TOL = 1e-13
r"""A bracket narrower than this (rad, relative to :math:`1 + |\psi|`) has converged."""
NOISE = 1e-15
"""Relative rounding of an objective value: values closer than this count as equal in :func:`polish_minima`."""
MAX_ROUNDS = 60
"""Most rounds of :func:`polish_minima` or :func:`roots`."""
POLISHED_PER_BRANCH = 2
"""Candidates polished per (pose, branch): its best discrete local minima."""
POLISHED_PER_POSE = 4
"""Further candidates polished per pose: the best ones left."""


@dataclass
class Pieces:
    """Feasible pieces: row i is the interval [lo[i], hi[i]] of branch row ``row[i]`` of pose ``pose[i]``;
    ``singular`` (P, 2) bool: whether its lower and upper ends are singular parameters of the branch (where
    dq/dψ is unbounded, :attr:`qpik.analytic.intervals.FeasibleIntervals.singular`); None: every end may be."""

    pose: np.ndarray
    row: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    singular: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.lo)

    def take(self, idx: np.ndarray) -> Pieces:
        """The pieces ``idx`` (an index array or a boolean mask)."""
        sing = None if self.singular is None else self.singular[idx]
        return Pieces(self.pose[idx], self.row[idx], self.lo[idx], self.hi[idx], sing)


def singular_ends(pieces: Pieces, pose: np.ndarray, row: np.ndarray, value: np.ndarray) -> np.ndarray:
    """(P, 2) bool: whether each end (lo, hi) of the pieces lies within :data:`SINGULAR_END` of a singular
    parameter ``value`` (K,) rad of the same pose (K,) and branch row (K,)."""
    out = np.zeros((len(pieces), 2), bool)
    if not len(value):
        return out
    rows = int(max(pieces.row.max(initial=0), row.max())) + 1
    # one sorted line: each (pose, row) owns [8k, 8k + 2π] (2π < 8), its parameters ψ + π inside
    line = np.sort((pose * rows + row) * 8.0 + (value + np.pi))
    base = (pieces.pose * rows + pieces.row) * 8.0 + np.pi
    for side, end in enumerate((pieces.lo, pieces.hi)):
        x = base + end
        j = np.searchsorted(line, x)
        below, above = line[np.maximum(j - 1, 0)], line[np.minimum(j, len(line) - 1)]
        out[:, side] = np.minimum(np.abs(x - below), np.abs(x - above)) < SINGULAR_END
    return out


def sample(scene: BestRun, pieces: Pieces, step: float = SAMPLE_STEP) -> tuple[Points, np.ndarray]:
    """Samples of every piece, at most ``step`` apart, from :data:`END` inside each end, and at :data:`ENDS` from
    each singular end: (points, piece (M,)).

    Points of one piece are consecutive and in increasing ψ. Only points where the branch reaches
    the pose with a finite objective are kept. They carry values only (:meth:`~qpik.nlp.run.BestRun.values`:
    the derivatives are NaN); :func:`split` and :func:`candidates` evaluate the derivatives where they are used.
    """
    shrink = np.minimum(END, 0.5 * (pieces.hi - pieces.lo))
    sharp = np.ones((len(pieces), 2), bool) if pieces.singular is None else pieces.singular
    pieces = Pieces(pieces.pose, pieces.row, pieces.lo + shrink, pieces.hi - shrink)
    width = pieces.hi - pieces.lo
    k = np.where(width > 0.0, np.maximum(2, np.ceil(width / step).astype(int) + 1), 1)
    piece = np.repeat(np.arange(len(pieces)), k)
    start = np.repeat(np.cumsum(k) - k, k)
    j = np.arange(len(piece)) - start
    t = np.where(k[piece] > 1, j / np.maximum(k[piece] - 1, 1), 0.0)
    psi = pieces.lo[piece] + width[piece] * t
    psi[j == k[piece] - 1] = pieces.hi[piece][j == k[piece] - 1]  # the end exactly
    # near each singular end, more samples at geometric spacing: there dq/dψ is unbounded, and the
    # objective can turn within a fraction of a step
    wide = width > 4 * ENDS[-1]
    at_lo, at_hi = np.flatnonzero(wide & sharp[:, 0]), np.flatnonzero(wide & sharp[:, 1])
    extra_piece = np.concatenate([np.repeat(at_lo, len(ENDS)), np.repeat(at_hi, len(ENDS))])
    offsets = np.concatenate([np.tile(ENDS, len(at_lo)), -np.tile(ENDS, len(at_hi))])
    extra = np.where(offsets > 0, pieces.lo[extra_piece], pieces.hi[extra_piece]) + offsets
    if len(extra):
        piece, psi = np.concatenate([piece, extra_piece]), np.concatenate([psi, extra])
        order = np.lexsort((psi, piece))
        piece, psi = piece[order], psi[order]
    pts = scene.values(pieces.pose[piece], pieces.row[piece], psi)
    keep = pts.valid & np.isfinite(pts.f)
    return (pts, piece) if keep.all() else (pts.take(keep), piece[keep])


def roots(scene: BestRun, left: Points, right: Points) -> Points:
    """The root of c between each pair (left[i], right[i]) whose c differ in sign: its point on the feasible side.

    Bracketed iteration: the secant, a Newton step from the feasible end, a point just past it (across
    the root once Newton is close, so that both ends close in) and the midpoint are tried together each
    round; the tightest bracket with a sign change is kept.
    """
    pose, row = left.pose, left.row
    ps, cs, ds = np.stack([left.psi, right.psi]), np.stack([left.c, right.c]), np.stack([left.dc, right.dc])
    for _ in range(MAX_ROUNDS):
        active = np.abs(ps[1] - ps[0]) > PSI_TOL * (1.0 + np.abs(ps[0]))
        if not active.any():
            break
        i = np.flatnonzero(active)
        (a, b), (ca_, cb), (da, db) = ps[:, i], cs[:, i], ds[:, i]
        secant = a - ca_ * (b - a) / np.where(cb != ca_, cb - ca_, np.nan)
        feasible_a = ca_ >= 0
        start, c0, d0 = np.where(feasible_a, a, b), np.where(feasible_a, ca_, cb), np.where(feasible_a, da, db)
        newton = _inside(start - c0 / np.where(d0 != 0, d0, np.nan), a, b)
        # just past the Newton point: across the root when Newton is close, so that the far end moves in too
        past = _inside(newton + (newton - start) * 1e-3 + np.sign(newton - start) * PSI_TOL * (1.0 + np.abs(a)), a, b)
        trials = np.stack([_inside(secant, a, b), newton, past, 0.5 * (a + b)], axis=1)
        n = trials.shape[1]
        pts = scene.evaluate(np.repeat(pose[i], n), np.repeat(row[i], n), trials.ravel())
        for t in range(n):
            x, cx, dx = pts.psi[t::n], pts.c[t::n], pts.dc[t::n]
            side = (cx >= 0) == feasible_a  # replaces the end on its own side of the root, if it is closer
            for k, sel in ((0, side & (x > ps[0, i])), (1, ~side & (x < ps[1, i]))):
                ps[k, i] = np.where(sel, x, ps[k, i])
                cs[k, i] = np.where(sel, cx, cs[k, i])
                ds[k, i] = np.where(sel, dx, ds[k, i])
    return scene.evaluate(pose, row, np.where(cs[0] >= 0, ps[0], ps[1]))


def _inside(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``x`` if strictly between a and b, else the midpoint (the round's midpoint trial guarantees progress)."""
    ok = np.isfinite(x) & (x > np.minimum(a, b)) & (x < np.maximum(a, b))
    return np.where(ok, x, 0.5 * (a + b))


@dataclass
class Polished:
    """Local minima: ``point`` (Points) with ``rounds`` (M,) of polish each."""

    point: Points
    rounds: np.ndarray


def polish_minima(scene: BestRun, a: Points, m: Points, b: Points) -> Polished:
    """Shrink brackets ``a.ψ ≤ m.ψ ≤ b.ψ`` with ``f(m) ≤ f(a), f(b)`` to local minima (see the module docstring).

    ``a`` or ``b`` may equal ``m`` (a minimum at the end of a piece). Each round also probes
    :data:`PSI_TOL` away from m on the side of descent: when nothing improved and the probe's
    slope has the opposite sign, f turns within that distance (a kink of an epigraph term, where
    the bracket ends would otherwise only close in by halving): m is the minimum to that accuracy.
    The clearance constraint holds at a, m and b; a trial where it fails counts as no better
    than any point. A Newton step on c from m (to the constraint's boundary) is tried as well,
    so that a minimum on the boundary of a gap in the clearance between two samples is met as
    fast as one at a kink; when the probe next to m fails the constraint and nothing improved,
    m is on that boundary to :data:`PSI_TOL`.
    Returns the final middle points.
    """
    pose, row = m.pose, m.row
    # X[field, position, candidate]: fields ψ, f, f', c, c'; positions a, m, b
    X = np.array([[getattr(p, name) for p in (a, m, b)] for name in ("psi", "f", "df", "c", "dc")])
    P, F, D, C, DC = X  # views
    rounds = np.zeros(len(m), int)
    done = np.zeros(len(m), bool)
    cols = np.arange(len(m))
    for _ in range(MAX_ROUNDS):
        # descend to the right (toward b) where f' < 0; where f' is not finite (a singular end of an
        # interval, where dq/dψ is unbounded) toward the side that is not empty, or the lower end
        known = np.isfinite(D[1])
        right = np.where(known, D[1] < 0, (P[0] == P[1]) | ((P[2] != P[1]) & (F[2] < F[0])))
        vp, vf, vd = X[:3, np.where(right, 2, 0), cols]
        width = np.abs(vp - P[1])
        tiny = PSI_TOL * (1.0 + np.abs(P[1]))
        done |= (width <= tiny) | (known & (D[1] == 0))
        if done.all():
            break
        i = np.flatnonzero(~done)
        (up, uf, ud), wp, wf, wd = X[:3, 1, i], vp[i], vf[i], vd[i]
        secant = up - ud * (wp - up) / np.where(wd != ud, wd - ud, np.nan)
        tangent = (wf - uf + ud * up - wd * wp) / np.where(ud != wd, ud - wd, np.nan)
        probe = up + np.sign(wp - up) * np.minimum(tiny[i], 0.5 * width[i])
        tangent = _inside(tangent, up, wp)
        mirror = _inside(2.0 * tangent - up, up, wp)  # beyond the kink estimate: the far end moves in too
        steps = [_inside(secant, up, wp), tangent, mirror, 0.5 * (up + wp)]
        if not np.isfinite(ud).all():
            steps.append(up + 1e-3 * (wp - up))  # off a singular end, where f' is not finite
        if np.isfinite(C[1, i]).any():
            edge = up - C[1, i] / np.where(DC[1, i] != 0, DC[1, i], np.nan)  # Newton on c toward its boundary
            steps.append(_inside(edge - 1e-12 * (edge - up), up, wp))
        trials = np.stack([*steps, probe], axis=1)
        k = trials.shape[1]
        pts = scene.evaluate(np.repeat(pose[i], k), np.repeat(row[i], k), trials.ravel())
        # every point known: a, m, b and the trials; the best becomes m, the nearest on each side a and b
        new = np.stack([pts.psi, np.where(pts.c >= 0, pts.f, np.inf), pts.df, pts.c, pts.dc]).reshape(5, len(i), k)
        every = np.concatenate([X[:, :, i].transpose(0, 2, 1), new], axis=2)  # (5, len(i), 3 + k)
        allP, allF, allD = every[:3]
        allF[np.isnan(allF)] = np.inf
        # f's rounding hides the last digits of ψ at a smooth minimum: among the points whose f is
        # within rounding of the least, the one with the smallest |f'| is the best estimate of the root
        low = allF.min(axis=1, keepdims=True)
        ties = allF <= low + NOISE * (1.0 + np.abs(low))
        best = np.argmin(np.where(ties, np.abs(np.where(np.isnan(allD), np.inf, allD)), np.inf), axis=1)
        cols_i = np.arange(len(i))
        pm = allP[cols_i, best][:, None]
        left = np.where(allP < pm, allP, -np.inf)
        right = np.where(allP > pm, allP, np.inf)
        ia = np.where(np.isfinite(left.max(axis=1)), left.argmax(axis=1), best)
        ib = np.where(np.isfinite(right.min(axis=1)), right.argmin(axis=1), best)
        X[:, :, i] = every[:, cols_i, np.stack([ia, best, ib])]
        improved = F[1, i] < uf
        across = np.sign(pts.df[k - 1 :: k]) == -np.sign(ud)  # the probe's slope has turned: a kink within tiny
        blocked = pts.c[k - 1 :: k] < 0  # the probe fails the constraint: m is on its boundary
        done[i] |= (across | blocked) & ~improved
        rounds[i] += 1
    return Polished(scene.evaluate(pose, row, P[1]), rounds)


def split(scene: BestRun, pts: Points, piece: np.ndarray) -> tuple[Points, np.ndarray]:
    """The feasible runs of the samples under ``c ≥ 0``, with the roots of c inserted at their ends.

    Returns the points of the runs (consecutive, increasing ψ within a run) and their run index.
    Without obstacles (c = +∞) the runs are the pieces.
    """
    if not np.isfinite(pts.c).any():
        return pts, piece
    ok = pts.c >= 0
    change = np.flatnonzero((piece[1:] == piece[:-1]) & (ok[1:] != ok[:-1]))
    found = None
    if len(change):  # the roots' brackets, with the derivatives the samples leave out
        found = roots(scene, *_derivatives(scene, pts, [change, change + 1]))
    key = np.arange(len(pts), dtype=float)
    all_pts, all_piece = pts, piece
    if found is not None:
        key = np.concatenate([key, change + 0.5])
        all_pts = Points.join([pts, found])
        all_piece = np.concatenate([piece, piece[change]])
    order = np.argsort(key, kind="stable")
    all_pts, all_piece = all_pts.take(order), all_piece[order]
    keep = all_pts.c >= 0
    all_pts, all_piece = all_pts.take(keep), all_piece[keep]
    kept_key = np.flatnonzero(keep)
    # a new run starts at a new piece or after a removed (infeasible) point
    start = np.ones(len(all_pts), bool)
    start[1:] = (all_piece[1:] != all_piece[:-1]) | (kept_key[1:] != kept_key[:-1] + 1)
    return all_pts, np.cumsum(start) - 1


def candidates(scene: BestRun, pts: Points, run: np.ndarray) -> tuple[Points, Points, Points]:
    """Brackets ``(a, m, b)`` of the discrete local minima of f along each run, the ones to polish, evaluated
    with their derivatives.

    Per (pose, branch row) its :data:`POLISHED_PER_BRANCH` best, then per pose the
    :data:`POLISHED_PER_POSE` best of the rest.
    """
    M = len(pts)
    first = np.ones(M, bool)
    first[1:] = run[1:] != run[:-1]
    last = np.ones(M, bool)
    last[:-1] = run[1:] != run[:-1]
    prev = np.where(first, np.inf, np.roll(pts.f, 1))
    nxt = np.where(last, np.inf, np.roll(pts.f, -1))
    local = np.flatnonzero((pts.f <= prev) & (pts.f <= nxt) & np.isfinite(pts.f))
    order = local[np.lexsort((pts.f[local], pts.row[local], pts.pose[local]))]  # by pose, branch, then f
    group = pts.pose[order] * 10_000 + pts.row[order]
    rank = np.arange(len(order)) - np.searchsorted(group, group)
    chosen = order[rank < POLISHED_PER_BRANCH]
    rest = order[rank >= POLISHED_PER_BRANCH]
    rest = rest[np.lexsort((pts.f[rest], pts.pose[rest]))]
    prank = np.arange(len(rest)) - np.searchsorted(pts.pose[rest], pts.pose[rest])
    chosen = np.concatenate([chosen, rest[prank < POLISHED_PER_POSE]])
    a = np.where(first[chosen], chosen, chosen - 1)
    b = np.where(last[chosen], chosen, chosen + 1)
    return tuple(_derivatives(scene, pts, [a, chosen, b]))


def _derivatives(scene: BestRun, pts: Points, parts: list[np.ndarray]) -> list[Points]:
    """The rows ``parts`` (index arrays) of samples, evaluated with the derivatives in one call."""
    k = np.concatenate(parts)
    full = scene.evaluate(pts.pose[k], pts.row[k], pts.psi[k])
    ends = np.cumsum([0, *(len(p) for p in parts)])
    return [full.take(np.arange(ends[j], ends[j + 1])) for j in range(len(parts))]


AT_LIMIT = 1e-7
"""A joint this close (rad) to a limit at a polished point is taken to be on it (:func:`onto_limits`)."""


def onto_limits(scene: BestRun, pts: Points) -> Points:
    r"""Polished points next to a joint limit, moved onto it where that lowers f.

    A minimum at the end of a feasible interval where a joint reaches its limit is found to the
    accuracy of the interval's end (1e-9 rad, and :data:`END` inside it). Newton steps on
    :math:`q_j(\psi) = l_j` for the joint nearest its limit l_j (with the exact dq/dψ) put it on
    the limit to rounding; the joint values are then clipped into the limits (by at most a few ulps).
    """
    robot = scene.robot
    gap = np.minimum(pts.q - robot.q_min, robot.q_max - pts.q)
    j = gap.argmin(axis=1)
    rows = np.arange(len(pts))
    near = (gap[rows, j] < AT_LIMIT) & (pts.dq[rows, j] != 0)
    if not near.any():
        return pts
    idx = np.flatnonzero(near)
    cur = pts.take(idx)
    jj = j[idx]
    r = np.arange(len(idx))
    limit = np.where(cur.q[r, jj] - robot.q_min[jj] < robot.q_max[jj] - cur.q[r, jj], robot.q_min[jj], robot.q_max[jj])
    psi = cur.psi
    for _ in range(3):
        new = scene.evaluate(cur.pose, cur.row, psi - (cur.q[r, jj] - limit) / cur.dq[r, jj])
        ok = new.valid & np.isfinite(new.f) & (new.c >= 0)
        cur = Points(*(np.where(ok.reshape(-1, *[1] * (getattr(new, f.name).ndim - 1)), getattr(new, f.name),
                                getattr(cur, f.name)) for f in fields(Points)))  # fmt: skip
        psi = cur.psi
    cur.q = np.clip(cur.q, robot.q_min, robot.q_max)
    better = cur.f <= pts.f[idx]
    out = pts.take(np.arange(len(pts)))
    for f in fields(Points):
        getattr(out, f.name)[idx[better]] = getattr(cur, f.name)[better]
    return out
