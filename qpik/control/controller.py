r"""The QP controller: tasks and limits -> one QP per control step -> a joint velocity.

Each :meth:`Controller.step` makes ONE natively compiled call, composed at construction
from the kinematics and every task's and limit's expression (:class:`~qpik.control.qp.Assembler`),
that gives :math:`\min \tfrac12 x^T P x + c^T x` s.t. :math:`l \le Ax \le u`,
:math:`lb \le x \le ub` (:mod:`qpik.control.qp`), solves it with a persistent solver
(:mod:`qpik.control.solvers`) and returns ``v`` (n,), rad/s, to integrate as
``q ← q + v·dt``.

When the QP has no solution, the step follows the failure policy of :mod:`qpik.control.failure_policy`
(another solver, the yielding QP, relaxed separating rows, then the stop the motion limits allow); what
happened is :attr:`Controller.last` (:class:`~qpik.control.step_info.StepInfo`).
"""

from __future__ import annotations

import operator
import time
from collections.abc import Sequence

import casadi as ca
import numpy as np

from qpik.control.failure_policy import FALLBACK, solve_with_fallbacks
from qpik.control.limits import ConfigurationLimit, Limit, ObstacleLimit, RowLimit, VelocityLimit
from qpik.control.options import ControllerOptions
from qpik.control.qp import Assembler
from qpik.control.self_collision import SelfCollisionLimit
from qpik.control.solvers import Solver, get_solver
from qpik.control.state import SymState
from qpik.control.step_info import StepInfo
from qpik.control.tasks import DampingTask, FrameTask, ManipulabilityTask, PostureTask, Task
from qpik.core.errors import InfeasibleError, InputError, SolverError
from qpik.core.validate import joint_vector, number
from qpik.geometry.contacts import capsule_pairs
from qpik.robots.robot import as_robot
from qpik.scene.scene import Scene


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
        self.config_limits = tuple(lim for lim in self.limits if isinstance(lim, ConfigurationLimit))
        self.caps = tuple(lim for lim in self.limits if isinstance(lim, VelocityLimit))
        # one compiled call per step: the QP and the step's summary (_summary)
        self.assembler = Assembler(robot, self.tasks, self.limits, self.dt, self._summary)
        summary = self.assembler.extra  # views, refilled by every build
        self._past, self._task_error, self._own = summary.past, summary.task_error, summary.own
        self._caps = (summary.cap_lo, summary.cap_hi)
        self._clearance, self._recovery = summary.clearance, summary.recovery
        self._d_safe = [lim.d_safe for lim in (*self.obstacle_limits, *self.self_limits)]  # as clearance + own
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
        (:meth:`~qpik.control.limits.base.RowLimit.recovery_expr`; given up first)."""
        clearance = []
        for lim in self.obstacle_limits:
            moving = np.repeat(~self.robot.fixed_capsules, len(lim.obstacles))  # pair (c, o) at c·O + o
            checked = capsule_pairs(self.robot, lim.obstacles).ravel() & moving
            mask = s.constant(np.where(checked, 0.0, np.inf))
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
        sol, qp, relaxation, yielding = solve_with_fallbacks(self.solver, self.fallback, qp, self._caps, self._recovery)
        t2 = time.perf_counter()
        info = StepInfo(solver_status=sol.status, solve_time=t2 - t1, relaxation=relaxation)
        if sol.found:
            v = np.maximum(sol.x, qp.lb)  # remove the solver's tolerance-level box violations
            np.minimum(v, qp.ub, out=v)
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
            elif past or any(map(operator.lt, clearances + own, self._d_safe)):
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
