r"""The QP controller: tasks and limits -> one QP per control step -> a joint velocity.

Each :meth:`Controller.step` makes ONE natively compiled call, composed at construction
from the kinematics and every task's and limit's expression (:class:`~qpik.control.qp.Assembler`),
that gives :math:`\min \tfrac12 x^T P x + c^T x` s.t. :math:`l \le Ax \le u`,
:math:`lb \le x \le ub` (:mod:`qpik.control.qp`), solves it with a persistent solver
(:mod:`qpik.control.solvers`) and returns ``v`` (n,), rad/s, to integrate as
``q ← q + v·dt``.

Failure policy (never raises in the loop unless ``raise_on_failure=True``):

1. the main solver; if it reports no solution (e.g. OSQP stopping on a degenerate QP),
2. DAQP, an exact active-set solver (:data:`FALLBACK`), on the same QP;
3. if the QP is truly infeasible while the box makes a joint move back from past a position
   limit (``lb_j > 0`` or ``ub_j < 0``), the return conflicts with the obstacle rows and
   safety wins: the *yielding* QP keeps every row and the velocity caps, lets the joints
   past a limit stop (the box widened to contain ``v = 0``: never further out) and asks for
   the return in the cost, :math:`w \sum_{j\ \rm forced} (v_j - r_j)^2` with the box's
   return velocity :math:`r_j` and ``w`` = :data:`YIELD_WEIGHT` × (1 + max diag P), above the
   tasks: the limit is recovered as fast as the obstacle rows allow (``last.status ==
   "yielding"``). The obstacle rows are bounded inside that widened box
   (:class:`~qpik.control.limits.ObstacleLimit`), so only rows among themselves can still conflict;
4. if obstacle rows demand separation and conflict (an arm inside the safety distance of two
   obstacles on opposite sides, or a moving obstacle the arm must flee from two sides), the parts of the
   demands that recover from inside a safety distance are scaled first (the escape from a moving obstacle
   kept), and only if that is not enough the whole demands, each time by the largest common fraction that
   can be met: first 0 (for the whole demands: only forbid approach, which ``v = 0`` meets where the
   acceleration limits let the arm stop), then :data:`RELAX_STEPS` bisection steps toward 1, the fraction
   found times :data:`BACK_OFF` (``last.relaxation`` is the part dropped; the QP is then not at the edge of
   feasibility, where its set is too thin for the solvers): as much of the separating speed is kept as can
   be, since rows held at exactly zero approach let the second-order terms of the motion (see
   :class:`~qpik.control.limits.ObstacleLimit`) creep closer;
5. otherwise the step returns the command nearest ``v = 0`` that the cap limits allow (their own box: the
   velocity limits and, where given, :class:`~qpik.control.limits_motion.AccelerationLimit` and
   :class:`~qpik.control.limits_motion.JerkLimit` around the last commands): ``v = 0`` without them (the arm
   holds still: never further past a limit, never toward an obstacle), else the arm brakes toward rest at those
   limits, which :class:`~qpik.control.limits_motion.BrakingLimit` leaves room for; ``last.status == "failed"``
   — or raises :class:`~qpik.core.errors.SolverError` with ``raise_on_failure=True``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from qpik.control.limits import ConfigurationLimit, Limit, ObstacleLimit, RowLimit, VelocityLimit
from qpik.control.options import ControllerOptions
from qpik.control.qp import QP, Assembler
from qpik.control.self_collision import SelfCollisionLimit
from qpik.control.solvers import Solver, get_solver
from qpik.control.state import SymState
from qpik.control.tasks import DampingTask, FrameTask, ManipulabilityTask, PostureTask, Task
from qpik.core.errors import InfeasibleError, InputError, SolverError
from qpik.core.validate import joint_vector, number
from qpik.geometry.contacts import capsule_pairs
from qpik.robots.robot import as_robot
from qpik.scene.scene import Scene

FALLBACK = "daqp"  # exact active-set solver tried when the main solver reports no solution
ACTIVE_TOL = 1e-7  # rad/s (box) and row units: a constraint within this of its bound is reported active
RELAX_STEPS = 6
"""Bisection steps on the fraction of their demand that separating rows keep when they conflict (failure policy)."""
BACK_OFF = 15 / 16
"""The fraction found by the bisection is kept times this (failure policy): not at the edge of feasibility."""
YIELD_WEIGHT = 1e3
"""Weight of the return from past a limit in the yielding QP, relative to 1 + the largest diagonal entry of P."""


@dataclass
class StepInfo:
    """What happened in the last control step.

    Attributes:
        status: ``"ok"``; ``"recovering"`` (started past a position limit or inside the
            safety distance, moving back); ``"penetrating"`` (a capsule overlaps an obstacle,
            d < 0; moving away); ``"yielding"`` (past a position limit, the return conflicts
            with the obstacle rows: it goes only as fast as they allow, see the failure
            policy); ``"failed"`` (no QP solution: the command nearest 0 that the velocity, acceleration and
            jerk limits allow was returned, ``v = 0`` without acceleration limits). When several
            hold, the first of failed, yielding, penetrating, recovering is reported.
        active: names of the constraints at their bound (``"joint3 position upper"``,
            ``"obstacle sphere0 / link4"``, ...).
        min_clearance: smallest capsule–obstacle signed distance, m, over the pairs :mod:`qpik.geometry.contacts`
            checks (not those whose distance no joint motion changes: a base column on its table;
            inf without such pairs).
        min_self_distance: smallest signed distance, m, of the pairs a
            :class:`~qpik.control.self_collision.SelfCollisionLimit` checks (inf without one); below its d_s
            the status is ``"recovering"``, below 0 ``"penetrating"``.
        relaxation: 0 if the QP was solved as built; else the part of the separating rows'
            demand that was dropped when they conflicted, in (0, 1] (1: only approach is forbidden;
            failure policy, step 4).
        task_error: norm of the first FrameTask's pose error ``[m; rad]`` (nan without one).
        solver_status: the solver's own status string.
        solve_time, total_time: seconds in the solver, and in the whole step.
        activity: what :attr:`active` is built from: the step's v (n,), a function giving the step's QP,
            and the controller's velocity limits (None when the step failed).
    """

    status: str = "ok"
    min_clearance: float = np.inf
    min_self_distance: float = np.inf
    relaxation: float = 0.0
    task_error: float = np.nan
    solver_status: str = ""
    solve_time: float = 0.0
    total_time: float = 0.0
    activity: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the constraints at their bound, built on first access."""
        if self.activity is None:
            return ()
        v, saved, caps = self.activity
        qp = saved()
        lb, ub, l, u = qp.lb, qp.ub, qp.l, qp.u
        Av = qp.A @ v
        gap_lo, gap_hi = Av - l, u - Av
        cap = [lim.range for lim in caps if lim.range is not None]

        def kind(j: int, bound: float, side: int) -> str:
            return "velocity" if any(bound == c[side][j] for c in cap) else "position"

        names = [f"joint{j + 1} {kind(j, lb[j], 0)} lower" for j in np.flatnonzero(v - lb < ACTIVE_TOL)]
        names += [f"joint{j + 1} {kind(j, ub[j], 1)} upper" for j in np.flatnonzero(ub - v < ACTIVE_TOL)]
        names += [qp.row_names[r] for r in np.flatnonzero((gap_lo < ACTIVE_TOL) | (gap_hi < ACTIVE_TOL))]
        return tuple(names)


class Controller:
    """Differential IK as one QP per control step.

    Args:
        robot: the arm (:class:`qpik.Robot`).
        tasks: cost terms (:mod:`qpik.control.tasks`).
        limits: constraints (:mod:`qpik.control.limits`).
        solver: a name of :func:`qpik.control.solvers.get_solver` (``"osqp"``: persistent,
            warm-started) or a :class:`~qpik.control.solvers.Solver`.
        dt: control period, s (position limits and dampers look one step ahead).
        raise_on_failure: raise :class:`SolverError` on a failed solve instead of
            returning the stop of the failure policy (step 5).

    Raises:
        InfeasibleError: the limits can never be met (e.g. ``q_min > q_max`` overrides, or two
            :class:`ConfigurationLimit` s whose ranges of a joint do not meet).
        InputError: bad dt, robot, solver, tasks, limits or task/limit shapes.
        SolverError: an unknown or uninstalled solver name.
    """

    def __init__(
        self,
        robot,
        tasks: Sequence[Task],
        limits: Sequence[Limit] = (),
        solver: str | Solver = "osqp",
        dt: float = 0.001,
        raise_on_failure: bool = False,
    ):
        self.dt = number(dt, "dt", minimum=None)
        if self.dt <= 0:
            raise InputError(f"dt: must be > 0, got {dt}")
        self.robot = robot = as_robot(robot)
        self.tasks = _items(tasks, Task, "tasks")
        self.limits = _items(limits, Limit, "limits")
        for task in self.tasks:
            if isinstance(task, PostureTask) and task.q_ref.shape != (robot.dof,):
                raise InputError(f"PostureTask.q_ref: expected shape ({robot.dof},), got {task.q_ref.shape}")
        for lim in self.limits:
            lim.check(robot, self.dt)
        _check_ranges([lim for lim in self.limits if isinstance(lim, ConfigurationLimit)])
        if isinstance(solver, str):
            self.solver = get_solver(solver)
        elif isinstance(solver, Solver):
            self.solver = solver
        else:
            raise InputError(f"solver: expected a solver name or a qpik.control.solvers.Solver, got {solver!r}")
        self.fallback = get_solver(FALLBACK) if self.solver.name != FALLBACK else None
        self.raise_on_failure = raise_on_failure
        self.frame_task = next((t for t in self.tasks if isinstance(t, FrameTask)), None)
        self.obstacle_limits = tuple(lim for lim in self.limits if isinstance(lim, ObstacleLimit))
        self.self_limits = tuple(lim for lim in self.limits if isinstance(lim, SelfCollisionLimit))
        self._d_safe_self = [lim.d_safe for lim in self.self_limits]
        self.config_limits = tuple(lim for lim in self.limits if isinstance(lim, ConfigurationLimit))
        self.caps = tuple(lim for lim in self.limits if isinstance(lim, VelocityLimit))
        # one compiled call per step: the QP and the step's summary (_summary)
        self.assembler = Assembler(robot, self.tasks, self.limits, self.dt, self._summary)
        summary = self.assembler.extra  # views, refilled by every build
        self._past, self._task_error, self._own = summary.past, summary.task_error, summary.own
        self._caps = (summary.cap_lo, summary.cap_hi)
        self._clearance, self._recovery = summary.clearance, summary.recovery
        self._d_safe = [lim.d_safe for lim in self.obstacle_limits]
        self.last = StepInfo()

    @classmethod
    def for_robot(
        cls,
        robot,
        target: np.ndarray | None = None,
        obstacles: Sequence = (),
        *,
        dt: float = 0.001,
        solver: str | Solver = "osqp",
        q_ref: np.ndarray | None = None,
        d_safe: float = 0.02,
        options: ControllerOptions | None = None,
    ) -> Controller:
        """:meth:`for_scene` of ``Scene.of(robot, obstacles, d_safe=d_safe, q_ref=q_ref)``."""
        return cls.for_scene(Scene.of(robot, obstacles, d_safe=d_safe, q_ref=q_ref), target, dt=dt, solver=solver,
                             options=options)  # fmt: skip

    @classmethod
    def for_scene(
        cls,
        scene: Scene,
        target: np.ndarray | None = None,
        *,
        dt: float = 0.001,
        solver: str | Solver = "osqp",
        options: ControllerOptions | None = None,
    ) -> Controller:
        """A controller with the usual tasks and limits for the scene's arm, obstacles, d_safe and q_ref.

        Tasks: :class:`FrameTask` (``target`` (4, 4), base frame; gains in 1/s, weights 1 per m² and 0.1 per
        rad²), :class:`PostureTask` toward the scene's ``q_ref`` (default ``robot.q_home``, gain 1/s),
        :class:`ManipulabilityTask`, :class:`DampingTask`. Limits: :class:`ConfigurationLimit`,
        :class:`VelocityLimit` (the robot's) and, with obstacles, :class:`ObstacleLimit` (``d_safe`` of the
        scene), and with ``options.self_collision`` :class:`~qpik.control.self_collision.SelfCollisionLimit`
        (its defaults: the pairs of non-adjacent links less those always in collision or never within 5 cm over
        10,000 seeded configurations, d_s = 1 cm, d_i = 6 cm). ``dt``: the control period, s. The gains, weights
        and margins are ``options`` (:class:`~qpik.control.options.ControllerOptions`; default its defaults).
        """
        if not isinstance(scene, Scene):
            raise InputError(f"scene: expected a Scene (qpik.Scene.of), got {type(scene).__name__}")
        o = ControllerOptions() if options is None else options
        if not isinstance(o, ControllerOptions):
            raise InputError(f"options: expected ControllerOptions, got {type(options).__name__}")
        robot = scene.robot
        tasks: list[Task] = [
            FrameTask(target, o.position_gain, o.orientation_gain),
            PostureTask(scene.reference, 1.0, number(o.posture_weight, "posture_weight")),
            ManipulabilityTask(number(o.manipulability_weight, "manipulability_weight")),
            DampingTask(number(o.damping, "damping")),
        ]
        limits: list[Limit] = [ConfigurationLimit(o.margin), VelocityLimit()]
        if len(scene.obstacles):
            limits.append(ObstacleLimit(scene.obstacles, o.d_influence, scene.d_safe, o.xi))
        if o.self_collision and len(robot.capsules) > 2:
            limits.append(SelfCollisionLimit())
        return cls(robot, tasks, limits, solver=solver, dt=dt)

    def set_posture(self, q_ref: np.ndarray) -> None:
        """Set the reference of every :class:`PostureTask` (n,), rad: for example the best configuration
        of :func:`qpik.solve_best` for the target, ``ctrl.set_posture(best.q)``."""
        q_ref = joint_vector(q_ref, self.robot.dof, "q_ref")[0]
        for task in self.tasks:
            if isinstance(task, PostureTask):
                task.set_target(q_ref)

    def _summary(self, s: SymState) -> dict[str, ca.SX]:
        """The step's summary, computed in the compiled call: ``clearance``, per :class:`ObstacleLimit` the
        smallest distance (m) of its capsule–obstacle pairs that :mod:`qpik.geometry.contacts` checks, over the
        capsules a joint moves (:attr:`~qpik.robots.robot.Robot.fixed_capsules` are left out; the pairs are an
        input, 0 or inf per pair, since controllers of one structure share the function); ``past``, 1.0 if q is
        past a :class:`ConfigurationLimit`'s range (else 0.0);
        ``task_error``, the norm of the first :class:`FrameTask`'s pose error ``[m; rad]`` (nan without one);
        ``own``, per :class:`~qpik.control.self_collision.SelfCollisionLimit` its smallest checked self-distance
        (m); ``cap_lo``, ``cap_hi``, the caps' own box (n,) each, rad/s (the yielding QP stays in it); ``recovery``
        (m,), m/s, per QP row the part of its bound that asks to recover from inside its safety distance
        (:meth:`~qpik.control.limits.RowLimit.recovery_expr`; given up first)."""
        clearance = []
        for lim in self.obstacle_limits:
            moving = np.repeat(~self.robot.fixed_capsules, len(lim.obstacles))  # pair (c, o) at c·O + o
            checked = capsule_pairs(self.robot, lim.obstacles).ravel() & moving
            on = np.where(checked, 0.0, np.inf)
            mask = s.parameter(len(checked), lambda state, on=on: on)
            clearance.append(ca.mmin(lim.distances_expr(s) + mask) if len(checked) else ca.SX(np.inf))
        past = ca.SX(0.0)
        for lim in self.config_limits:
            p = s.params_of(lim)
            past = past + ca.sum1(s.q < p.lo) + ca.sum1(s.q > p.hi)
        error = ca.SX(np.nan)
        if self.frame_task is not None:
            error = ca.norm_2(self.frame_task.error_expr(s, s.params_of(self.frame_task)))
        own = [ca.mmin(d) if (d := lim.distances_expr(s)).numel() else ca.inf for lim in self.self_limits]
        rows = [lim for lim in self.limits if isinstance(lim, RowLimit)]  # the assembler's order of the rows
        recovery = ca.vertcat(ca.SX(0, 1), *[lim.recovery_expr(s, lim.parameters(s)) for lim in rows])
        return {"recovery": recovery, "clearance": ca.vertcat(*clearance), "past": past > 0, "task_error": error,
                "own": ca.vertcat(*own), "cap_lo": s.caps[0], "cap_hi": s.caps[1]}  # fmt: skip

    def step(self, q: np.ndarray, target: np.ndarray | None = None, twist: np.ndarray | None = None) -> np.ndarray:
        """One control step: the joint velocity v (n,), rad/s, for configuration ``q`` (n,), rad.

        ``target`` (4, 4) and ``twist`` (6,) ``[v; ω]`` (base frame), if given, update the
        first :class:`FrameTask` first. Details of the step are in :attr:`last`.
        """
        t0 = time.perf_counter()
        q, batched = joint_vector(q, self.robot.dof)
        if batched:
            raise InputError(f"q: expected shape ({self.robot.dof},), got {q.shape}")
        if target is not None:
            if self.frame_task is None:
                raise InputError("target: this controller has no FrameTask")
            self.frame_task.set_target(target, twist)
        qp = self.assembler.build(q)
        t1 = time.perf_counter()
        sol = self.solver.solve(qp)
        exact = self.fallback or self.solver
        relaxation, yielding = 0.0, False
        if not sol.found and self.fallback is not None:
            sol = self.fallback.solve(qp)
        if not sol.found:
            forced = (qp.lb > 0.0) | (qp.ub < 0.0)
            if forced.any():  # the return from past a limit conflicts with the rows: safety wins
                qp, yielding = yielding_qp(qp, forced, *self._caps), True
                sol = exact.solve(qp)
        if not sol.found and (qp.l > 0).any():  # separating rows conflict: ask less of them, down to no approach
            demand = np.maximum(qp.l, 0.0)
            # the recoveries from inside d_s first (an escape from a moving obstacle kept), then every demand
            for part in (np.minimum(self._recovery, demand), demand):
                if part.any():
                    sol, kept = _relax(exact, qp, part)
                    if sol.found:
                        relaxation = 1.0 - kept
                        break
        t2 = time.perf_counter()
        info = StepInfo(solver_status=sol.status, solve_time=t2 - t1, relaxation=relaxation)
        if sol.found:
            v = np.minimum(np.maximum(sol.x, qp.lb), qp.ub)  # remove the solver's tolerance-level box violations
            info.activity = (v, self.assembler.snapshot(qp), self.caps)
        else:
            if self.raise_on_failure:
                raise SolverError(f"{self.solver.name}: no solution ({sol.status})")
            v = np.minimum(np.maximum(0.0, self._caps[0]), self._caps[1])  # the stop the motion limits allow
            info.status = "failed"
        for lim in self.limits:
            lim.observe(v)
        clearances = self._clearance.tolist()
        past, info.task_error = self._past[0], float(self._task_error[0])
        if clearances:
            info.min_clearance = min(clearances)
        own = self._own.tolist()
        if own:
            info.min_self_distance = min(own)
        if info.status == "ok":
            if yielding:
                info.status = "yielding"
            elif min(info.min_clearance, info.min_self_distance) < 0.0:
                info.status = "penetrating"
            elif past or any(d < ds for d, ds in zip(clearances + own, self._d_safe + self._d_safe_self)):
                info.status = "recovering"
        info.total_time = time.perf_counter() - t0
        self.last = info
        return v

    def solve_ik(
        self,
        q0: np.ndarray,
        pose: np.ndarray,
        tol: float = 1e-10,
        max_iters: int = 3000,
        max_time: float | None = None,
        seed: int = 0,
    ) -> np.ndarray:
        """A configuration q (n,), rad, inside the robot's joint limits, with the end-effector at ``pose``.

        Delegates to :func:`qpik.nlp.ik.solve_ik` for this controller's robot (closed form where the arm
        has one, else Levenberg–Marquardt with restarts); this controller's tasks, limits and solver
        do not enter. ``qpik.nlp`` sits beside ``qpik.control`` in the layering, so it is imported
        here, at call time, and ``import qpik.control`` does not load it.

        Args:
            q0: (n,) start configuration, rad.
            pose: (4, 4) target pose of the end-effector (base frame).
            tol: the answer has ``‖[p* − p; log(R* Rᵀ)]‖ ≤ tol`` (m and rad together).
            max_iters: budget of iterations over all attempts.
            max_time: budget in seconds, or None.
            seed: seed of the restarts (the answer is reproducible).

        Raises:
            UnreachableError: no configuration found (the message gives the smallest pose error).
            InputError: NaN or wrong shapes.
        """
        from qpik.nlp.ik import solve_ik
        from qpik.nlp.options import IKOptions

        options = IKOptions(max_iters=max_iters, max_time=max_time, seed=seed)
        return solve_ik(self.robot, pose, q0, tol=tol, options=options)


def _items(items: Sequence, kind: type, name: str) -> tuple:
    """``items`` as a tuple, each a ``kind``; else :class:`InputError` naming ``name`` and the position."""
    try:
        out = tuple(items)
    except TypeError:
        raise InputError(f"{name}: expected a sequence of {kind.__name__}s, got {type(items).__name__}") from None
    for i, item in enumerate(out):
        if not isinstance(item, kind):
            raise InputError(f"{name}[{i}]: expected a {kind.__name__}, got {type(item).__name__}")
    return out


def _check_ranges(limits: Sequence[ConfigurationLimit]) -> None:
    """Raise :class:`InfeasibleError` if the position ranges of several limits (after ``check``) do not meet."""
    if len(limits) < 2:
        return
    lo = np.max([lim.range[0] for lim in limits], axis=0)
    hi = np.min([lim.range[1] for lim in limits], axis=0)
    bad = np.flatnonzero(lo > hi)
    if len(bad):
        raise InfeasibleError(
            "ConfigurationLimit: the position ranges of the limits do not meet for joint(s) "
            + ", ".join(str(j + 1) for j in bad)
        )


def _relax(solver: Solver, qp: QP, part: np.ndarray) -> tuple:
    """``(solution, kept)``: ``qp`` solved with its lower bounds lowered by ``(1 - kept) · part`` (m,), ≥ 0, for
    the largest fraction ``kept`` that can be met (failure policy, step 4), ``qp.l`` left so; kept 0 and no
    solution (``qp.l`` as given) if even ``l - part`` cannot."""
    rows = np.flatnonzero(part > 0.0)
    full, part = qp.l[rows].copy(), part[rows]
    qp.l[rows] = full - part
    sol = solver.solve(qp)
    if not sol.found:
        qp.l[rows] = full
        return sol, 0.0
    kept, above = 0.0, 1.0
    for _ in range(RELAX_STEPS):  # bisection on the fraction kept
        middle = 0.5 * (kept + above)
        qp.l[rows] = full - (1.0 - middle) * part
        trial = solver.solve(qp)
        if trial.found:
            kept, sol = middle, trial
        else:
            above = middle
    if kept > 0.0:  # backed off from the edge of feasibility, where the set is too thin for ADMM
        qp.l[rows] = full - (1.0 - BACK_OFF * kept) * part
        trial = solver.solve(qp)
        kept, sol = (BACK_OFF * kept, trial) if trial.found else (kept, sol)
    qp.l[rows] = full - (1.0 - kept) * part  # the QP solved (as :attr:`StepInfo.active` reads it)
    return sol, kept


def yielding_qp(
    qp: QP, forced: np.ndarray, cap_lo: np.ndarray | float = -np.inf, cap_hi: np.ndarray | float = np.inf
) -> QP:
    r"""The QP of step 3 of the failure policy (module docstring), as a new QP.

    ``forced`` (n,) bool marks the joints whose box excludes ``v = 0`` (past a position
    limit, or an acceleration box that excludes 0). Their bounds are widened toward 0 within the caps' own
    box ``[cap_lo, cap_hi]`` (``lb ← max(min(lb, 0), cap_lo)``, ``ub ← min(max(ub, 0), cap_hi)``: they
    may stop, where the acceleration limit lets them, but not move further out), and the cost gains
    :math:`w (v_j - r_j)^2` toward the velocity :math:`r_j` the box demanded (its bound
    nearer to 0), ``w`` = :data:`YIELD_WEIGHT` × (1 + max diag P): the return comes first,
    the tasks after it; every row is kept.
    """
    out = qp.copy()
    r = np.where(qp.lb > 0.0, qp.lb, qp.ub)
    out.lb[:] = np.maximum(np.minimum(out.lb, 0.0), cap_lo)
    out.ub[:] = np.minimum(np.maximum(out.ub, 0.0), cap_hi)
    w = YIELD_WEIGHT * (1.0 + float(np.abs(np.diagonal(qp.P)).max()))
    idx = np.flatnonzero(forced)
    out.P[idx, idx] += 2.0 * w
    out.c[idx] -= 2.0 * w * r[idx]
    return out
