r"""Tasks: the cost terms of the QP over the joint velocity ``v`` (n,), rad/s.

Every task adds :math:`\tfrac12 v^T P_i v + c_i^T v` to the cost
(:meth:`Task.compute`). Least-squares tasks are written as
:math:`\|A v - b\|^2_W = v^T A^T W A v - 2 b^T W A v + b^T W b`, so
:math:`P_i = 2 A^T W A`, :math:`c_i = -2 A^T W b` (the constant is dropped).

Pose errors are world-frame: :func:`pose_error` gives
:math:`e = [p^* - p;\ \log(R^* R^T)]` (m; rad), the quantity that the geometric
Jacobian's rows ``[v; ω]`` change at first order: :math:`\dot e = \dot x^*_d - J \dot q`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from qpik.control.state import State
from qpik.validate import finite_array, pose

_EYE3 = np.eye(3)
_EYES: dict[tuple[int, float], np.ndarray] = {}
_ZEROS: dict[int, np.ndarray] = {}


def _eye(n: int, scale: float = 1.0) -> np.ndarray:
    """A cached read-only ``scale·I`` (n, n) (tasks with a constant P return it without a new array)."""
    eye = _EYES.get((n, scale))
    if eye is None:
        eye = _EYES[n, scale] = scale * np.eye(n)
        eye.flags.writeable = False
    return eye


def _zeros(n: int) -> np.ndarray:
    """A cached read-only zero vector (n,)."""
    z = _ZEROS.get(n)
    if z is None:
        z = _ZEROS[n] = np.zeros(n)
        z.flags.writeable = False
    return z


def so3_log(R: np.ndarray) -> np.ndarray:
    r"""Rotation vector :math:`\omega = \theta u` of a rotation matrix ``R`` (3, 3), with θ ∈ [0, π].

    :math:`\sin\theta\,u = \mathrm{vee}(R - R^T)/2` and :math:`\cos\theta = (\mathrm{tr} R - 1)/2`,
    so :math:`\theta = \mathrm{atan2}(\|\mathrm{vee}\|, \cos\theta)` is accurate at every angle.
    Away from π the vector is :math:`\mathrm{vee}\,\theta/\sin\theta` (a series near 0);
    near π, where vee loses its digits, the axis comes from the symmetric part
    :math:`(R + R^T)/2 - \cos\theta\,I = (1 - \cos\theta)\,u u^T` with the sign of vee.
    """
    return _log(np.asarray(R, dtype=float).tolist())


def _log(R: list[list[float]]) -> np.ndarray:
    """:func:`so3_log` of a rotation given as nested lists (Python floats: a few µs, no numpy temporaries)."""
    w = (0.5 * (R[2][1] - R[1][2]), 0.5 * (R[0][2] - R[2][0]), 0.5 * (R[1][0] - R[0][1]))
    s = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    c = 0.5 * (R[0][0] + R[1][1] + R[2][2] - 1.0)
    theta = math.atan2(s, c)
    if c > -0.9:  # θ < ~2.69 rad: sin θ is not small unless θ is, and then the series is exact
        scale = 1.0 + theta * theta / 6.0 + 7.0 * theta**4 / 360.0 if theta < 1e-4 else theta / s
        return np.array((w[0] * scale, w[1] * scale, w[2] * scale))
    Rm = np.array(R)
    B = 0.5 * (Rm + Rm.T) - c * _EYE3
    k = int(np.argmax(np.diag(B)))
    u = B[:, k] / math.sqrt(B[k, k] * (1.0 - c))
    if u @ w < 0.0:
        u = -u
    return theta * u


def pose_error(target: np.ndarray, current: np.ndarray) -> np.ndarray:
    r"""World-frame pose error :math:`[p^* - p;\ \log(R^* R^T)]` (6,) of ``current`` toward ``target`` (4, 4)."""
    T, C = target.tolist(), current.tolist()
    # R* Rᵀ: entry (i, j) is row i of R* dotted with row j of R
    R = [[T[i][0] * C[j][0] + T[i][1] * C[j][1] + T[i][2] * C[j][2] for j in range(3)] for i in range(3)]
    e = np.empty(6)
    e[:3] = (T[0][3] - C[0][3], T[1][3] - C[1][3], T[2][3] - C[2][3])
    e[3:] = _log(R)
    return e


class Task(ABC):
    """A cost term :math:`\\tfrac12 v^T P v + c^T v` of the QP (v in rad/s)."""

    name: str = "task"

    @abstractmethod
    def compute(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """``(P, c)``: (n, n) symmetric PSD and (n,) for the configuration in ``state``."""


class FrameTask(Task):
    r"""Track an end-effector pose and twist.

    Cost :math:`\|J v - (v_{ff} + K e)\|^2_W` with the geometric Jacobian ``J`` (6, n),
    the pose error :math:`e = [p^* - p;\ \log(R^* R^T)]` (world frame, :func:`pose_error`),
    :math:`K = \mathrm{diag}(k_p I_3, k_o I_3)` (1/s) and
    :math:`W = \mathrm{diag}(w_p I_3, w_o I_3)`. With ``v = J⁺(v_ff + K e)`` the error
    obeys :math:`\dot e = -K e` (closed-loop IK, seed 002 eq. 18 with K_d = 1).

    Args:
        target: (4, 4) target pose in the base frame (may be set later by :meth:`set_target`).
        position_gain, orientation_gain: :math:`k_p, k_o`, 1/s.
        position_weight, orientation_weight: :math:`w_p` (per m²/s²), :math:`w_o` (per rad²/s²).
        twist: (6,) feedforward twist ``[v; ω]`` of the target, base frame (m/s; rad/s).
    """

    name = "frame"

    def __init__(
        self,
        target: np.ndarray | None = None,
        position_gain: float = 50.0,
        orientation_gain: float = 50.0,
        position_weight: float = 1.0,
        orientation_weight: float = 0.1,
        twist: np.ndarray | None = None,
    ):
        self.target: np.ndarray | None = None
        self.twist = np.zeros(6)
        self.last_error: np.ndarray | None = None  # e of the last compute, [m; rad]
        self.gain = np.repeat([float(position_gain), float(orientation_gain)], 3)
        self.weight = np.repeat([float(position_weight), float(orientation_weight)], 3)
        if np.any(self.weight < 0) or np.any(self.gain < 0):
            raise ValueError("FrameTask: gains and weights must be >= 0")
        if target is not None:
            self.set_target(target, twist)

    def set_target(self, target: np.ndarray, twist: np.ndarray | None = None) -> None:
        """Set the target pose (4, 4) and feedforward twist (6,) ``[v; ω]`` (zero if omitted)."""
        self.target = pose(target, "target")[0]
        self.twist = np.zeros(6) if twist is None else finite_array(twist, "twist", (6,)).copy()

    def error(self, state: State) -> np.ndarray:
        """Pose error e (6,) ``[m; rad]`` of the current end-effector toward the target."""
        if self.target is None:
            raise ValueError("FrameTask: no target set (call set_target)")
        return pose_error(self.target, state.pose)

    def compute(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        self.last_error = self.error(state)
        b = self.twist + self.gain * self.last_error
        WJ = self.weight[:, None] * state.J
        return 2.0 * (state.J.T @ WJ), -2.0 * (b @ WJ)


class PostureTask(Task):
    r"""Pull the joints toward a reference: :math:`w\,\|v - k (q_{ref} - q)\|^2`.

    Args:
        q_ref: (n,) reference configuration, rad.
        gain: k, 1/s.
        weight: w, per (rad/s)².
    """

    name = "posture"

    def __init__(self, q_ref: np.ndarray, gain: float = 1.0, weight: float = 1e-3):
        self.q_ref = finite_array(q_ref, "q_ref", (None,)).copy()
        self.gain = float(gain)
        self.weight = float(weight)

    def compute(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        return _eye(len(state.q), 2.0 * self.weight), (-2.0 * self.weight * self.gain) * (self.q_ref - state.q)


class DampingTask(Task):
    r"""Velocity damping :math:`\lambda \|v\|^2` (λ per (rad/s)²): regularises the null space."""

    name = "damping"

    def __init__(self, weight: float = 1e-4):
        self.weight = float(weight)

    def compute(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        n = len(state.q)
        return _eye(n, 2.0 * self.weight), _zeros(n)


class ManipulabilityTask(Task):
    r"""Manipulability ascent: the linear cost :math:`-w\,\nabla m(q)^T v`.

    :math:`m = \sqrt{\det(J J^T)}` (seed 002 eq. 6; ``translational`` uses :math:`J_v`),
    :math:`\partial m/\partial q_k = m\,\mathrm{tr}((JJ^T)^{-1} J H_k^T)` from the
    kinematic Hessian :math:`H_k = \partial J/\partial q_k`. Minimising
    :math:`-w \nabla m^T v` moves v along the gradient wherever the other terms leave
    freedom (its magnitude is set by the quadratic terms).

    Args:
        weight: w (s/rad per unit of m).
        translational: use the translational part of the Jacobian only.
    """

    name = "manipulability"

    def __init__(self, weight: float = 1e-2, translational: bool = False):
        self.weight = float(weight)
        self.translational = bool(translational)

    def gradient(self, state: State) -> np.ndarray:
        """∇m(q) (n,), per rad (:func:`qpik.robots.dh.manipulability_gradient_expr`, compiled into the state)."""
        return state.manipulability_gradient(self.translational)

    def compute(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        n = len(state.q)
        return _eye(n, 0.0), -self.weight * self.gradient(state)
