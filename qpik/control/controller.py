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
3. if the QP is truly infeasible and obstacle rows demand separation (several of them
   conflict), those rows are relaxed to only forbid approach (``l ← min(l, 0)``, which
   ``v = 0`` meets) and it is solved again (``last.relaxation == 1``);
4. otherwise the step returns the point of the box ``[lb, ub]`` nearest to zero velocity
   (it meets the position and velocity limits and never moves toward an obstacle by
   itself) with ``last.status == "failed"`` — or raises
   :class:`~qpik.errors.SolverError` with ``raise_on_failure=True``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from qpik.control.limits import ConfigurationLimit, Limit, ObstacleLimit, VelocityLimit
from qpik.control.qp import Assembler
from qpik.control.solvers import Solver, get_solver
from qpik.control.state import SymState
from qpik.control.tasks import DampingTask, FrameTask, ManipulabilityTask, PostureTask, Task
from qpik.errors import InputError, SolverError, UnreachableError
from qpik.lie import pose_error
from qpik.validate import joint_vector
from qpik.validate import pose as check_pose

FALLBACK = "daqp"  # exact active-set solver tried when the main solver reports no solution
ACTIVE_TOL = 1e-7  # rad/s (box) and row units: a constraint within this of its bound is reported active


@dataclass
class StepInfo:
    """What happened in the last control step.

    Attributes:
        status: ``"ok"``; ``"recovering"`` (started past a position limit or inside the
            safety distance, moving back); ``"penetrating"`` (a capsule overlaps an obstacle,
            d < 0; moving away); ``"failed"`` (no QP solution: the safe velocity was returned).
        active: names of the constraints at their bound (``"joint3 position upper"``,
            ``"obstacle sphere0 / link4"``, ...).
        min_clearance: smallest capsule–obstacle signed distance, m (inf without obstacles).
        relaxation: 1 if the QP had no solution and the rows that demanded separation were
            relaxed to only forbid approach (``l ← min(l, 0)``, which ``v = 0`` meets), else 0.
        task_error: norm of the first FrameTask's pose error ``[m; rad]`` (nan without one).
        solver_status: the solver's own status string.
        solve_time, total_time: seconds in the solver, and in the whole step.
    """

    status: str = "ok"
    min_clearance: float = np.inf
    relaxation: int = 0
    task_error: float = np.nan
    solver_status: str = ""
    solve_time: float = 0.0
    total_time: float = 0.0
    _activity: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the constraints at their bound, built on first access."""
        if self._activity is None:
            return ()
        v, bounds, row_names, caps = self._activity  # bounds: [lb, ub, l, u, A v] stacked
        n, m = len(v), len(row_names)
        lb, ub, l, u = bounds[:n], bounds[n : 2 * n], bounds[2 * n : 2 * n + m], bounds[2 * n + m : 2 * n + 2 * m]
        Av = bounds[2 * n + 2 * m :]
        gap_lo, gap_hi = Av - l, u - Av
        cap = [lim._bounds for lim in caps if lim._bounds is not None]

        def kind(j: int, bound: float, side: int) -> str:
            return "velocity" if any(bound == c[side][j] for c in cap) else "position"

        names = [f"joint{j + 1} {kind(j, lb[j], 0)} lower" for j in np.flatnonzero(v - lb < ACTIVE_TOL)]
        names += [f"joint{j + 1} {kind(j, ub[j], 1)} upper" for j in np.flatnonzero(ub - v < ACTIVE_TOL)]
        names += [row_names[r] for r in np.flatnonzero((gap_lo < ACTIVE_TOL) | (gap_hi < ACTIVE_TOL))]
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
            returning the safe velocity.

    Raises:
        InfeasibleError: the limits can never be met (e.g. ``q_min > q_max`` overrides).
        InputError: bad dt or task/limit shapes.
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
        self.dt = float(dt)
        if not np.isfinite(self.dt) or self.dt <= 0:
            raise InputError(f"dt: must be finite and > 0, got {dt}")
        self.robot = robot
        self.tasks = tuple(tasks)
        self.limits = tuple(limits)
        for task in self.tasks:
            if isinstance(task, PostureTask) and task.q_ref.shape != (robot.dof,):
                raise InputError(f"PostureTask.q_ref: expected shape ({robot.dof},), got {task.q_ref.shape}")
        for lim in self.limits:
            lim.check(robot, self.dt)
        self.solver = get_solver(solver) if isinstance(solver, str) else solver
        self.fallback = get_solver(FALLBACK) if self.solver.name != FALLBACK else None
        self.raise_on_failure = raise_on_failure
        self.frame_task = next((t for t in self.tasks if isinstance(t, FrameTask)), None)
        self.obstacle_limits = tuple(lim for lim in self.limits if isinstance(lim, ObstacleLimit))
        # one compiled call per step: the QP, the first FrameTask's pose error, every obstacle limit's distances
        self.assembler = Assembler(robot, self.tasks, self.limits, self.dt, self._extra)
        self.config_limits = tuple(lim for lim in self.limits if isinstance(lim, ConfigurationLimit))
        self.caps = tuple(lim for lim in self.limits if isinstance(lim, VelocityLimit))
        self.last = StepInfo()
        self._ik: Controller | None = None

    @classmethod
    def for_robot(
        cls,
        robot,
        target: np.ndarray | None = None,
        obstacles: Sequence = (),
        dt: float = 0.001,
        solver: str | Solver = "osqp",
        q_ref: np.ndarray | None = None,
        position_gain: float = 50.0,
        orientation_gain: float = 50.0,
        posture_weight: float = 1e-3,
        manipulability_weight: float = 1e-3,
        damping: float = 1e-4,
        margin: float = 0.0,
        d_influence: float = 0.10,
        d_safe: float = 0.02,
        xi: float = 0.5,
    ) -> Controller:
        """A controller with the usual tasks and limits.

        Tasks: :class:`FrameTask` (``target``, gains in 1/s, weights 1 per m² and 0.1 per rad²),
        :class:`PostureTask` toward ``q_ref`` (default ``robot.q_home``, gain 1/s),
        :class:`ManipulabilityTask`, :class:`DampingTask`. Limits:
        :class:`ConfigurationLimit` (``margin``), :class:`VelocityLimit` (the robot's) and,
        with ``obstacles``, :class:`ObstacleLimit` (``d_influence``, ``d_safe`` in m, ``xi`` in m/s).
        """
        tasks: list[Task] = [
            FrameTask(target, position_gain, orientation_gain),
            PostureTask(robot.q_home if q_ref is None else q_ref, 1.0, posture_weight),
            ManipulabilityTask(manipulability_weight),
            DampingTask(damping),
        ]
        limits: list[Limit] = [ConfigurationLimit(margin), VelocityLimit()]
        if len(obstacles):
            limits.append(ObstacleLimit(obstacles, d_influence, d_safe, xi))
        return cls(robot, tasks, limits, solver=solver, dt=dt)

    def set_posture(self, q_ref: np.ndarray) -> None:
        """Set the reference of every :class:`PostureTask` (n,), rad: for example the best configuration
        of :func:`qpik.solve_best` for the target, ``ctrl.set_posture(best.q)``."""
        q_ref = joint_vector(q_ref, self.robot.dof, "q_ref")[0]
        for task in self.tasks:
            if isinstance(task, PostureTask):
                task.set_target(q_ref)

    def _extra(self, s: SymState) -> list:
        out = [lim.distances_expr(s) for lim in self.obstacle_limits]
        if self.frame_task is not None:
            out.append(self.frame_task.error_expr(s, s.params_of(self.frame_task)))
        return out

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
        extra = self.assembler.extra
        t1 = time.perf_counter()
        sol = self.solver.solve(qp)
        relaxation = 0
        if not sol.found and self.fallback is not None:
            sol = self.fallback.solve(qp)
        if not sol.found and (qp.l > 0).any():  # separating rows may conflict: only forbid approach
            relaxation = 1
            np.minimum(qp.l, 0.0, out=qp.l)
            sol = (self.fallback or self.solver).solve(qp)
        t2 = time.perf_counter()
        lb, ub = qp.lb, qp.ub
        info = StepInfo(solver_status=sol.status, solve_time=t2 - t1, relaxation=relaxation)
        if sol.found:
            v = np.minimum(np.maximum(sol.x, lb), ub)  # remove the solver's tolerance-level box violations
            info._activity = (v, np.concatenate((lb, ub, qp.l, qp.u, qp.A @ v)), qp.row_names, self.caps)
        else:
            if self.raise_on_failure:
                raise SolverError(f"{self.solver.name}: no solution ({sol.status})")
            v = np.clip(0.0, lb, ub)
            info.status = "failed"
        for d in extra[: len(self.obstacle_limits)]:
            info.min_clearance = min(info.min_clearance, float(d.min()))
        if self.frame_task is not None:
            e = extra[-1]
            info.task_error = math.sqrt(e @ e)
        if info.status == "ok":
            if info.min_clearance < 0.0:
                info.status = "penetrating"
            elif any(info.min_clearance < lim.d_safe for lim in self.obstacle_limits) or self._past_limit(q):
                info.status = "recovering"
        info.total_time = time.perf_counter() - t0
        self.last = info
        return v

    def _past_limit(self, q: np.ndarray) -> bool:
        return any((q < lim._lo).any() or (q > lim._hi).any() for lim in self.config_limits)

    def solve_ik(
        self,
        q0: np.ndarray,
        pose: np.ndarray,
        tol: float = 1e-10,
        max_iters: int = 200,
        restarts: int = 10,
        seed: int = 0,
    ) -> np.ndarray:
        r"""Iterate ``q ← q + v`` until the pose error of the end-effector is below ``tol``.

        The iteration is a damped Gauss–Newton step through a QP of its own: a
        :class:`FrameTask` with unit gains (``K·dt = 1``: each step aims at the whole
        error, with this controller's frame weights), a small :class:`DampingTask`
        (1e-9, Levenberg–Marquardt), this controller's :class:`ConfigurationLimit` s and a
        trust region ``|Δq_j| ≤ 0.5 rad`` per iteration (the velocity cap at dt = 1 s).
        Obstacles, posture and manipulability are left out: their terms would move the
        fixed point off the target. Converges quadratically near a regular solution.

        A local method can stall (at a joint limit, or in a local minimum of the error
        far from the target). Then it starts again from a configuration drawn uniformly
        within the position limits, up to ``restarts`` times, from a generator seeded
        with ``seed`` (so the answer is reproducible). The first attempt is always ``q0``.

        Args:
            q0: (n,) start configuration, rad.
            pose: (4, 4) target pose of the end-effector (base frame).
            tol: stop when ``‖[p* − p; log(R* Rᵀ)]‖ < tol`` (m and rad together).
            max_iters: iteration budget of each attempt.
            restarts: attempts from random configurations after the one from ``q0``.
            seed: seed of the random restarts.

        Returns:
            q (n,), rad, within the position limits.

        Raises:
            UnreachableError: no attempt converged (the message gives the smallest residual).
            InputError: NaN or wrong shapes.
        """
        q, batched = joint_vector(q0, self.robot.dof, "q0")
        if batched:
            raise InputError(f"q0: expected shape ({self.robot.dof},), got {q.shape}")
        target = check_pose(pose, "pose")[0]
        if self._ik is None:
            ft = self.frame_task
            w = (1.0, 1.0) if ft is None else (ft.weight[0], ft.weight[3])
            limits = [*self.config_limits, VelocityLimit(np.full(self.robot.dof, 0.5))]
            tasks = [FrameTask(None, 1.0, 1.0, *w), DampingTask(1e-9)]
            self._ik = Controller(self.robot, tasks, limits, solver=self.solver.name, dt=1.0)
        ik = self._ik
        ik.frame_task.set_target(target)
        rng = np.random.default_rng(seed)
        best = np.inf
        for attempt in range(restarts + 1):
            q = q.copy() if attempt == 0 else rng.uniform(self.robot.q_min, self.robot.q_max)
            for _ in range(max_iters):
                err = float(np.linalg.norm(pose_error(target, self.robot.fk(q))))
                if err < tol:
                    return q
                q += ik.step(q)
            err = float(np.linalg.norm(pose_error(target, self.robot.fk(q))))
            if err < tol:
                return q
            best = min(best, err)
        raise UnreachableError(
            f"solve_ik: smallest pose error {best:.3g} (m, rad) after {restarts + 1} attempts "
            f"of {max_iters} iterations (tol {tol:g})"
        )
