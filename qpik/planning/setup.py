"""The checked inputs of one planning call (:class:`Setup`): waypoints, their times and progress, the
transition bounds of the DP (:class:`~qpik.planning.dp.Transitions`) and the objective's weights."""

from __future__ import annotations

import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import finite_array, flag, number
from qpik.core.validate import pose as check_pose
from qpik.geometry.paths import TimedPath
from qpik.objectives import ReferenceDistance
from qpik.planning import dp
from qpik.planning.options import PlanOptions
from qpik.scene.evaluator import Evaluator
from qpik.scene.scene import Scene

MAX_WAYPOINTS = 10_000
"""The most waypoints of one plan."""


class Setup:
    """The checked inputs of one planning call: waypoints, progress, transition bounds and weights.

    Attributes:
        scene: the problem's scene; robot, objective, obstacles: the arm, the objective (or None) and the obstacles
            (an ObstacleSet).
        poses, times, progress: the waypoints (N, 4, 4), their times (N,) s or None, and progress (N,).
        d_safe, q_ref: the safety distance (m) and the posture reference (n,), rad.
        tr: the transition bounds (:class:`~qpik.planning.dp.Transitions`).
    """

    def __init__(self, scene: Scene, path, times, options: PlanOptions):
        self.scene = scene
        self.robot = robot = scene.robot
        waypoints, max_joint_step, a_max = options.waypoints, options.max_joint_step, options.a_max
        n = robot.dof
        if isinstance(path, TimedPath) and not isinstance(path, np.ndarray):
            duration = number(path.duration, "path.duration")
            if times is None:
                count = int(number(waypoints, "waypoints", 2))
                if count != waypoints or count > MAX_WAYPOINTS:
                    raise InputError(f"waypoints: expected an integer in [2, {MAX_WAYPOINTS}], got {waypoints!r}")
                times = np.linspace(0.0, duration, count)
            poses = np.asarray(path.pose(finite_array(times, "times", (None,))), float)
        else:
            poses = path
        T, batched = check_pose(poses, "path", flag(options.project, "project"))
        if not batched or len(T) < 2:
            raise InputError(f"path: expected (N, 4, 4) poses with N >= 2 or a timed path, got shape {np.shape(T)}")
        N = len(T)
        if N > MAX_WAYPOINTS:
            raise InputError(f"path: at most {MAX_WAYPOINTS} waypoints, got {N}")
        self.poses = T
        if times is not None:
            times = finite_array(times, "times", (N,)).copy()
            if np.any(np.diff(times) <= 0):
                raise InputError("times: must be strictly increasing")
        self.times = times
        self.progress = times if times is not None else np.linspace(0.0, 1.0, N)
        step = finite_array(max_joint_step, "max_joint_step")
        if step.shape not in ((), (n,)) or np.any(step <= 0):
            raise InputError(f"max_joint_step: expected a number > 0 or ({n},) of them (rad), got {step}")
        lim = np.broadcast_to(step, (N - 1, n)).copy()
        dt = None
        if times is not None:
            dt = np.diff(times)
            lim = np.minimum(lim, robot.v_max[None] * dt[:, None])
        acc = None
        if a_max is not None:
            if times is None:
                raise InputError("a_max: acceleration limits need times")
            acc = np.broadcast_to(finite_array(a_max, "a_max"), (n,)).copy()
            if np.any(acc <= 0):
                raise InputError("a_max: must be > 0")
        delta = np.diff(self.progress)
        point = np.zeros(N)
        point[:-1] += 0.5 * delta
        point[1:] += 0.5 * delta
        self.tr = dp.Transitions(lim, 1.0 / delta, point, dt, acc)
        self.objective, self.obstacles, self.d_safe = scene.objective, scene.obstacles, scene.d_safe
        if scene.q_ref is None and self.objective is not None and any(isinstance(o, ReferenceDistance)
                                                                      for _, o in self.objective.terms):  # fmt: skip
            raise InputError("q_ref: the distance objective needs a reference configuration q_ref")
        self.q_ref = np.zeros(n) if scene.q_ref is None else scene.q_ref

    def cost(self, q: np.ndarray, continuous: np.ndarray) -> float:
        """J of configurations q (N, n) (see :mod:`qpik.planning.dp`); ``continuous`` (N-1,): which
        transitions count in the motion term."""
        D = np.diff(q, axis=0)
        motion = float(np.sum(np.einsum("kj,kj->k", D, D) * self.tr.motion[: len(D)] * continuous))
        if self.objective is None:
            return motion
        f = Evaluator(self.robot, self.objective, self.obstacles)(q, self.q_ref)[0]
        return motion + float(np.sum(self.tr.point[: len(q)] * f))
