r"""``qpik.solve_best``: the globally best branch and δ/ψ of a closed-form arm for a pose.

Minimises an objective (:mod:`qpik.objectives`) over every branch and every δ (offset
shoulder) or ψ (S-R-S) that keeps the joints inside their limits (the exact
:func:`qpik.feasible_intervals`), every link capsule at least ``d_safe`` from every obstacle and, with the
scene's ``self_collision``, the capsules of every checked pair (:attr:`~qpik.scene.Scene.self_pairs`) at least
``d_safe`` apart.
The variable is the one parameter; q is the branch's closed form, traced in CasADi with exact
derivatives (:mod:`qpik.nlp.selfmotion`). Every feasible interval of every branch is searched
(:mod:`qpik.nlp.search`: sampling, then a bracketed polish of the local minima; or, with
``method="ipopt"``, IPOPT from the middle of each interval, :mod:`qpik.nlp.ipopt`), and the
answer is checked for global optimality (:mod:`qpik.nlp.certificate`). The plain joint-limit
margin without obstacles has a faster exact method, which finds and proves its maximum with the
feasible intervals under shrunk limits (:mod:`qpik.nlp.levelset`); a pose it leaves unproved goes
through the search and the certificate. In its per-branch table a branch's row holds the best point
evaluated on that branch, which is the branch's own optimum only for the best branch.

Self-collision (on by default, :meth:`Scene.of <qpik.scene.Scene.of>`'s ``self_collision``) is solved in two
passes. The poses are first solved without the capsule pairs, by the methods above (the level sets included,
which do not see them); an optimal answer whose pairs are all ≥ d_safe apart is kept as it is: adding a constraint
that it meets can only remove points, none better, so it stays optimal and its certificate stands
(:attr:`~qpik.nlp.best_result.BestResult.self_collision` ``"clear"``; a row of its table whose point comes closer
says so). Every other pose is solved again with the pairs as constraints, by the search (or IPOPT when asked),
``"re-solved"``.

Statuses: ``"optimal"`` (the best point found; :attr:`~qpik.nlp.best_result.BestResult.certified`
says whether it is proved global), ``"unreachable"`` (no configuration inside the limits reaches the pose, proved
by empty feasible sets, and no branch reaches it at any of 720 sampled parameters, limits aside),
``"no feasible branch"`` (reachable, but not inside the limits and clear of the obstacles and of itself: proved,
by empty feasible sets or by the certificate cutting off every feasible interval by its clearances),
``"not found"`` (no feasible point found, and nothing proved: the feasible sets are not proved, the certificate
could not prove the absence or was not asked for, or the arm's slots are found per pose, :mod:`qpik.nlp.best_sampled`),
``"solver failed"`` (a numerical failure, or an answer that fails its own check at q: FK, limits,
clearance, self-clearance; the reason in :attr:`~qpik.nlp.best_result.BestResult.message`).
Every result's q is a finite configuration: for a status other than ``"optimal"`` it is the
fallback of :func:`~qpik.nlp.least_violating.least_violating` (its objective is +inf,
:attr:`~qpik.nlp.best_result.BestResult.violation` says how
far it is from a solution). Outputs never hold NaN.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from dataclasses import replace
from functools import partial

import numpy as np

from qpik.analytic.api import closed_form_for
from qpik.core.errors import InputError, NoClosedFormError
from qpik.core.stopwatch import Stopwatch
from qpik.core.validate import finite_array, flag, number
from qpik.core.validate import pose as check_pose
from qpik.nlp.best_result import BestResult, BestResults
from qpik.nlp.best_sampled import solve_sampled
from qpik.nlp.best_search import solve_poses
from qpik.nlp.full import full_nlp
from qpik.nlp.least_violating import build_sweep, least_violating
from qpik.nlp.levelset import margin_weight
from qpik.nlp.options import BestOptions
from qpik.nlp.run import BestRun
from qpik.nlp.selfmotion import selfmotion_of
from qpik.objectives import Objective, ReferenceDistance
from qpik.robots.robot import Robot
from qpik.scene.scene import Scene, scene_of

VERIFY_TOL = 1e-9
"""m and rad: an ``"optimal"`` answer's FK reaches the pose to this (:func:`_verify`)."""


METHODS = ("auto", "levelset", "search", "ipopt")


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
        robot: an arm with a closed form (``nammoto7``: δ, ``iiwa14``: ψ, ``panda``: q7, ...) or whose branches the
            1-D search or the general 6-R finds (the Sawyer, Baxter, YuMi: sampled along the locked joint, never
            certified, :mod:`qpik.nlp.best_sampled`), or a :class:`~qpik.scene.Scene` of one (then ``objective``,
            ``obstacles``, ``d_safe`` and a single ``q_ref`` are the scene's).
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
        A :class:`~qpik.nlp.best_result.BestResult`, or :class:`~qpik.nlp.best_result.BestResults` for a batch.

    Raises:
        NoClosedFormError: the robot has neither a closed form nor the 1-D search (use :func:`qpik.nlp.solve_full`).
        InputError: NaN/inf or wrong shapes (the message names the argument), unknown objective
            or method.
    """
    options = BestOptions() if options is None else options
    if not isinstance(options, BestOptions):
        raise InputError(f"options: expected BestOptions, got {type(options).__name__}")
    certify, tol, method, branches = options.certify, options.tol, options.method, options.branches
    per_pose = q_ref is not None and np.ndim(q_ref) == 2
    problem = scene_of(robot, obstacles, d_safe, objective, None if per_pose else q_ref).with_objective("margin")
    robot, obj, obs = problem.robot, problem.objective, problem.obstacles
    q_ref = q_ref if per_pose else problem.q_ref
    if robot.closed_form is None:
        raise NoClosedFormError(f"{robot.name} has no closed-form IK, so no parameter to search; use "
                                "qpik.nlp.solve_full (7 joint variables)")  # fmt: skip
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
    if not robot.branch_functions:  # the 1-D search's slots: sampled along the locked joint
        if method == "levelset":
            raise InputError("method: 'levelset' needs branches in closed form; this arm's are found per pose")
        results = solve_sampled(problem, T, ref, _ids(branches, list(closed_form_for(robot).branch_ids)))
        for r, Tk in zip(results, T):
            _verify(problem, Tk, r)
            r.quantity = obj.quantity
        return BestResults(results, n) if batched else results[0]
    sm = selfmotion_of(robot)
    weight = margin_weight(obj, obs, sm)
    if method == "levelset" and weight is None:
        raise InputError("method: 'levelset' solves the margin objective alone, without obstacles")
    if method == "auto":
        method = "levelset" if weight is not None and sm.solver.closed_form_sets else "search"
    rows = _rows(sm, branches)
    if not len(T):
        return BestResults([], n)
    with sm.solver.lock:  # the arm's compiled functions evaluate in buffers of their own: one thread at a time
        run = BestRun(problem.replace(self_collision=False) if problem.self_pairs else problem, sm, T, ref)
        results = _solve(run, certify, tol, method, rows, weight)
        elapsed = run.watch.stop()  # the clock stops while functions are built (BestRun.build_search)
        if problem.self_pairs:
            again = "search" if method == "levelset" else method
            elapsed += _self_pass(problem, results, run, partial(_solve, certify=certify, tol=tol, method=again,
                                                                 rows=rows, weight=None))  # fmt: skip
    elapsed /= len(T)
    quantity = obj.quantity
    for r, Tk in zip(results, T):
        _verify(problem, Tk, r)
    for r in results:
        r.time, r.quantity = elapsed, quantity
    return BestResults(results, n) if batched else results[0]


def build_search(
    robot: Robot,
    pose: np.ndarray,
    objective: Objective | str | None = None,
    obstacles=None,
    q_ref: np.ndarray | None = None,
    *,
    d_safe: float | None = None,
) -> None:
    """Trace and compile now what :func:`solve_best`'s search may call for this scene (arguments as there; ``pose``
    (4, 4), base frame, is where the feasible sets are first evaluated): the functions of the pass without the
    capsule pairs and, with self-collision, those of the pass with them and the pairs' distances, and the sweep of
    the answer for a pose without a feasible point (:func:`~qpik.nlp.least_violating.build_sweep`). A call of
    :func:`solve_best` builds only what it uses, so without this the first pose that needs the other pass (one the
    level sets do not settle, or whose answer comes too close to itself) would build it inside its call."""
    problem = scene_of(robot, obstacles, d_safe, objective, q_ref).with_objective("margin")
    if problem.robot.closed_form is None:
        raise NoClosedFormError(f"{problem.robot.name} has no closed-form IK, so no parameter to search")
    T = check_pose(pose, "pose")[0]
    if T.ndim != 2:
        raise InputError(f"pose: expected one pose (4, 4), got shape {T.shape}")
    if not problem.robot.branch_functions:  # the 1-D search's arms: the objective's values and the full-joint NLP
        problem.evaluator.build()
        full_nlp(problem.robot, problem.objective, problem.obstacles, problem.self_pairs)
        return
    ref = np.zeros((1, problem.robot.dof)) if problem.q_ref is None else finite_array(problem.q_ref, "q_ref")[None]
    sm = selfmotion_of(problem.robot)
    scenes = [problem.replace(self_collision=False)] + ([problem] if problem.self_pairs else [])
    with sm.solver.lock:
        for scene in scenes:
            BestRun(scene, sm, T[None], ref).build_search()
        build_sweep(sm.solver, T)
        if problem.self_pairs:
            problem.self_distances.build()


def _solve(
    run: BestRun, certify: bool, tol: float, method: str, rows: list[int], weight: float | None
) -> list[BestResult]:
    """The results of :func:`~qpik.nlp.best_search.solve_poses` for the poses of ``run``, a numerical failure
    ``"solver failed"`` for each."""
    try:
        return solve_poses(run, certify, tol, method, rows, weight)
    except (RuntimeError, FloatingPointError, np.linalg.LinAlgError) as exc:  # a numerical failure: a status
        why = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
        return [least_violating(run, i, None, "solver failed", why) for i in range(len(run.poses))]


def _self_pass(
    scene: Scene, results: list[BestResult], first: BestRun, solve: Callable[[BestRun], list[BestResult]]
) -> float:
    """The second pass of self-collision (module docstring) over ``results``, solved by ``first`` without the
    capsule pairs of ``scene``: the optimal answers whose pairs are ≥ d_safe apart are kept (their clearance and
    their table's rows measured), the other poses solved again by ``solve`` with the pairs and replaced. Returns its
    seconds (compiles not counted)."""
    watch = Stopwatch()
    with watch.paused():
        scene.self_distances.build()
    sm = first.selfmotion
    kept = [i for i, r in enumerate(results) if r.status == "optimal"]
    Q = np.concatenate([results[i].rows.q for i in kept]) if kept else np.zeros((0, sm.robot.dof))
    d = scene.self_clearance(Q).reshape(len(kept), sm.searched)
    redo = np.ones(len(results), bool)
    for i, d_rows in zip(kept, d):
        r = results[i]
        best = r.rows.f.index(min(r.rows.f))
        if d_rows[best] >= scene.d_safe:
            r.self_collision, r.clearance, redo[i] = "clear", min(r.clearance, float(d_rows[best])), False
            r.rows = replace(r.rows, collides=[f < math.inf and di < scene.d_safe for f, di in zip(r.rows.f, d_rows)])
    seconds = watch.stop()
    if redo.any():
        run = BestRun(scene, sm, first.poses[redo], first.q_ref[redo])
        run.counts += first.counts[redo]  # a branch's evaluations: both passes'
        for i, r in zip(np.flatnonzero(redo).tolist(), solve(run)):
            r.self_collision, results[i] = "re-solved", r
        seconds += run.watch.stop()
    return seconds


def _verify(scene: Scene, T: np.ndarray, r: BestResult) -> None:
    """An ``"optimal"`` result is measured at its q: FK reaches T (:data:`VERIFY_TOL`), every joint inside its
    limits, clearance ≥ d_safe over the pairs :mod:`qpik.geometry.contacts` checks and over the scene's capsule
    pairs (:meth:`~qpik.scene.Scene.self_clearance`); one that fails becomes ``"solver failed"`` naming the check."""
    if r.status != "optimal":
        return
    from qpik.algebra.lie import tracking_errors
    from qpik.geometry.contacts import capsule_clearance

    robot, obstacles, d_safe = scene.robot, scene.obstacles, scene.d_safe
    pos, rot = tracking_errors(robot.fk(r.q), T)
    fails = []
    if not (pos <= VERIFY_TOL and rot <= VERIFY_TOL):
        fails.append(f"FK misses the pose by {float(pos):.2e} m, {float(rot):.2e} rad")
    if np.any(r.q < robot.q_min) or np.any(r.q > robot.q_max):
        fails.append("a joint is outside its limits")
    if len(obstacles) and float(capsule_clearance(robot, r.q[None], obstacles)[0]) < d_safe - 1e-9:
        fails.append(f"clearance below d_s = {d_safe:g} m")
    if float(scene.self_clearance(r.q[None])[0]) < d_safe - 1e-9:
        fails.append(f"self-clearance below d_s = {d_safe:g} m")
    if fails:
        r.status, r.objective, r.certified, r.gap = "solver failed", math.inf, False, math.inf
        r.message = "the answer fails its check: " + "; ".join(fails)


def _ids(branches, known: list[int]) -> list[int]:
    """The public ids ``branches`` checked against the arm's ``known`` ones (None: all of them)."""
    if branches is None:
        return known
    try:
        ids = [operator.index(b) for b in np.atleast_1d(np.asarray(branches, dtype=object)).ravel()]
    except TypeError:
        raise InputError(f"branches: expected branch ids (integers), got {branches!r}"[:200]) from None
    bad = [b for b in ids if b not in known]
    if bad:
        raise InputError(f"branches: unknown branch id(s) {bad}; the branches are {known}")
    return ids


def _rows(sm, branches) -> list[int]:
    """The searched rows of the closed form for the public ids ``branches`` (None: all)."""
    if branches is None:
        return list(range(sm.searched))
    known = sm.branch_ids.tolist()
    ids = _ids(branches, known)
    rows = set()
    for b in ids:
        k = known.index(b)
        m = sm.mirror(k)
        rows.add(k if m is None else m[0])
    return sorted(rows)
