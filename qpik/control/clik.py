r"""Closed-loop inverse kinematics (CLIK) baselines (Zheng et al. 2019), with the controller's ``step`` interface.

All of them map a task-space command :math:`b = \dot x_d + K e` to a joint velocity,
with the world-frame pose error :math:`e = [p^* - p;\ \log(R^* R^T)]` and the desired
twist :math:`\dot x_d = [v; \omega]` (base frame), :math:`K = \mathrm{diag}(k_p I_3, k_o I_3)`:

- :class:`PseudoInverseCLIK` (Zheng et al. 2019, eq. 18, Fig. 3b):
  :math:`\dot q_k = J^+(\dot x_d + K e + K_d(\dot x_d - J\dot q_{k-1}))` — the pseudo-inverse
  :math:`J^+ = J^T (J J^T)^{-1}` (eq. 11) of proportional feedback on the pose error and a
  derivative (velocity) term on the twist error, :math:`\dot x = J \dot q_{k-1}` being the
  end-effector twist of the previous command; ``kd = 0`` is the textbook CLIK;
- :class:`VelocityOnly` (Fig. 3a, eq. 12): :math:`\dot q = J^+ \dot x_d` — open loop in
  position, so the discretisation error accumulates (drift);
- :class:`DampedLeastSquares`: :math:`\dot q = J^T (J J^T + \lambda^2 I)^{-1} b`, bounded
  near singularities;
- :class:`GradientProjection` (Yoshikawa): :math:`\dot q = J^+ b + k (I - J^+ J)\nabla m`,
  manipulability ascent in the null space.

They enforce no joint, velocity or obstacle limit: they are the baselines the QP is
compared with.
"""

from __future__ import annotations

import time

import numpy as np

from qpik.algebra.lie import pose_error
from qpik.control.state import State
from qpik.control.step_info import StepInfo
from qpik.core.errors import InputError
from qpik.core.validate import finite_array, joint_vector, number, single_pose
from qpik.robots.robot import as_robot


class CLIK:
    """Common part: target, error, feedforward; subclasses map ``b = ẋ_d + K e`` to ``q̇``.

    Args:
        robot: the arm.
        position_gain, orientation_gain: :math:`k_p, k_o`, 1/s.
        dt: control period, s (kept for the sim; the laws themselves are instantaneous).
    """

    name = "clik"

    def __init__(self, robot, position_gain: float = 50.0, orientation_gain: float = 50.0, dt: float = 0.001):
        self.robot = as_robot(robot)
        self.dt = number(dt, "dt", minimum=None)
        if self.dt <= 0:
            raise InputError(f"dt: must be > 0, got {dt}")
        self.gain = np.repeat([number(position_gain, "position_gain"), number(orientation_gain, "orientation_gain")], 3)
        self.target: np.ndarray | None = None
        self.twist = np.zeros(6)
        self.last = StepInfo()

    def set_target(self, target: np.ndarray, twist: np.ndarray | None = None) -> None:
        """Target pose (4, 4) and desired twist (6,) ``[v; ω]`` (base frame; zero if omitted)."""
        self.target = single_pose(target, "target")
        self.twist = np.zeros(6) if twist is None else finite_array(twist, "twist", (6,)).copy()

    def step(self, q: np.ndarray, target: np.ndarray | None = None, twist: np.ndarray | None = None) -> np.ndarray:
        """Joint velocity (n,), rad/s, at configuration ``q`` (n,); ``target``/``twist`` update the command."""
        t0 = time.perf_counter()
        q, batched = joint_vector(q, self.robot.dof)
        if batched:
            raise InputError(f"q: expected shape ({self.robot.dof},), got {q.shape}")
        if target is not None:
            self.set_target(target, twist)
        if self.target is None:
            raise InputError("target: no target set (pass target= or call set_target)")
        state = State(self.robot, q, self.dt)
        e = pose_error(self.target, state.pose)
        v = self._velocity(state, self.twist + self.gain * e)
        t = time.perf_counter() - t0
        self.last = StepInfo(task_error=float(np.linalg.norm(e)), solve_time=t, total_time=t)
        return v

    def _velocity(self, state: State, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class PseudoInverseCLIK(CLIK):
    r"""Pseudo-inverse CLIK with PD feedback (Zheng et al. 2019, eq. 18); see the module docstring.

    Args:
        kd: :math:`K_d` ≥ 0, weight of the twist error of the previous command (0: plain CLIK).
    """

    name = "pinv"

    def __init__(
        self, robot, position_gain: float = 50.0, orientation_gain: float = 50.0, kd: float = 0.0, dt: float = 0.001
    ):
        super().__init__(robot, position_gain, orientation_gain, dt)
        self.kd = number(kd, "kd")
        self._v_prev = np.zeros(self.robot.dof)

    def _velocity(self, state: State, b: np.ndarray) -> np.ndarray:
        if self.kd:
            b = b + self.kd * (self.twist - state.J @ self._v_prev)
        self._v_prev = np.linalg.pinv(state.J) @ b
        return self._v_prev


class VelocityOnly(PseudoInverseCLIK):
    r"""Velocity-only feedforward :math:`\dot q = J^+ \dot x_d` (Zheng et al. 2019, Fig. 3a): drifts."""

    name = "velocity-only"

    def __init__(self, robot, dt: float = 0.001):
        super().__init__(robot, 0.0, 0.0, 0.0, dt)


class DampedLeastSquares(CLIK):
    r""":math:`\dot q = J^T (J J^T + \lambda^2 I)^{-1} (\dot x_d + K e)`.

    Args:
        damping: λ (units of J: m and rad per rad).
    """

    name = "dls"

    def __init__(
        self,
        robot,
        position_gain: float = 50.0,
        orientation_gain: float = 50.0,
        damping: float = 1e-2,
        dt: float = 0.001,
    ):
        super().__init__(robot, position_gain, orientation_gain, dt)
        self.damping = number(damping, "damping")

    def _velocity(self, state: State, b: np.ndarray) -> np.ndarray:
        J = state.J
        return J.T @ np.linalg.solve(J @ J.T + self.damping**2 * np.eye(6), b)


class GradientProjection(CLIK):
    r""":math:`\dot q = J^+ (\dot x_d + K e) + k (I - J^+ J) \nabla m` (Yoshikawa).

    Args:
        null_gain: k (rad/s per unit of ∇m).
    """

    name = "gradient-projection"

    def __init__(
        self,
        robot,
        position_gain: float = 50.0,
        orientation_gain: float = 50.0,
        null_gain: float = 1.0,
        dt: float = 0.001,
    ):
        super().__init__(robot, position_gain, orientation_gain, dt)
        self.null_gain = number(null_gain, "null_gain")

    def _velocity(self, state: State, b: np.ndarray) -> np.ndarray:
        J = state.J
        Jp = np.linalg.pinv(J)
        grad = state.manipulability_gradient()
        return Jp @ b + self.null_gain * (grad - Jp @ (J @ grad))
