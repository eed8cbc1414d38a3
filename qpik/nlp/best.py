r"""``qpik.solve_best``: the globally best branch and δ/ψ of a closed-form arm for a pose.

Minimises an objective (:mod:`qpik.objectives`) over every branch and every δ (offset
shoulder) or ψ (S-R-S) that keeps the joints inside their limits (the exact
:func:`qpik.feasible_intervals`) and every link capsule at least ``d_safe`` from every obstacle.
The variable is the one parameter; q is the branch's closed form, traced in CasADi with exact
derivatives (:mod:`qpik.nlp.selfmotion`). Every feasible interval of every branch is searched
(:mod:`qpik.nlp.search`: sampling, then a bracketed polish of the local minima; or, with
``method="ipopt"``, IPOPT from the middle of each interval, :mod:`qpik.nlp.ipopt`), and the
answer is checked for global optimality (:mod:`qpik.nlp.certificate`). The plain joint-limit
margin without obstacles has a faster exact method, which finds and proves its maximum with the
feasible intervals under shrunk limits (:mod:`qpik.nlp.levelset`); a pose it leaves unproved goes
through the search and the certificate. In its per-branch table a branch's row holds the best point
evaluated on that branch, which is the branch's own optimum only for the best branch.

Statuses: ``"optimal"`` (the best point found; :attr:`BestResult.certified` says whether it is
proved global), ``"unreachable"`` (no branch reaches the pose at any parameter),
``"no feasible branch"`` (reachable, but not inside the limits and clear of the obstacles),
``"solver failed"`` (a numerical failure, or an answer that fails its own check at q: FK, limits,
clearance; the reason in :attr:`BestResult.message`).
Every result's q is a finite configuration: for a status other than ``"optimal"`` it is the
fallback of :func:`least_violating` (its objective is +inf, :attr:`BestResult.violation` says how
far it is from a solution). Outputs never hold NaN.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np

from qpik.analytic.intervals import wrap
from qpik.core.errors import InputError, NoClosedFormError
from qpik.core.validate import finite_array, flag, number
from qpik.core.validate import pose as check_pose
from qpik.geometry.distance import ObstacleSet
from qpik.nlp.certificate import certify as prove
from qpik.nlp.levelset import margin_weight, maximise
from qpik.nlp.options import BestOptions
from qpik.nlp.run import BestRun, Points, least_per_row
from qpik.nlp.search import SAMPLE_STEP, Pieces, candidates, onto_limits, polish_minima, sample, singular_ends, split
from qpik.nlp.selfmotion import SelfMotion, selfmotion_of
from qpik.objectives import Objective, Quantity, ReferenceDistance, clearance
from qpik.robots.robot import Robot
from qpik.scene.scene import Scene, scene_of

VERIFY_TOL = 1e-9
"""m and rad: an ``"optimal"`` answer's FK reaches the pose to this (:func:`_verify`)."""
UNPROVED_SETS = "this closed form's feasible sets come from a sweep, which proves no maximum"
STATUSES = ("optimal", "unreachable", "no feasible branch", "solver failed")
METHODS = ("auto", "levelset", "search", "ipopt")
VIOLATION_SAMPLES = 720
"""Parameter samples per branch when looking for the least-violating branch."""
RETRIES = 2
"""Searches again (with samples 4x closer each time) when the certificate finds a better point."""


@dataclass
class BranchOptimum:
    """One branch's row of the table.

    Attributes:
        branch: public branch id.
        searched: whether it was searched (``branches`` of :func:`solve_best`).
        feasible: some δ/ψ of it keeps the joints in their limits (and clear of the obstacles).
        param: its best δ/ψ (rad; None if not feasible); objective: the value there (+inf if not feasible).
        q: (n,) its configuration, rad (None if not feasible).
        rounds: polish rounds (iterations) of its best local minimum.
        evaluations: objective evaluations spent on the branch.
        time: its share of the pose's solve time (by evaluations), s.
    """

    branch: int
    searched: bool
    feasible: bool
    param: float | None
    objective: float
    q: np.ndarray | None
    rounds: int = 0
    evaluations: int = 0
    time: float = 0.0


@dataclass(frozen=True, eq=False)
class BranchRows:
    """What one pose's per-branch table is built from: the best point found per searched row, f (R,) (+inf where
    none), ψ (R,), q (R, n), its rounds (R,) and the evaluations per row (R,); ``columns`` the table's branches, per
    branch (public id, its searched row, its shift (None: its own row), whether it was searched)."""

    columns: list[tuple[int, int, float | None, bool]]
    f: list[float]
    psi: list[float]
    q: np.ndarray
    rounds: list[int]
    counts: list[int]

    def table(self, time: float) -> list[BranchOptimum]:
        """The rows, a branch's time its share (by evaluations) of the pose's ``time`` (s); plain floats, which
        cost less than numpy's calls for one pose's few rows."""
        f, psi, q, counts = self.f, self.psi, self.q, self.counts
        per = time / max(sum(counts), 1)
        out = []
        for bid, r, shift, done in self.columns:
            ok = f[r] < math.inf
            param = (psi[r] if shift is None else float(wrap(psi[r] - shift))) if ok else None
            evals = counts[r] if shift is None else 0
            out.append(BranchOptimum(bid, done, ok, param, f[r], q[r] if ok else None,
                                     self.rounds[r] if shift is None else 0, evals, evals * per))  # fmt: skip
        return out


@dataclass
class BestResult:
    """The answer for one pose.

    Attributes:
        status: one of :data:`STATUSES`.
        branch: the best branch's public id (for another status, the branch of :func:`least_violating`'s
            configuration; -1 if unreachable).
        param: its δ/ψ, rad; q: (n,) its configuration, rad (always finite); objective: the minimised value at q
            (+inf for a status other than ``"optimal"``); :attr:`reported` is the quantity it measures (the margin
            itself for the margin objective, whose ``objective`` is −margin).
        certified: proved to be the global minimum to ``gap`` (:mod:`qpik.nlp.certificate`).
        gap: the objective minus the certified lower bound (inf when not certified).
        clearance: smallest capsule–obstacle distance at q, m (inf without obstacles).
        violation: 0 for ``"optimal"``; else how far q is from a solution: outside the limits (rad),
            inside d_s (m), or, when unreachable, the norm of its pose error (m and rad, :func:`least_violating`).
        branches: the per-branch table (:class:`BranchOptimum`), built when first read (from :attr:`rows`).
        param_name: ``"delta"`` or ``"psi"``.
        message: why it is not certified, or what failed ("" otherwise).
        method: what found the answer: ``"levelset"`` (then a row of :attr:`branches` other than the best
            holds the best point evaluated on its branch, not the branch's optimum), ``"search"`` or ``"ipopt"``.
        time: seconds of the solve, without building or compiling its functions (done before the clock starts;
            a batch: the solve's time divided by the number of poses).
        rows: what :attr:`branches` is built from (None: an empty table).
        quantity: how the objective is shown (:attr:`qpik.objectives.Objective.quantity`).
    """

    status: str
    branch: int
    param: float
    q: np.ndarray
    objective: float
    certified: bool = False
    gap: float = np.inf
    clearance: float = np.inf
    violation: float = 0.0
    param_name: str = "psi"
    message: str = ""
    time: float = 0.0
    method: str = "search"
    rows: BranchRows | None = field(default=None, repr=False)
    quantity: Quantity = field(default_factory=lambda: Quantity("objective"), repr=False)

    @property
    def reported(self) -> float:
        """The objective as the quantity it measures (:attr:`quantity`): the margin (not −margin), the clearance (m),
        the manipulability (not −log m), or the minimised value itself."""
        return self.quantity.value(self.objective)

    @cached_property
    def branches(self) -> list[BranchOptimum]:
        """The per-branch table (:class:`BranchOptimum`; each branch's time its share of :attr:`time`)."""
        return [] if self.rows is None else self.rows.table(self.time)

    def table(self) -> str:
        """The per-branch table as text: the parameter (rad), the objective as its :attr:`quantity` (the margin
        itself, ...), polish rounds, evaluations and each branch's share of the solve's time (µs)."""
        sym = {"delta": "δ", "psi": "ψ"}.get(self.param_name, self.param_name)
        head = self.quantity.header
        w = max(13, len(head))
        lines = [
            f"{'branch':>6} {'feasible':>8} {sym + '* [rad]':>11} {head:>{w}}"
            f" {'rounds':>6} {'evals':>6} {'time [µs]':>9}"
        ]
        for r in self.branches:
            mark = " *" if r.branch == self.branch and self.status == "optimal" else ""
            shown = self.quantity.value(r.objective)
            val = f"{r.param:11.6f} {shown:{w}.8g}" if r.feasible else f"{'—':>11} {'—':>{w}}"
            feasible = ("yes" if r.feasible else "no") if r.searched else "skipped"
            lines.append(
                f"{r.branch:>6} {feasible:>8} {val} {r.rounds:>6} {r.evaluations:>6} {r.time * 1e6:9.1f}{mark}"
            )
        if self.method == "levelset":
            lines.append("(level sets: a row other than the best holds the best point evaluated on its branch)")
        return "\n".join(lines)

    def summary(self) -> str:
        """One line: status, branch, parameter, objective, certificate."""
        sym = {"delta": "δ", "psi": "ψ"}.get(self.param_name, self.param_name)
        if self.status == "unreachable":
            return "unreachable: no branch reaches the pose"
        if self.status == "no feasible branch":
            return (
                f"no feasible branch: least violating is branch {self.branch} at {sym} = {self.param:.6f} rad"
                f" (violation {self.violation:.3g})"
            )
        if self.status != "optimal":
            return f"{self.status}: {self.message}"
        cert = f"certified (gap {self.gap:.2g})" if self.certified else f"not certified ({self.message})"
        value = self.quantity.text(self.objective, ".10g")
        return f"best: branch {self.branch}, {sym} = {self.param:.6f} rad, {value}, {self.quantity.sense}, {cert}"


class BestResults:
    """Answers for a batch of poses: ``results[i]`` is a :class:`BestResult`; the arrays stack them."""

    def __init__(self, results: list[BestResult], n: int):
        self.results, self.n = results, n

    def __len__(self) -> int:
        return len(self.results)

    def __getitem__(self, i: int) -> BestResult:
        return self.results[i]

    def __iter__(self):
        return iter(self.results)

    @property
    def status(self) -> np.ndarray:
        return np.array([r.status for r in self.results])

    @property
    def q(self) -> np.ndarray:
        """(N, n), rad."""
        return np.array([r.q for r in self.results]).reshape(len(self.results), self.n)

    @property
    def objective(self) -> np.ndarray:
        """(N,) the minimised values."""
        return np.array([r.objective for r in self.results])

    @property
    def reported(self) -> np.ndarray:
        """(N,) the objectives as the quantities they measure (:attr:`BestResult.reported`)."""
        return np.array([r.reported for r in self.results])

    @property
    def param(self) -> np.ndarray:
        return np.array([r.param for r in self.results])

    @property
    def branch(self) -> np.ndarray:
        return np.array([r.branch for r in self.results])

    @property
    def certified(self) -> np.ndarray:
        return np.array([r.certified for r in self.results])


def solve_best(
    robot: Robot | Scene,
    pose: np.ndarray,
    objective: Objective | str | None = None,
    obstacles=None,
    q_ref: np.ndarray | None = None,
    project: bool = False,
    *,
    d_safe: float | None = None,
    options: BestOptions | None = None,
) -> BestResult | BestResults:
    """The best branch and δ/ψ for ``pose`` under ``objective``; see the module docstring.

    Args:
        robot: an arm with a closed form (``nammoto7``: δ, ``iiwa14``: ψ), or a :class:`~qpik.scene.Scene` of one
            (then ``objective``, ``obstacles``, ``d_safe`` and a single ``q_ref`` are the scene's).
        pose: end-effector pose (4, 4) in the base frame, or a batch (N, 4, 4).
        objective: an :class:`~qpik.objectives.Objective` or a name of
            :func:`qpik.objectives.resolve` (``"margin"``, ``"manipulability"``, ...); default: the margin.
        obstacles: shapes of :mod:`qpik.geometry` (base frame): the constraint
            clearance ≥ ``d_safe`` for every link capsule, and the pairs of a clearance objective.
        q_ref: (n,) or (N, n) reference configuration, rad (the ``"distance"`` objective's).
        project: project a non-orthonormal rotation onto SO(3) instead of raising.
        d_safe: the clearance constraint's distance, m (≥ 0; default 0.02).
        options: the certificate, its tolerance, the method and the branches searched
            (:class:`~qpik.nlp.options.BestOptions`; default its defaults).

    Returns:
        A :class:`BestResult`, or :class:`BestResults` for a batch.

    Raises:
        NoClosedFormError: the robot has no closed form (use :func:`qpik.nlp.solve_full`).
        InputError: NaN/inf or wrong shapes (the message names the argument), unknown objective
            or method.
    """
    options = BestOptions() if options is None else options
    if not isinstance(options, BestOptions):
        raise InputError(f"options: expected BestOptions, got {type(options).__name__}")
    certify, tol, method, branches = options.certify, options.tol, options.method, options.branches
    per_pose = q_ref is not None and np.ndim(q_ref) == 2
    problem = scene_of(robot, obstacles, d_safe, objective, None if per_pose else q_ref).with_objective("margin")
    robot, obj, obs, d_safe = problem.robot, problem.objective, problem.obstacles, problem.d_safe
    q_ref = q_ref if per_pose else problem.q_ref
    if robot.closed_form is None:
        raise NoClosedFormError(
            f"{robot.name} has no closed-form IK, so no δ/ψ to search; use qpik.nlp.solve_full (7 joint variables)"
        )
    T, batched = check_pose(pose, "pose", project)
    T = T if batched else T[None]
    n = robot.dof
    if q_ref is None:
        ref = np.zeros((len(T), n))
    else:
        ref = finite_array(q_ref, "q_ref")
        if ref.shape not in ((n,), (len(T), n)):
            raise InputError(f"q_ref: expected shape ({n},) or ({len(T)}, {n}), got {ref.shape}")
        ref = np.broadcast_to(ref, (len(T), n)).copy()
    obj.params(robot)  # checks the parameters against the robot (e.g. a weight per joint)
    if q_ref is None and any(isinstance(o, ReferenceDistance) for _, o in obj.terms):
        raise InputError("q_ref: the distance objective needs a reference configuration q_ref")
    tol = number(tol, "tol")
    if tol <= 0:
        raise InputError(f"tol: must be > 0, got {tol}")
    certify = flag(certify, "certify")
    if not isinstance(method, str) or method not in METHODS:
        raise InputError(f"method: expected one of {list(METHODS)}, got {method!r}")
    sm = selfmotion_of(robot)
    weight = margin_weight(obj, obs, sm)
    if method == "levelset" and weight is None:
        raise InputError("method: 'levelset' solves the margin objective alone, without obstacles")
    if method == "auto":
        method = "search" if weight is None else "levelset"
    rows = _rows(sm, branches)
    if not len(T):
        return BestResults([], n)
    with sm.solver.lock:  # the arm's compiled functions evaluate in buffers of their own: one thread at a time
        scene = BestRun(problem, sm, T, ref)
        try:
            results = _solve(scene, certify, tol, method, rows, weight)
        except (RuntimeError, FloatingPointError, np.linalg.LinAlgError) as exc:  # a numerical failure: a status
            why = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
            results = [least_violating(scene, i, None, "solver failed", why) for i in range(len(T))]
    elapsed = scene.watch.stop() / len(T)  # the clock stops while functions are built (BestRun.build_search)
    quantity = obj.quantity
    for r, Tk in zip(results, T):
        _verify(robot, Tk, r, obs, d_safe)
    for r in results:
        r.time, r.quantity = elapsed, quantity
    return BestResults(results, n) if batched else results[0]


def _verify(robot: Robot, T: np.ndarray, r: BestResult, obstacles: ObstacleSet, d_safe: float) -> None:
    """An ``"optimal"`` result is measured at its q: FK reaches T (:data:`VERIFY_TOL`), every joint inside its
    limits, clearance ≥ d_safe over the pairs :mod:`qpik.geometry.contacts` checks; one that fails becomes
    ``"solver failed"`` naming the check."""
    if r.status != "optimal":
        return
    from qpik.algebra.lie import tracking_errors
    from qpik.geometry.contacts import capsule_clearance

    pos, rot = tracking_errors(robot.fk(r.q), T)
    fails = []
    if not (pos <= VERIFY_TOL and rot <= VERIFY_TOL):
        fails.append(f"FK misses the pose by {float(pos):.2e} m, {float(rot):.2e} rad")
    if np.any(r.q < robot.q_min) or np.any(r.q > robot.q_max):
        fails.append("a joint is outside its limits")
    if len(obstacles) and float(capsule_clearance(robot, r.q[None], obstacles)[0]) < d_safe - 1e-9:
        fails.append(f"clearance below d_s = {d_safe:g} m")
    if fails:
        r.status, r.objective, r.certified, r.gap = "solver failed", math.inf, False, math.inf
        r.message = "the answer fails its check: " + "; ".join(fails)


def _rows(sm, branches) -> list[int]:
    """The searched rows of the closed form for the public ids ``branches`` (None: all)."""
    all_rows = list(range(sm.searched))
    if branches is None:
        return all_rows
    try:
        ids = [operator.index(b) for b in np.atleast_1d(np.asarray(branches, dtype=object)).ravel()]
    except TypeError:
        raise InputError(f"branches: expected branch ids (integers), got {branches!r}"[:200]) from None
    known = sm.branch_ids.tolist()
    bad = [b for b in ids if b not in known]
    if bad:
        raise InputError(f"branches: unknown branch id(s) {bad}; the branches are {known}")
    rows = set()
    for b in ids:
        k = known.index(b)
        m = sm.mirror(k)
        rows.add(k if m is None else m[0])
    return sorted(rows)


def _solve(
    scene: BestRun, certify: bool, tol: float, method: str, rows: list[int], weight: float | None
) -> list[BestResult]:
    sm = scene.selfmotion
    N, B = len(scene.poses), sm.searched
    certify = certify and sm.solver.sets_proved  # a certificate over unproved sets would prove nothing
    if method == "levelset":
        sets = maximise(scene, rows, weight)
        scene.counts += sets.evaluations
        f = -weight * sets.mu  # +inf where a row has no point
        if sets.certified.all():  # the common case: every answer comes straight from the rounds
            found = _BestSoFar(f, sets.psi, sets.q, sets.rounds, np.full(f.shape, np.inf))
            return _answers(scene, found, rows, sets.certified, sets.bound, [""] * N, ["levelset"] * N)
    best = _BestSoFar.empty(N, B, scene.robot.dof)
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
    pieces = _feasible_pieces(fis, rows, left)
    if method == "ipopt":
        from qpik.nlp.ipopt import solve_pieces

        best.update(*solve_pieces(scene, pieces))
    elif len(pieces):
        best.update_from(*_search(scene, pieces, SAMPLE_STEP))
    todo = np.flatnonzero(best.found() & certify & ~cert_ok)
    for attempt in range(RETRIES + 1):
        if not len(todo):
            break
        value = best.pose_value()
        top = np.argmin(best.f, axis=1)
        focus = top, best.psi[np.arange(len(top)), top]
        cert = prove(scene, pieces, value, tol * np.maximum(1.0, np.abs(value)), todo, focus)
        for i in todo:
            cert_ok[i], bound[i], reason[i] = cert.certified[i], cert.bound[i], cert.reason[i]
        if cert.better is None or attempt == RETRIES:
            break
        redo = np.unique(cert.better.pose)
        sub = pieces.take(np.isin(pieces.pose, redo))
        best.update_from(*_search(scene, sub, SAMPLE_STEP / 4 ** (attempt + 1), extra=cert.better))
        todo = redo
    methods = ["levelset" if done else method for done in by_levels.tolist()]
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
class _BestSoFar:
    """Per (pose, branch row): the best feasible point found so far, f (N, B) (+inf where none), ψ (N, B), q (N, B,
    n), the polish rounds (N, B) and the clearance (N, B)."""

    f: np.ndarray
    psi: np.ndarray
    q: np.ndarray
    rounds: np.ndarray
    clearance: np.ndarray

    @classmethod
    def empty(cls, N: int, B: int, n: int) -> _BestSoFar:
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
    best: _BestSoFar,
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
        if value == math.inf:
            result = least_violating(scene, i, rows)
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


def least_violating(
    scene: BestRun, i: int, rows: BranchRows | None, status: str | None = None, message: str = ""
) -> BestResult:
    """The answer for pose i when the search has none: unreachable, or the least-violating configuration.

    Every branch's closed form (numpy, :meth:`~qpik.analytic.solver.AnalyticSolver.solve_batch`) at
    :data:`VIOLATION_SAMPLES` parameters. If no branch reaches the pose, the status is
    ``"unreachable"`` and q is the configuration (the closed form clamps what it cannot reach) whose
    pose error (:func:`qpik.algebra.lie.pose_error`) has the smallest norm, its norm the violation. Otherwise
    ``"no feasible branch"``: inside the limits but never clear of the obstacles, the configuration
    with the largest clearance (violation d_s minus it, m); else the one least outside the limits
    (rad). ``status`` replaces the status (a solver failure keeps this configuration as its q).
    The objective is +inf.
    """
    robot, sm = scene.robot, scene.selfmotion
    name = sm.solver.param_name
    psi = np.linspace(-np.pi, np.pi, VIOLATION_SAMPLES, endpoint=False)
    T = scene.poses[i]
    sol = sm.solver.solve_batch(np.broadcast_to(T, (len(psi), 4, 4)), psi)
    if not sol.valid.any():
        k, b, err = _closest(robot, T, sol.q)
        why = message or "no branch reaches the pose at any parameter"
        return BestResult(status or "unreachable", -1, float(psi[k]), sol.q[k, b].copy(), np.inf, violation=err,
                          rows=rows, param_name=name, message=why)  # fmt: skip
    beyond = np.maximum(robot.q_min - sol.q, sol.q - robot.q_max).max(axis=2)  # (M, B) rad outside the limits
    within = sol.within_limits
    if within.any() and len(scene.obstacles):
        # inside the limits but never clear: the configuration with the largest clearance
        k, b = np.nonzero(within)
        Q = sol.q[k, b]
        clear = clearance(robot, Q, scene.obstacles)  # the pairs of fixed capsules constrain nothing
        j = int(np.argmax(clear))
        violation = max(float(scene.d_safe - clear[j]), 0.0)
        at, br, q = psi[k[j]], b[j], Q[j]
    else:
        score = np.where(sol.valid, np.maximum(beyond, 0.0), np.inf)
        k, br = np.unravel_index(int(np.argmin(score)), score.shape)
        violation, at, q = float(score[k, br]), psi[k], sol.q[k, br]
    why = "no branch keeps the joints in their limits" + (" and clear of the obstacles" if len(scene.obstacles) else "")
    return BestResult(status or "no feasible branch", int(sm.branch_ids[br]), float(wrap(at)), q.copy(), np.inf,
                      violation=violation, rows=rows, param_name=name, message=message or why)  # fmt: skip


def _closest(robot: Robot, target: np.ndarray, Q: np.ndarray, stride: int = 8) -> tuple[int, int, float]:
    """The sample k and branch b of configurations Q (M, B, n) whose pose is closest to ``target`` (4, 4), and its
    error (:func:`_pose_error_norm`): every ``stride``-th sample of every branch first, then every sample within
    ``stride`` of the closest one on its branch."""
    M, B, n = Q.shape
    coarse = np.ascontiguousarray(Q[::stride]).reshape(-1, n)
    k, b = divmod(int(np.argmin(_pose_error_norm(target, robot.fk(coarse)))), B)
    near = (k * stride + np.arange(-stride, stride + 1)) % M
    err = _pose_error_norm(target, robot.fk(np.ascontiguousarray(Q[near, b])))
    j = int(np.argmin(err))
    return int(near[j]), b, float(err[j])


def _pose_error_norm(target: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(M,): ‖[p* − p; log(R* Rᵀ)]‖ of poses (M, 4, 4) toward ``target`` (4, 4): √(|Δp|² + θ²), θ the angle of R* Rᵀ."""
    dp = poses[:, :3, 3] - target[:3, 3]
    cos = 0.5 * (np.einsum("ij,mij->m", target[:3, :3], poses[:, :3, :3]) - 1.0)
    return np.sqrt((dp * dp).sum(axis=1) + np.arccos(np.clip(cos, -1.0, 1.0)) ** 2)
