r"""The search behind :func:`~qpik.nlp.best.solve_best`: every feasible interval of every branch, then the certificate.

:func:`solve_poses` takes the poses of one :class:`~qpik.nlp.run.BestRun`. With the level-set method
(the margin alone, :mod:`qpik.nlp.levelset`) the poses it proves are done; the others are searched:
the feasible intervals of the searched branch rows (:meth:`~qpik.analytic.solver.AnalyticSolver.feasible_intervals`)
become pieces, sampled every :data:`~qpik.nlp.search.SAMPLE_STEP` rad, split at infeasible samples and
polished around their local minima (:mod:`qpik.nlp.search`), or solved by IPOPT per piece
(:mod:`qpik.nlp.ipopt`). :class:`BestSoFar` keeps per (pose, branch row) the best feasible point. The
certificate (:mod:`qpik.nlp.certificate`) then proves the best value per pose to a tolerance, or
returns better points, which are searched again with samples 4 times closer (at most
:data:`RETRIES` times). A pose without any feasible point gets
:func:`~qpik.nlp.least_violating.least_violating`'s answer. Its status claims that none exists only with a proof:
the feasible sets are empty, or the certificate, run with :math:`f^* = +\infty`, cuts off every cell of every
feasible interval by its clearance (a clearance whose upper bound over the cell is below d_s). Otherwise it is
``"not found"``, with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from qpik.nlp.best_result import BestResult, BranchRows
from qpik.nlp.certificate import certify as prove
from qpik.nlp.least_violating import least_violating
from qpik.nlp.levelset import maximise
from qpik.nlp.run import BestRun, Points, least_per_row
from qpik.nlp.search import SAMPLE_STEP, Pieces, candidates, onto_limits, polish_minima, sample, singular_ends, split
from qpik.nlp.selfmotion import SelfMotion

RETRIES = 2
"""Searches again (with samples 4x closer each time) when the certificate finds a better point."""
UNPROVED_SETS = "the feasible sets at this pose are not proved"
"""The message of an answer over feasible sets that are not proved (``AnalyticSolver.sets_proved``,
``FeasibleIntervals.proved``)."""
NONE_FOUND = "no feasible point was found, and that none exists is not proved"
"""The message of ``"not found"``: the search found no feasible point and the certificate could not prove its
absence (the reason follows)."""


def solve_poses(
    scene: BestRun, certify: bool, tol: float, method: str, rows: list[int], weight: float | None
) -> list[BestResult]:
    """One result per pose of ``scene``: ``method`` ``"levelset"``, ``"search"`` or ``"ipopt"``, the branch rows
    ``rows``, certified to the relative tolerance ``tol`` when ``certify``; ``weight`` the margin's weight (the
    level-set method)."""
    sm = scene.selfmotion
    N, B = len(scene.poses), sm.searched
    certify = certify and sm.solver.sets_proved  # a certificate over unproved sets would prove nothing
    if method == "levelset":
        sets = maximise(scene, rows, weight)
        scene.counts += sets.evaluations
        f = -weight * sets.mu  # +inf where a row has no point
        if sets.certified.all():  # the common case: every answer comes straight from the rounds
            found = BestSoFar(f, sets.psi, sets.q, sets.rounds, np.full(f.shape, np.inf))
            return _answers(scene, found, rows, sets.certified, sets.bound, [""] * N, ["levelset"] * N)
    best = BestSoFar.empty(N, B, scene.robot.dof)
    cert_ok = np.zeros(N, bool)
    bound = np.full(N, -np.inf)
    reason = ["certify=False"] * N
    by_levels = np.zeros(N, bool)
    if method == "levelset":  # the poses it leaves uncertified go to the search and the certificate
        by_levels = sets.certified
        best.take(f, sets.psi, sets.q, sets.rounds)
        cert_ok, bound = sets.certified.copy(), sets.bound.copy()
        method = "search"
    left = np.flatnonzero(~by_levels)
    scene.build_search()
    fis = dict(zip(left.tolist(), (sm.solver.feasible_intervals(scene.poses[i]) for i in left)))
    unproved = [i for i in left.tolist() if not fis[i].proved]
    pieces = _feasible_pieces(fis, rows, left)
    if method == "ipopt":
        from qpik.nlp.ipopt import solve_pieces

        best.update(*solve_pieces(scene, pieces))
    elif len(pieces):
        best.update_from(*_search(scene, pieces, SAMPLE_STEP))
    searched = np.zeros(N, bool)
    searched[pieces.pose] = True
    for i in left[~best.found()[left] & ~searched[left]].tolist():
        cert_ok[i], reason[i] = fis[i].proved, ""  # empty sets: nothing inside the limits reaches the pose
    # a pose without a feasible point is certified too: with f* = +inf, every cell must be cut off by its clearance
    todo = np.setdiff1d(np.flatnonzero((best.found() | searched) & certify & ~cert_ok), unproved)
    for attempt in range(RETRIES + 1):
        if not len(todo):
            break
        value = best.pose_value()
        top = np.argmin(best.f, axis=1)
        focus = top, best.psi[np.arange(len(top)), top]
        slack = np.where(np.isfinite(value), tol * np.maximum(1.0, np.abs(value)), 0.0)
        cert = prove(scene, pieces, value, slack, todo, focus)
        for i in todo:
            cert_ok[i], bound[i], reason[i] = cert.certified[i], cert.bound[i], cert.reason[i]
        if cert.better is None or attempt == RETRIES:
            break
        redo = np.unique(cert.better.pose)
        sub = pieces.take(np.isin(pieces.pose, redo))
        best.update_from(*_search(scene, sub, SAMPLE_STEP / 4 ** (attempt + 1), extra=cert.better))
        todo = redo
    methods = ["levelset" if done else method for done in by_levels.tolist()]
    for i in unproved:  # the certificate stands on the feasible sets
        cert_ok[i], reason[i] = False, UNPROVED_SETS
    return _answers(scene, best, rows, cert_ok, bound, reason, methods)


def _feasible_pieces(fis: dict, rows: list[int], poses: np.ndarray) -> Pieces:
    """The feasible intervals ``fis`` (by pose index) of the branch rows ``rows`` of the poses ``poses`` as pieces,
    with their singular ends."""
    if not len(poses):
        none = np.zeros(0)
        return Pieces(none.astype(int), none.astype(int), none, none, np.zeros((0, 2), bool))
    pose, row, lo, hi = [], [], [], []
    s_pose, s_row, s_value = [], [], []
    for i in poses.tolist():
        fi = fis[i]
        for b in rows:
            for a, c in fi.intervals[b]:
                pose.append(i), row.append(b), lo.append(a), hi.append(c)
            if fi.singular and fi.singular[b]:
                s_value += fi.singular[b]
                s_pose += [i] * len(fi.singular[b])
                s_row += [b] * len(fi.singular[b])
    pieces = Pieces(np.array(pose, int), np.array(row, int), np.array(lo, float), np.array(hi, float))
    pieces.singular = singular_ends(pieces, np.array(s_pose, int), np.array(s_row, int), np.array(s_value, float))
    return pieces


def _search(scene: BestRun, pieces: Pieces, step: float, extra: Points | None = None) -> tuple[Points, np.ndarray]:
    """Sample, split and polish: the polished local minima and their polish rounds.

    Every (pose, branch row) with a feasible sample has its best discrete local minimum polished
    (:data:`~qpik.nlp.search.POLISHED_PER_BRANCH`), and polishing never raises f: the polished
    points hold each branch's best point found."""
    if not len(pieces):
        return scene.evaluate(np.zeros(0, int), np.zeros(0, int), np.zeros(0)), np.zeros(0, int)
    pts, piece = sample(scene, pieces, step)
    if extra is not None:
        # a certificate's better points join the samples of their piece
        inside = (extra.pose[:, None] == pieces.pose) & (extra.row[:, None] == pieces.row)
        inside &= (extra.psi[:, None] >= pieces.lo) & (extra.psi[:, None] <= pieces.hi)
        hit = inside.any(axis=1)
        extra_piece = inside.argmax(axis=1)[hit]
        pts, piece = Points.join([pts, extra.take(hit)]), np.concatenate([piece, extra_piece])
        order = np.lexsort((pts.psi, piece))
        pts, piece = pts.take(order), piece[order]
    _count(scene, pts)
    runs, run = split(scene, pts, piece)
    if not len(runs):
        return runs, np.zeros(0, int)
    a, m, b = candidates(scene, runs, run)
    before = scene.evaluations
    pol = polish_minima(scene, a, m, b)
    share = (scene.evaluations - before) / max(len(m), 1)
    np.add.at(scene.counts, (m.pose, m.row), np.round(share).astype(int))
    return onto_limits(scene, pol.point), pol.rounds


def _count(scene: BestRun, pts: Points) -> None:
    np.add.at(scene.counts, (pts.pose, pts.row), 1)


@dataclass
class BestSoFar:
    """Per (pose, branch row): the best feasible point found so far, f (N, B) (+inf where none), ψ (N, B), q (N, B,
    n), the polish rounds (N, B) and the clearance (N, B)."""

    f: np.ndarray
    psi: np.ndarray
    q: np.ndarray
    rounds: np.ndarray
    clearance: np.ndarray

    @classmethod
    def empty(cls, N: int, B: int, n: int) -> BestSoFar:
        """No point yet: f and the clearance +inf, ψ and q 0 (finite: they are never read where f is +inf)."""
        none = np.full((N, B), np.inf)
        return cls(none, np.zeros((N, B)), np.zeros((N, B, n)), np.zeros((N, B), int), none.copy())

    def update(self, pose, row, psi, q, f, rounds, clearance) -> None:
        """Points (M,) with their rounds: the best feasible one of each (pose, branch row) replaces a worse best."""
        pose, row, f = np.asarray(pose, int), np.asarray(row, int), np.asarray(f, float)
        if not len(f):
            return
        np.maximum.at(self.rounds, (pose, row), np.asarray(rounds, int))
        ok = np.flatnonzero(np.isfinite(f))
        top = ok[least_per_row(pose[ok], row[ok], f[ok])]
        top = top[f[top] < self.f[pose[top], row[top]]]
        i, b = pose[top], row[top]
        self.f[i, b], self.psi[i, b], self.q[i, b] = f[top], np.asarray(psi)[top], np.asarray(q)[top]
        self.clearance[i, b] = np.asarray(clearance)[top]

    def take(self, f: np.ndarray, psi: np.ndarray, q: np.ndarray, rounds: np.ndarray) -> None:
        """Each (pose, branch row)'s best point already found: f (N, B) (+inf where none), ψ (N, B), q (N, B, n),
        rounds (N, B); a point replaces a worse best."""
        better = f < self.f
        self.f = np.where(better, f, self.f)
        self.psi = np.where(better, psi, self.psi)
        self.q = np.where(better[..., None], q, self.q)
        self.rounds = np.maximum(self.rounds, rounds)

    def update_from(self, pts: Points, rounds: np.ndarray) -> None:
        """:meth:`update` with evaluated points (the invalid ones skipped)."""
        f = np.where(pts.valid, pts.f, np.inf)
        clear = pts.d.min(axis=1) if pts.d.shape[1] else np.full(len(pts), np.inf)
        self.update(pts.pose, pts.row, pts.psi, pts.q, f, rounds, clear)

    def found(self) -> np.ndarray:
        return np.isfinite(self.f).any(axis=1)

    def pose_value(self) -> np.ndarray:
        return self.f.min(axis=1)


def _answers(
    scene: BestRun,
    best: BestSoFar,
    searched: list[int],
    certified: np.ndarray,
    bound: np.ndarray,
    reason: list[str],
    method: list[str],
) -> list[BestResult]:
    """Per pose, the result from the best points, and what its per-branch table is built from."""
    sm = scene.selfmotion
    columns, ids = _columns(sm, tuple(searched)), sm.branch_ids.tolist()
    if not sm.solver.sets_proved:  # the level sets and the certificate stand on the feasible sets
        certified = np.zeros_like(certified)
        reason = [UNPROVED_SETS] * len(reason)
    out = []
    poses = zip(best.f.tolist(), best.psi.tolist(), best.rounds.tolist(), scene.counts.tolist(), best.q.copy(),
                best.clearance.tolist(), certified.tolist(), bound.tolist(), reason, method)  # fmt: skip
    for i, (f, psi, rounds, counts, q, clear, proved, low, why, how) in enumerate(poses):
        rows = BranchRows(columns, f, psi, q, rounds, counts)
        value = min(f)
        if value == math.inf and proved:
            result = least_violating(scene, i, rows)
        elif value == math.inf:
            result = least_violating(scene, i, rows, "not found", f"{NONE_FOUND} ({why})")
        else:
            r = f.index(value)
            result = BestResult("optimal", ids[r], psi[r], q[r].copy(), value, proved,
                                value - low if proved else math.inf, clear[r], 0.0, sm.solver.param_name,
                                "" if proved else why, rows=rows)  # fmt: skip
        result.method = how
        out.append(result)
    return out


@lru_cache(maxsize=64)
def _columns(sm: SelfMotion, searched: tuple[int, ...]) -> list[tuple[int, int, float | None, bool]]:
    """The table's branches: per branch (public id, its searched row, its shift (None: its own row), searched)."""
    out = []
    for k, bid in enumerate(sm.branch_ids.tolist()):
        m = sm.mirror(k)
        row = k if m is None else m[0]
        out.append((bid, row, None if m is None else m[1], row in searched))
    return out
