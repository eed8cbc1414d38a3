r"""The joint-limit margin's global maximum from its exact super-level sets (:func:`qpik.solve_best`'s method
for the margin objective without obstacles).

The margin of a configuration (:class:`~qpik.objectives.JointLimitMargin`, :math:`\rho_j` the half range)

.. math:: \mu(q) = \min_j \min(q_j - l_j,\ u_j - q_j) / \rho_j

is at least m exactly where every joint lies in the limits shrunk by :math:`m\rho_j`. So the super-level
set :math:`S(m) = \{(b, \psi) : \mu(q_b(\psi)) \ge m\}` of every branch b is its exact feasible set under
the shrunk limits, :meth:`~qpik.analytic.solver.AnalyticSolver.feasible_intervals` with ``margin=m``:
computed from the breakpoint equations, not sampled. Per pose, from :math:`S(0)` (the feasible intervals):

1. On every piece [a, b] of :math:`S(m_k)` (a piece through ±π joined into one), evaluate μ and dμ/dψ at
   trial points (:func:`_trials`): in the first round the middle; then the middle, the crossing of the tangents
   at the two ends (exact at a kink, where two joints' margins cross) and the root of the secant of dμ/dψ between
   the points those slopes come from (exact at a quadratic top). The slope at an end comes from the previous
   round's best point on that side of the top (its value and slope, with the end's own value, the level: exact
   for a quadratic). Then climb the top of the piece that holds the best of them (:func:`_climb`: a few steps of
   the same two points between the brackets of its top), so that the next level is close to the maximum.
2. :math:`\mu_{k+1}` is the best value found, :math:`m_{k+1} = \mu_{k+1} + \varepsilon` (:data:`EPS`).
3. An empty :math:`S(m_{k+1})` proves that no branch and δ/ψ reaches :math:`\mu_{k+1} + \varepsilon`:
   the answer is certified to ε (to the sets' accuracy: their ends are exact to
   :data:`qpik.analytic.intervals.SAME`). Otherwise every point of :math:`S(m_{k+1})` beats it: back to 1.

Every point of :math:`S(m_{k+1})` is better than the best so far by ε, so each round gains at least ε, and
near a top the pieces close in on it from both sides: 1–4 rounds on random poses (one when the climb reached the
top, or when the margin is bound by a joint that the parameter does not move, such as the S-R-S elbow). A pose
whose round finds nothing inside its own super-level set, or that needs more than :data:`MAX_ROUNDS`, is left
uncertified:
:func:`qpik.solve_best` searches it by sampling and proves it with the Taylor models
(:mod:`qpik.nlp.certificate`) instead.

The certificate costs one feasible-set call (tens of µs) where the Taylor models need ~150 cells of a
compiled bound function; it covers only the plain margin (a weighted sum with other terms has no such level
sets). Where the arm's feasible sets are one C call (:meth:`~qpik.analytic.solver.AnalyticSolver.native_sets`),
the rounds of a pose run in C (``levelset.c``, one call per pose, the self-motion through its generated C; the
sets of a round classify only the gaps inside the previous round's sets, which hold them);
otherwise in Python and numpy, all poses of a batch together. The two give the same answers (tested).
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from qpik.analytic.intervals import FeasibleIntervals, wrap
from qpik.analytic.native_sets import NativeSets
from qpik.geometry.distance import ObstacleSet
from qpik.native.compiled import Kernel, NativeFunction
from qpik.native.sources import load_source
from qpik.nlp.run import BestRun, Points, least_per_row
from qpik.nlp.search import END
from qpik.nlp.selfmotion import SelfMotion
from qpik.objectives import JointLimitMargin, Objective

EPS = 1e-9
r"""ε: each level is the best margin found plus this (the certificate's gap, in μ; about what the sets'
boundaries, exact to 1e-9 rad, can resolve)."""
MAX_ROUNDS = 12
"""Most rounds per pose before it is left to the search."""
TWO_PI = 2.0 * np.pi
NEAR = 1e-7
"""A trial point this close (rad) to an end of a piece gives the slope there."""
SLACK = 1e-12
"""A piece lies in its parent to this (rad): the sets' ends move with the level, and by rounding."""
CLIMB = 6
"""Steps of a round's climb (:func:`_climb`) at most."""
ROWS = 64
"""More than any arm's branch rows (a piece's key: pose · ROWS + row)."""


def margin_weight(objective: Objective, obstacles: ObstacleSet, selfmotion: SelfMotion) -> float | None:
    """w when the objective is w · the (epigraph) margin with w > 0, there are no obstacles and no joint's
    range spans a whole turn (``selfmotion.whole_turn``): the cases this method solves. None otherwise."""
    terms = objective.terms
    if len(obstacles) or len(terms) != 1 or selfmotion.whole_turn:
        return None
    ((w, term),) = terms
    if not isinstance(term, JointLimitMargin) or term.smooth or not w > 0:
        return None
    return float(w)


@dataclass
class LevelSets:
    """What :func:`maximise` found: per pose and searched branch row, the best point the rounds evaluated.

    Attributes:
        mu: (N, R) its margin (−inf where the rounds evaluated none); psi: (N, R) its parameter, rad;
            q: (N, R, n) its configuration, rad.
        rounds: (N, R) the last round that evaluated the row (1 for the first); evaluations: (N, R) the points it
            evaluated.
        certified: (N,) the best point of the pose is proved to be within ε of the maximum.
        bound: (N,) for a certified pose, a lower bound of the objective over every feasible point
            (−w (μ + ε)); -inf otherwise.
    """

    mu: np.ndarray
    psi: np.ndarray
    q: np.ndarray
    rounds: np.ndarray
    evaluations: np.ndarray
    certified: np.ndarray
    bound: np.ndarray


def build(scene: BestRun, rows: list[int]) -> None:
    """Trace and compile, with the scene's clock paused, what :func:`maximise` calls for ``rows``: the C rounds, or
    else the sets under shrunk limits (by evaluating them at the first pose) and the self-motion."""
    sm = scene.selfmotion
    with scene.watch.paused():
        if list(rows) == list(range(sm.searched)) and _native(sm) is not None:
            return
        sm.build_sets(scene.poses[0])
        sm.build(models=False)


def maximise(scene: BestRun, rows: list[int], weight: float) -> LevelSets:
    """The rounds of the module docstring for every pose of ``scene`` over the branch rows ``rows``; f = −``weight``
    · μ. In C (``levelset.c``: the arm's feasible sets and its self-motion as C calls, one call per pose) where the
    arm has :meth:`~qpik.analytic.solver.AnalyticSolver.native_sets` and every row is searched; else in Python
    and numpy, all poses together (the same rounds: the tests compare the two)."""
    sm = scene.selfmotion
    build(scene, rows)
    native = _native(sm) if list(rows) == list(range(sm.searched)) else None
    if native is not None:
        return native(scene, weight)
    solver = sm.solver
    N, R, n = len(scene.poses), sm.searched, scene.robot.dof
    out = LevelSets(np.full((N, R), -np.inf), np.zeros((N, R)), np.zeros((N, R, n)), np.zeros((N, R), int),
                    np.zeros((N, R), int), np.zeros(N, bool), np.full(N, -np.inf))  # fmt: skip
    best = np.full(N, -np.inf)
    level = np.zeros(N)
    current = {i: solver.feasible_intervals(T) for i, T in enumerate(scene.poses)}
    proved = np.array([current[i].proved for i in range(N)], bool)  # every set of the pose's rounds proved
    parent = None
    for k in range(MAX_ROUNDS + 1):
        pieces = _pieces(current, rows, level)
        found = np.zeros(N, bool)
        found[pieces.pose] = True
        if k:
            out.certified[[i for i in current if not found[i]]] = True
        if not len(pieces) or k == MAX_ROUNDS:
            break
        psi = _trials(pieces, parent)  # (trials, P)
        reps = len(psi)
        pts, mu, slope = _margins(scene, np.tile(pieces.pose, reps), np.tile(pieces.row, reps), psi.ravel(), weight)
        _keep_best(out, pts, mu, k + 1)
        top = np.full(N, -np.inf)
        np.maximum.at(top, pts.pose, mu)
        pieces.x, pieces.mu, pieces.slope = psi, mu.reshape(len(psi), -1), slope.reshape(len(psi), -1)
        _climb(scene, pieces, top, weight, out, k + 1)
        # inside S(level) every point has μ ≥ level: a pose whose round found nothing there is left to the search
        moved = found & (top > level - 0.5 * EPS) if k else found
        best = np.where(found, np.maximum(best, top), best)
        moved &= np.isfinite(best)
        level = np.maximum(best, 0.0) + EPS
        current = {i: solver.feasible_intervals(scene.poses[i], margin=float(level[i])) for i in np.flatnonzero(moved)}
        proved[list(current)] &= [fi.proved for fi in current.values()]
        parent = pieces
    out.certified &= proved
    out.bound = np.where(out.certified, -weight * level, -np.inf)
    return out


def _margins(
    scene: BestRun, pose: np.ndarray, row: np.ndarray, psi: np.ndarray, weight: float
) -> tuple[Points, np.ndarray, np.ndarray]:
    """The points (M,) of branch rows ``row`` at ψ (rad, wrapped here) of the poses ``pose``, with μ and dμ/dψ there
    (−inf and NaN where the branch does not reach the pose)."""
    pts = scene.evaluate(pose, row, wrap(psi))
    ok = pts.valid & np.isfinite(pts.f)
    return pts, np.where(ok, -pts.f / weight, -np.inf), np.where(ok, -pts.df / weight, np.nan)


def _climb(scene: BestRun, pieces: _Pieces, top: np.ndarray, weight: float, out: LevelSets, round_: int) -> None:
    r"""Per pose, climbs the top of the piece that holds its round's best trial point (the first), before the level
    is raised: :data:`CLIMB` steps at most, each evaluating the crossing of the tangents of the two brackets (the
    best points with dμ/dψ > 0 and < 0; an end of the piece, where μ is the level, stands for a missing one, its
    slope that of the quadratic through it and the other bracket) and the root of the secant of dμ/dψ between
    them (exact at a quadratic top; the crossing is exact at a kink). Each point replaces the bracket on its side;
    the climb stops where the tangents' crossing (their upper bound near a top) is within ε/2 of ``top``.

    A level near the top is what proves it in one more call of the sets; without the climb the rounds close in on a
    smooth top by the sets alone, one call per round. Raises ``top`` (N,) in place; the points go into ``out``."""
    hit = np.flatnonzero((top[pieces.pose][:, None] == pieces.mu.T).any(axis=1))
    at = hit[np.unique(pieces.pose[hit], return_index=True)[1]]  # per pose its first piece at the top
    pose, row = pieces.pose[at], pieces.row[at]
    lx, rx, lm = pieces.lo[at], pieces.hi[at], pieces.level[at]
    rm, ls, rs = lm.copy(), np.full(len(at), np.nan), np.full(len(at), np.nan)
    lk, rk = np.zeros(len(at), bool), np.zeros(len(at), bool)
    for x, m, s in zip(pieces.x[:, at], pieces.mu[:, at], pieces.slope[:, at]):
        take = (s > 0) & (~lk | (m > lm))
        lx, lm, ls, lk = np.where(take, x, lx), np.where(take, m, lm), np.where(take, s, ls), lk | take
        take = (s < 0) & (~rk | (m > rm))
        rx, rm, rs, rk = np.where(take, x, rx), np.where(take, m, rm), np.where(take, s, rs), rk | take
    active, t = lk | rk, top[pose]
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(CLIMB):
            active &= rx - lx > SLACK
            sl = np.where(lk, ls, 2.0 * (lm - rm) / (lx - rx) - rs)
            sr = np.where(rk, rs, 2.0 * (rm - lm) / (rx - lx) - ls)
            active &= (sl > 0) & (sr < 0) & np.isfinite(sl - sr)
            cross = (rm - lm + sl * lx - sr * rx) / (sl - sr)
            active &= ~(lm + sl * (cross - lx) - t < 0.5 * EPS)
            secant = np.where(lk & rk, lx - ls * (rx - lx) / (rs - ls), np.nan)
            for x in (cross, secant):
                i = np.flatnonzero(active & (x > lx) & (x < rx))
                if not len(i):
                    continue
                pts, m, s = _margins(scene, pose[i], row[i], x[i], weight)
                _keep_best(out, pts, m, round_)
                t[i] = np.maximum(t[i], m)
                up, down = s > 0, s < 0
                lx[i], lm[i], ls[i] = np.where(up, x[i], lx[i]), np.where(up, m, lm[i]), np.where(up, s, ls[i])
                rx[i], rm[i], rs[i] = np.where(down, x[i], rx[i]), np.where(down, m, rm[i]), np.where(down, s, rs[i])
                lk[i] |= up
                rk[i] |= down
                active[i] &= up | down  # the top itself, or no point
            if not active.any():
                break
    top[pose] = t


def _keep_best(out: LevelSets, pts: Points, mu: np.ndarray, round_: int) -> None:
    """The points of round ``round_`` (their margins ``mu``) into ``out``: each row's best, its rounds and counts."""
    np.add.at(out.evaluations, (pts.pose, pts.row), 1)
    out.rounds[pts.pose, pts.row] = round_
    top = least_per_row(pts.pose, pts.row, -mu)
    top = top[mu[top] > out.mu[pts.pose[top], pts.row[top]]]
    i, r = pts.pose[top], pts.row[top]
    out.mu[i, r], out.psi[i, r], out.q[i, r] = mu[top], pts.psi[top], pts.q[top]


@dataclass
class _Pieces:
    """Pieces of super-level sets: [lo, hi] (rad, hi ≤ lo + 2π) of branch row ``row`` of pose ``pose`` at
    ``level`` (μ), all (P,); after their round, the trial points ``x`` (3, P) with μ (``mu``) and dμ/dψ
    (``slope``) there (−inf and NaN where the branch does not reach the pose)."""

    pose: np.ndarray
    row: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    level: np.ndarray
    x: np.ndarray | None = None
    mu: np.ndarray | None = None
    slope: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.lo)

    @property
    def key(self) -> np.ndarray:
        """(P,) one integer per (pose, branch row)."""
        return self.pose * ROWS + self.row


def _pieces(sets: dict[int, FeasibleIntervals], rows: list[int], level: np.ndarray) -> _Pieces:
    """The pieces of the sets' rows ``rows`` (pose i's sets at ``level[i]``); a set through ±π (one interval
    ending at π, one starting at −π) is one piece [lo, hi + 2π]."""
    pose, row, lo, hi = [], [], [], []
    for i, fi in sets.items():
        for b in rows:
            ivs = fi.intervals[b]
            if len(ivs) > 1 and ivs[0][0] == -np.pi and ivs[-1][1] == np.pi:
                ivs = [(ivs[-1][0], ivs[0][1] + TWO_PI), *ivs[1:-1]]
            for a, c in ivs:
                pose.append(i), row.append(b), lo.append(a), hi.append(c)
    pose_a = np.array(pose, int)
    return _Pieces(pose_a, np.array(row, int), np.array(lo, float), np.array(hi, float), level[pose_a])


def _trials(pieces: _Pieces, parent: _Pieces | None) -> np.ndarray:
    """(3, P) trial points of the pieces (rad, in [lo, hi]): the middle, the crossing of the tangents at the two
    ends, and the root of the secant of dμ/dψ between the points the tangents' slopes come from; (1, P), the middle,
    in the first round (``parent`` None).

    The slope at the left end (a level crossing) comes from the best point x with dμ/dψ > 0 of the previous
    round's piece that holds this one (its parent): 2 (level − μ(x))/(lo − x) − μ'(x), exact for a quadratic
    (μ'(x) itself when x is the end, :data:`NEAR`);
    without such a point, the secant through the two level crossings (lo_parent, level_parent) and (lo, level).
    The right end likewise, with dμ/dψ < 0. Where one side has no such point, the end of that side (:data:`END`
    inside) instead of the root: its slope serves the next round.

    After the first round a pose has a few pieces: plain floats, which cost less than numpy's calls here."""
    lo, hi = pieces.lo, pieces.hi
    if parent is None:
        return 0.5 * (lo + hi)[None]
    inset = np.minimum(END, 0.25 * (hi - lo))
    holders: dict[int, list[int]] = {}
    for k, key in enumerate(parent.key.tolist()):
        holders.setdefault(key, []).append(k)
    p_lo, p_hi, p_level = parent.lo.tolist(), parent.hi.tolist(), parent.level.tolist()
    p_x, p_mu, p_slope = parent.x.T.tolist(), parent.mu.T.tolist(), parent.slope.T.tolist()
    out = []
    rows = zip(lo.tolist(), hi.tolist(), pieces.level.tolist(), pieces.key.tolist(), inset.tolist())
    for a, b, level, key, e in rows:
        mid = 0.5 * (a + b)
        k = next((k for k in holders.get(key, ()) if p_lo[k] <= a + SLACK and b <= p_hi[k] + SLACK), None)
        if k is None:
            out.append((mid, mid, mid))
            continue
        side = []  # per end: (the slope there, the point it came from or None)
        for end, p_end, sign in ((a, p_lo[k], 1.0), (b, p_hi[k], -1.0)):
            top = None
            for x, f, d in zip(p_x[k], p_mu[k], p_slope[k]):
                if sign * d > 0 and (top is None or f > top[1]):
                    top = (x + TWO_PI * round((mid - x) / TWO_PI), f, d)  # beside this piece (one may pass π)
            if top is not None and abs(end - top[0]) <= NEAR:  # the point is the end: its own slope
                side.append((top[2], top))
            elif top is not None:
                side.append((2.0 * (level - top[1]) / (end - top[0]) - top[2], top))
            else:
                side.append(((level - p_level[k]) / (end - p_end) if end != p_end else sign * math.inf, None))
        (sl, left), (sr, right) = side
        cross = (sl * a - sr * b) / (sl - sr) if sl > 0 > sr and math.isfinite(sl - sr) else mid
        if left is not None and right is not None and left[2] != right[2]:
            root = left[0] - left[2] * (right[0] - left[0]) / (right[2] - left[2])
        else:
            root = b - e if left is not None else a + e
        out.append((mid, min(max(cross, a), b), min(max(root, a), b) if math.isfinite(root) else mid))
    return np.array(out).T


ROOM = 1024
"""Pieces per round the C rounds hold; a pose with more is left unproved (to the search)."""


class _LevelSet(ctypes.Structure):
    """``LevelSet`` of ``levelset.c`` (same fields, same order)."""

    _fields_ = [(name, ctypes.c_void_p) for name in ("sets", "context", "sets_pose", "sets_lo", "sets_hi", "iv")]
    _fields_ += [("count", ctypes.c_void_p), ("region", ctypes.c_void_p), ("n_region", ctypes.c_void_p)]
    _fields_ += [("region_room", ctypes.c_int), ("rows", ctypes.c_int), ("motion", Kernel)]
    _fields_ += [(name, ctypes.c_void_p) for name in ("motion_row", "motion_pose", "motion_psi", "motion_out")]
    _fields_ += [("n", ctypes.c_int), ("q_min", ctypes.c_void_p), ("q_max", ctypes.c_void_p)]
    _fields_ += [(name, ctypes.c_double) for name in ("eps", "end", "near", "slack")]
    _fields_ += [(name, ctypes.c_int) for name in ("climb", "max_rounds", "room")] + [("work", ctypes.c_void_p)]


class _Native:
    """The rounds in C (``qpik_levelset``, ``levelset.c``) for one arm: its feasible sets under run-time limits
    (:class:`~qpik.analytic.native_sets.NativeSets`) and its self-motion's one-row call, over buffers allocated once."""

    def __init__(self, dll: ctypes.CDLL, sets: NativeSets, motion: NativeFunction, selfmotion: SelfMotion):
        robot = selfmotion.robot
        self._dll, self._sets, self._motion = dll, sets, motion  # the C call uses their buffers: they live as long
        self._rows = selfmotion.searched
        self._limits = (np.array(robot.q_min, float), np.array(robot.q_max, float))
        self._work = np.zeros(24 * ROOM)
        row, pose, psi = (a.ctypes.data for a in motion.args)
        self._call = _LevelSet(
            sets=sets.function, context=sets.context, sets_pose=sets.pose.ctypes.data, sets_lo=sets.lo.ctypes.data,
            sets_hi=sets.hi.ctypes.data, iv=sets.iv.ctypes.data, count=sets.count.ctypes.data,
            region=sets.region.ctypes.data, n_region=sets.n_region.ctypes.data, region_room=len(sets.region) // 2,
            rows=self._rows,
            motion=motion.kernel, motion_row=row, motion_pose=pose, motion_psi=psi,
            motion_out=motion.res[0].ctypes.data, n=robot.dof, q_min=self._limits[0].ctypes.data,
            q_max=self._limits[1].ctypes.data, eps=EPS, end=END, near=NEAR, slack=SLACK, climb=CLIMB,
            max_rounds=MAX_ROUNDS, room=ROOM, work=self._work.ctypes.data,
        )  # fmt: skip
        self._address = ctypes.addressof(self._call)
        self._width = self._rows * (robot.dof + 2) + 1  # per pose: mu (R), psi (R), q (R, n), the last level
        self._poses = np.zeros((0, 16))  # the call's buffers (:meth:`__call__`): poses, out (width), info (2 R + 1)

    def __call__(self, scene: BestRun, weight: float) -> LevelSets:
        N, R = len(scene.poses), self._rows
        if len(self._poses) < N:  # the call's buffers, grown to the largest batch so far
            self._poses, self._out = np.zeros((N, 16)), np.zeros((N, self._width))
            self._info = np.zeros((N, 2 * R + 1), np.intc)
            self._at = [a.ctypes.data for a in (self._poses, self._out, self._info)]
        self._poses[:N] = scene.columns
        failed = self._dll.qpik_levelset(self._address, N, *self._at)
        if failed:  # -1 (more pieces than the buffers hold) is a pose left to the search; below it a failure
            raise RuntimeError(f"qpik_levelset failed ({failed}: -2 a compiled function failed, -3 no memory)")
        out, info = self._out[:N].copy(), self._info[:N].copy()
        certified = info[:, 2 * R] == 1
        return LevelSets(
            out[:, :R], out[:, R : 2 * R], out[:, 2 * R : -1].reshape(N, R, -1), info[:, :R], info[:, R : 2 * R],
            certified, np.where(certified, -weight * out[:, -1], -np.inf),
        )  # fmt: skip


def _native(selfmotion: SelfMotion) -> _Native | None:
    """The C rounds of ``selfmotion``'s arm (built once per robot), None without a compiler or the arm's
    native sets."""
    return selfmotion.robot.cache.get("level-set rounds", _build_native, selfmotion)


def _build_native(selfmotion: SelfMotion) -> _Native | None:
    sets = selfmotion.solver.native_sets()
    dll = None if sets is None else _library()
    motion = None if dll is None else NativeFunction.of(selfmotion.point_call, outputs=(0,))
    return None if motion is None else _Native(dll, sets, motion, selfmotion)


@cache
def _library() -> ctypes.CDLL | None:
    """``levelset.c`` compiled, loaded as a :class:`ctypes.PyDLL` (its call keeps the GIL: the arm's buffers are one
    thread's at a time, under the solver's lock)."""
    args = [ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
    return load_source("qpik_levelset", "pydll", ["levelset.c"], signatures={"qpik_levelset": (ctypes.c_int, args)})
