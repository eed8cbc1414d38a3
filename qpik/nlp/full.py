r"""The full-joint NLP: minimise an objective over the 7 joints with the pose as an equality.

.. math::

    \min_{q,\ t}\ s(q) + \sum_k w_k t_k \quad\text{s.t.}\quad
    \begin{bmatrix} p^* - p(q) \\ \log(R^* R(q)^T) \end{bmatrix} = 0,\quad
    h_{k,i}(q) \le t_k,\quad d_{c,o}(q) \ge d_s,\quad q_{min} \le q \le q_{max}

(the objective's split in epigraph form, :class:`qpik.objectives.Split`; the world-frame pose
error :func:`qpik.algebra.lie.pose_error_expr`, differentiable at its solution; the capsule–obstacle distances of
:mod:`qpik.geometry.distance` and, with the scene's self-collision, the capsule pairs' distances), solved by IPOPT
(``casadi.nlpsol``, exact derivatives). It works for every arm, with or without a closed form. ``objective=None``
is a pure IK (the feasibility problem).

A local method: :func:`solve_full` starts it from several configurations — ``q0`` (given),
then, for an arm with a closed form, the within-limits branches of the pose at the middle of
each branch's feasible interval (:func:`qpik.feasible_intervals`, one start per branch; for an arm whose branches
are found by a search, :func:`qpik.ik`'s within-limits branches at a few values of its parameter),
then configurations drawn uniformly inside the limits from a generator seeded with ``seed`` —
and keeps the best start that reaches the pose (pure IK: the first). Its KKT residual
(:attr:`FullResult.kkt`) is the ∞-norm of the Lagrangian's gradient and of the constraint
violation at the answer, with IPOPT's multipliers.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.algebra.lie import pose_error, pose_error_expr
from qpik.core.errors import InputError
from qpik.core.validate import count, joint_vector
from qpik.core.validate import pose as check_pose
from qpik.geometry.distance import ObstacleSet
from qpik.nlp.options import FullOptions
from qpik.objectives import Context, Objective, ReferenceDistance
from qpik.robots.robot import Robot
from qpik.robots.self_pairs import Pair
from qpik.scene.scene import Scene, scene_of

REACHED = 1e-9
"""A configuration reaches the pose when ‖[p* − p; log(R* Rᵀ)]‖ (m and rad together) is below this."""
OPTIONS = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": 1e-12,
    "ipopt.constr_viol_tol": 1e-12,
    "ipopt.max_iter": 300,
    "show_eval_warnings": False,
    "calc_lam_p": False,
}
"""IPOPT options of the full-joint NLP."""
SEARCHED = np.pi * np.array([0.0, 1.0, 0.5, -0.5, 0.25, -0.75, 0.75, -0.25])
"""rad: the parameter values whose branches start :func:`solve_full` on an arm whose branches are found by a search
(no expressions of the parameter, no feasible sets): spread over the circle, the widest gaps first."""


@dataclass
class FullResult:
    """The answer of :func:`solve_full`.

    Attributes:
        status: ``"optimal"`` (reached the pose, inside the limits and clear of the obstacles, checked at q;
            with an objective, the best start's local minimum), ``"unreachable"`` (proved: an arm with a
            closed form whose exact feasible set at the pose is empty), ``"not found"`` (no start reached it;
            nothing proved), ``"solver failed"`` (IPOPT failed from every start; the reason in ``message``).
        q: (n,) configuration, rad (the start's end point with the smallest pose error if not reached;
            the first start, clipped into the limits, if the solver failed).
        objective: the objective at q (0 for a pure IK; +inf if the solver failed).
        pose_error: ‖[p* − p; log(R* Rᵀ)]‖ at q, m and rad together.
        kkt: the KKT residual at q (∞-norm of ∇L and of the constraint violation).
        clearance: smallest clearance at q, m: capsule–obstacle distances and the distances of the scene's capsule
            pairs (:attr:`~qpik.scene.Scene.self_pairs`); inf without either.
        starts: starts tried; iterations: IPOPT iterations over all of them.
        time: seconds of the starts' solves (building the NLP and its IPOPT solver not counted).
    """

    status: str
    q: np.ndarray
    objective: float
    pose_error: float
    kkt: float
    clearance: float
    starts: int
    iterations: int
    time: float = 0.0
    message: str = ""


class FullNLP:
    """The compiled full-joint NLP of one robot, objective form, obstacle families and capsule pairs kept apart
    (built once, cached)."""

    def __init__(self, robot: Robot, objective: Objective | None, obstacles: ObstacleSet,
                 self_pairs: tuple[Pair, ...] = ()):  # fmt: skip
        self.robot, self.objective, self.obstacles = robot, objective, obstacles
        self.lock = threading.Lock()
        """Held around each solve (:func:`solve_full`): threads may share the NLP, one solve at a time."""
        n = robot.dof
        self.params = np.zeros(0) if objective is None else objective.params(robot)
        T = ca.SX.sym("T", 4, 4)
        q, q_ref = ca.SX.sym("q", n), ca.SX.sym("q_ref", n)
        p_obj = ca.SX.sym("p", len(self.params))
        prm, d_s = ca.SX.sym("obstacles", len(obstacles.params)), ca.SX.sym("d_safe")
        ctx = Context(robot, q, q_ref, obstacles, prm, self_pairs=self_pairs)
        if objective is None:
            t, cost, g_epi = ca.SX(0, 1), ca.SX(0.0), ca.SX(0, 1)
            value = ca.SX(0.0)
        else:
            split = objective.split(ctx, p_obj)
            t, cost, g_epi = split.epigraph()
            value = split.value()
        R, pos = ctx.frames[-1]
        err = pose_error_expr(T, ca.horzcat(ca.vertcat(*[ca.horzcat(*R[i]) for i in range(3)]), ca.vertcat(*pos)))
        x = ca.vertcat(q, t)
        g = ca.vertcat(err, g_epi, d_s - ctx.clearances)
        p = ca.vertcat(ca.vec(T), p_obj, q_ref, prm, d_s)
        self.n_eq, self.n_t = 6, t.numel()
        self.solver = ca.nlpsol(f"full_{robot.identifier}", "ipopt", {"x": x, "f": cost, "g": g, "p": p}, OPTIONS)
        lam_g, lam_x = ca.SX.sym("lam_g", g.numel()), ca.SX.sym("lam_x", x.numel())
        grad = ca.gradient(cost + ca.dot(lam_g, g), x) + lam_x
        self.kkt_terms = ca.Function("kkt", [x, p, lam_g, lam_x], [grad, g])
        clear = ctx.clearances
        self.value = ca.Function("value", [q, p], [value, ca.mmin(clear) if clear.numel() else ca.inf])
        self.start_t = (
            ca.Function("start_t", [q, p], [ca.vertcat(*[ca.mmax(h) for _, h in split.maxima], ca.SX(0, 1))])
            if objective is not None
            else None
        )

    def parameters(self, T: np.ndarray, q_ref: np.ndarray, d_safe: float, objective: Objective | None,
                   obstacles: ObstacleSet) -> np.ndarray:  # fmt: skip
        """The NLP's parameter vector: the pose ``T`` (4, 4), the parameters of ``objective`` (of this NLP's form), the
        reference ``q_ref`` (n,) rad, the geometry of ``obstacles`` (of this NLP's families) and ``d_safe`` (m)."""
        weights = np.zeros(0) if objective is None else objective.params(self.robot)
        return np.concatenate([np.asarray(T, float).T.ravel(), weights, q_ref, obstacles.params, [d_safe]])


def full_nlp(robot: Robot, objective: Objective | None, obstacles: ObstacleSet,
             self_pairs: tuple[Pair, ...] = ()) -> FullNLP:  # fmt: skip
    """The :class:`FullNLP` for ``robot``, the objective's form, the obstacle families and the capsule pairs, built
    once (``robot.cache``)."""
    form = None if objective is None else (objective.key(), len(objective.params(robot)))
    key = ("full nlp", form, obstacles.kinds, self_pairs)
    return robot.cache.get(key, FullNLP, robot, objective, obstacles, self_pairs)


def solve_full(
    robot: Robot | Scene,
    pose: np.ndarray,
    objective: Objective | str | None = None,
    obstacles=None,
    q_ref: np.ndarray | None = None,
    project: bool = False,
    *,
    d_safe: float | None = None,
    options: FullOptions | None = None,
) -> FullResult:
    """Minimise ``objective`` over q with ``fk(q) = pose`` (see the module docstring).

    Args:
        robot: any arm, or a :class:`~qpik.scene.Scene` of one (then ``objective``, ``obstacles``, ``q_ref`` and
            ``d_safe`` are the scene's).
        pose: (4, 4) end-effector pose, base frame.
        objective: an :class:`~qpik.objectives.Objective`, a name of :func:`qpik.objectives.resolve`, or
            None for a pure IK.
        obstacles: shapes (world frame): clearance ≥ ``d_safe`` for every link capsule.
        q_ref: (n,) reference configuration, rad (the ``"distance"`` objective's).
        project: project a non-orthonormal rotation onto SO(3) instead of raising.
        d_safe: m (≥ 0; default 0.02).
        options: the first start(s) q0, the number of starts and the seed (:class:`~qpik.nlp.options.FullOptions`;
            default its defaults).

    Raises:
        InputError: NaN/inf or wrong shapes (naming the argument).
    """
    options = FullOptions() if options is None else options
    if not isinstance(options, FullOptions):
        raise InputError(f"options: expected FullOptions, got {type(options).__name__}")
    q0, starts, max_starts, seed = options.q0, options.starts, options.max_starts, options.seed
    scene = scene_of(robot, obstacles, d_safe, objective, q_ref)
    robot, obj, obs, d_safe, q_ref = scene.robot, scene.objective, scene.obstacles, scene.d_safe, scene.q_ref
    T = check_pose(pose, "pose", project)[0]
    if T.ndim != 2:
        raise InputError(f"pose: solve_full takes one pose (4, 4), got {T.shape}")
    n = robot.dof
    if obj is not None and q_ref is None and any(isinstance(o, ReferenceDistance) for _, o in obj.terms):
        raise InputError("q_ref: the distance objective needs a reference configuration q_ref")
    ref = np.zeros(n) if q_ref is None else q_ref
    starts, max_starts, seed = count(starts, "starts", 1), count(max_starts, "max_starts", 1), count(seed, "seed")
    first = np.zeros((0, n)) if q0 is None else np.atleast_2d(joint_vector(q0, n, "q0")[0])
    nlp = full_nlp(robot, obj, obs, scene.self_pairs)
    t0 = time.perf_counter()  # the solve's clock: the NLP and its IPOPT solver are built above (cached per form)
    p = nlp.parameters(T, ref, d_safe, obj, obs)
    queue = _starts(robot, T, first, seed)
    best, best_err, tried, iters = None, np.inf, 0, 0
    wanted = 1 if obj is None else starts
    reached, failure = 0, ""
    for q_start in queue:
        if tried >= max_starts or (reached and tried >= wanted):
            break
        tried += 1
        try:
            out = solve_from(nlp, q_start, p)
        except RuntimeError as exc:  # an evaluation error inside IPOPT: the next start
            failure = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
            continue
        iters += out[3]
        q, value, err, _, kkt, clear = out
        if err < REACHED and clear >= d_safe - 1e-9:
            reached += 1
            if best is None or best_err >= REACHED or value < best[1]:
                best, best_err = (q, value, kkt, clear), err
        elif best is None or (best_err >= REACHED and err < best_err):
            best, best_err = (q, value, kkt, clear), err
    elapsed = time.perf_counter() - t0
    if best is None:
        q = np.clip(next(iter(_starts(robot, T, first, seed))), robot.q_min, robot.q_max)
        return FullResult("solver failed", q, np.inf, np.inf, np.inf, np.inf, tried, iters, elapsed,
                          f"every start failed ({failure})")  # fmt: skip
    q, value, kkt, clear = best
    inside = bool(np.all(q >= robot.q_min) and np.all(q <= robot.q_max))
    if best_err < REACHED and inside and clear >= d_safe - 1e-9:
        return FullResult("optimal", q, value, best_err, kkt, clear, tried, iters, elapsed, "")
    msg = f"no start reached the pose (smallest error {best_err:.3g} after {tried} starts)"
    if best_err < REACHED:
        msg = f"the best point found fails its check: {'clearance' if inside else 'joint limits'}"
    return FullResult(_not_found(robot, T), q, value, best_err, kkt, clear, tried, iters, elapsed, msg)


def _not_found(robot: Robot, T: np.ndarray) -> str:
    """``"unreachable"`` when proved (a closed form's feasible sets at T are all empty and proved so), else
    ``"not found"``."""
    if robot.closed_form is None:
        return "not found"
    from qpik.analytic import closed_form_for, feasible_intervals

    if not closed_form_for(robot).sets_proved:
        return "not found"
    fi = feasible_intervals(robot, T)
    return "unreachable" if fi.proved and not any(fi.intervals) else "not found"


def _starts(robot: Robot, T: np.ndarray, first: np.ndarray, seed: int):
    """``first``, then one closed-form start per branch with a feasible interval (an arm whose branches are found by
    a search instead: its branches within the limits at :data:`SEARCHED` values of the parameter), then seeded random
    ones."""
    yield from first
    from qpik.analytic import feasible_intervals, ik

    if robot.branch_functions:
        fi = feasible_intervals(robot, T)
        for b, ivs in zip(fi.branch, fi.intervals):
            if ivs:
                lo, hi = max(ivs, key=lambda iv: iv[1] - iv[0])
                sols = ik(robot, T, 0.5 * (lo + hi))
                k = int(np.flatnonzero(sols.branch == b)[0])
                if sols.within_limits[k]:
                    yield sols.q[k]
    elif robot.closed_form is not None:
        for param in SEARCHED:
            sols = ik(robot, T, param)
            yield from sols.q[sols.within_limits]
    rng = np.random.default_rng(seed)
    while True:
        yield rng.uniform(robot.q_min, robot.q_max)


def solve_from(
    nlp: FullNLP, q_start: np.ndarray, p: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple:
    """``(q, objective, pose error, iterations, kkt, clearance)`` of IPOPT started at ``q_start`` (n,) rad, with the
    parameters ``p`` (:meth:`FullNLP.parameters`); ``box``: bounds (n,) each of q, rad, inside the joint limits
    (default: the limits)."""
    with nlp.lock:  # one IPOPT solve of this NLP at a time (its memory and stats are the solver's)
        robot = nlp.robot
        lo, hi = (robot.q_min, robot.q_max) if box is None else box
        t0 = np.asarray(nlp.start_t(q_start, p)).ravel() + 1e-3 if nlp.start_t is not None else np.zeros(0)
        x0 = np.concatenate([q_start, t0])
        lbx = np.concatenate([lo, np.full(nlp.n_t, -np.inf)])
        ubx = np.concatenate([hi, np.full(nlp.n_t, np.inf)])
        n_g = nlp.solver.size1_out("g")
        lbg = np.concatenate([np.zeros(nlp.n_eq), np.full(n_g - nlp.n_eq, -np.inf)])
        ubg = np.zeros(n_g)
        bounds = {"lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}
        sol = nlp.solver(x0=x0, p=p, **bounds)
        iters = int(nlp.solver.stats().get("iter_count", 0))
        x = np.asarray(sol["x"]).ravel()
        q = np.clip(x[: robot.dof], lo, hi)
        T = np.asarray(p[:16]).reshape(4, 4).T
        err = float(np.linalg.norm(pose_error(T, robot.fk(q))))
        value, clear = (float(v) for v in nlp.value(q, p))
        kkt = kkt_residual(nlp, p, sol, bounds)
        return q, value, err, iters, kkt, clear


def kkt_residual(nlp: FullNLP, p: np.ndarray, sol: dict, bounds: dict[str, np.ndarray]) -> float:
    """∞-norm of the Lagrangian's gradient, the constraint violation and the complementarity at IPOPT's answer
    ``sol`` (``x``, ``lam_g``, ``lam_x``) of ``nlp`` with parameters ``p`` and ``bounds`` (``lbx``, ``ubx``, ``lbg``,
    ``ubg``)."""
    x, lam_g, lam_x = (np.asarray(sol[k]).ravel() for k in ("x", "lam_g", "lam_x"))
    lbx, ubx, lbg, ubg = (bounds[k] for k in ("lbx", "ubx", "lbg", "ubg"))
    grad, g = (np.asarray(v).ravel() for v in nlp.kkt_terms(x, p, lam_g, lam_x))
    viol = np.maximum(np.maximum(lbg - g, g - ubg), 0.0)
    viol_x = np.maximum(np.maximum(lbx - x, x - ubx), 0.0)
    ineq = np.isinf(lbg)
    comp = np.abs(lam_g[ineq] * (g[ineq] - ubg[ineq]))
    gap_x = np.where(lam_x < 0, x - lbx, ubx - x)  # the distance to the bound the multiplier acts on
    bound = np.abs(lam_x[np.isfinite(gap_x)] * gap_x[np.isfinite(gap_x)])
    return float(
        max(
            np.abs(grad).max(),
            viol.max(initial=0.0),
            viol_x.max(initial=0.0),
            comp.max(initial=0.0),
            bound.max(initial=0.0),
        )
    )
