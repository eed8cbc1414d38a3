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

from abc import ABC, abstractmethod

import casadi as ca
import numpy as np

from qpik.compiled import Compiled
from qpik.control.state import State, SymState, _unique, evaluate
from qpik.validate import finite_array, pose

_EMPTY = np.zeros(0)


def log_expr(R: ca.SX) -> ca.SX:
    r"""Rotation vector :math:`\omega = \theta u` (3,) of an SX rotation matrix ``R`` (3, 3), with θ ∈ [0, π].

    :math:`\sin\theta\,u = \mathrm{vee}(R - R^T)/2` and :math:`\cos\theta = (\mathrm{tr} R - 1)/2`,
    so :math:`\theta = \mathrm{atan2}(\|\mathrm{vee}\|, \cos\theta)` is accurate at every angle.
    Away from π (cos θ > −0.9) the vector is :math:`\mathrm{vee}\,\theta/\sin\theta` (a series
    below θ = 1e-4); near π, where vee loses its digits, the axis comes from the symmetric part
    :math:`(R + R^T)/2 - \cos\theta\,I = (1 - \cos\theta)\,u u^T` (its largest diagonal
    column) with the sign of vee. The branches are selections (both are evaluated).
    """
    w = 0.5 * ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])
    s = ca.sqrt(ca.dot(w, w))
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    theta = ca.atan2(s, c)
    scale = ca.if_else(theta < 1e-4, 1.0 + theta * theta / 6.0 + 7.0 * theta**4 / 360.0, theta / s)
    B = 0.5 * (R + R.T) - c * ca.SX.eye(3)
    b0, b1, b2 = B[0, 0], B[1, 1], B[2, 2]
    first = ca.logic_and(b0 >= b1, b0 >= b2)
    col = ca.if_else(first, B[:, 0], ca.if_else(b1 >= b2, B[:, 1], B[:, 2]))
    bkk = ca.if_else(first, b0, ca.if_else(b1 >= b2, b1, b2))
    u = col / ca.sqrt(bkk * (1.0 - c))
    u = ca.if_else(ca.dot(u, w) < 0.0, -u, u)
    return ca.if_else(c > -0.9, w * scale, theta * u)



def pose_error_expr(T: ca.SX, pose_: ca.SX) -> ca.SX:
    r"""World-frame pose error :math:`[p^* - p;\ \log(R^* R^T)]` (6,) of ``pose_`` toward ``T`` (SX, (≥3, 4) each)."""
    return ca.vertcat(T[:3, 3] - pose_[:3, 3], log_expr(ca.mtimes(T[:3, :3], pose_[:3, :3].T)))


_NUMERIC: dict[str, Compiled] = {}


def _numeric(name: str) -> Compiled:
    """The compiled numeric form of :func:`log_expr` (``"log"``) or :func:`pose_error_expr` (``"pose_error"``)."""
    fn = _NUMERIC.get(name)
    if fn is None:
        if name == "log":
            R = ca.SX.sym("R", 3, 3)
            fn = Compiled(ca.Function("so3_log", [R], [log_expr(R)]))
        else:
            T, C = ca.SX.sym("T", 4, 4), ca.SX.sym("C", 4, 4)
            fn = Compiled(ca.Function("pose_error", [T, C], [pose_error_expr(T, C)]))
        _NUMERIC[name] = fn
    return fn


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) of a rotation matrix ``R`` (3, 3): :func:`log_expr`, compiled."""
    return _numeric("log")(np.asarray(R, dtype=float))[0].copy()


def pose_error(target: np.ndarray, current: np.ndarray) -> np.ndarray:
    r"""World-frame pose error :math:`[p^* - p;\ \log(R^* R^T)]` (6,) of ``current`` toward ``target`` (4, 4)."""
    return _numeric("pose_error")(target, current)[0].copy()


class Task(ABC):
    """A cost term :math:`\\tfrac12 v^T P v + c^T v` of the QP (v in rad/s).

    A task holds its math once, as a CasADi expression (:meth:`expr`) of the symbolic
    state and of its own parameters (:meth:`params`: targets, gains, weights — inputs of
    the compiled function, so changing them never recompiles). The controller composes
    every task's expression into one compiled function; :meth:`compute` evaluates the
    same expression on a numeric :class:`State`.
    """

    name: str = "task"

    def param_size(self, n: int) -> int:
        """Number of parameters for an arm with n joints (default 0)."""
        return 0

    def params(self) -> np.ndarray:
        """The current parameters, a flat (param_size,) vector."""
        return _EMPTY

    def structure(self) -> tuple:
        """What fixes the expression's form beyond the parameters (part of the compiled function's key).

        The default is unique to this object (its compiled function is never shared);
        subclasses whose form depends only on their parameters return ``()``.
        """
        return (_unique(self),)

    @abstractmethod
    def expr(self, s: SymState, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        """``(P, c)``: (n, n) symmetric PSD and (n,) SX, given the state ``s`` and the parameters ``p``."""

    def bind(self, s: SymState) -> tuple[ca.SX, ca.SX]:
        """:meth:`expr` with this task's parameters declared as inputs of ``s``."""
        return self.expr(s, s.params_of(self))

    def compute(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """``(P, c)``: (n, n) and (n,) for the configuration in ``state`` (:meth:`expr` on numbers)."""
        P, c = evaluate(self, state, lambda s: list(self.bind(s)))
        return P, c.reshape(-1)


class FrameTask(Task):
    r"""Track an end-effector pose and twist.

    Cost :math:`\|J v - (v_{ff} + K e)\|^2_W` with the geometric Jacobian ``J`` (6, n),
    the pose error :math:`e = [p^* - p;\ \log(R^* R^T)]` (world frame, :func:`pose_error`),
    :math:`K = \mathrm{diag}(k_p I_3, k_o I_3)` (1/s) and
    :math:`W = \mathrm{diag}(w_p I_3, w_o I_3)`. With ``v = J⁺(v_ff + K e)`` the error
    obeys :math:`\dot e = -K e` (closed-loop IK, seed 002 eq. 18 with K_d = 1).

    Parameters (30): the target's first three rows (12, row-major), twist, gain and weight (6 each).

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

    def structure(self) -> tuple:
        return ()

    def param_size(self, n: int) -> int:
        return 30

    def params(self) -> np.ndarray:
        if self.target is None:
            raise ValueError("FrameTask: no target set (call set_target)")
        return np.concatenate((self.target[:3].ravel(), self.twist, self.gain, self.weight))

    def error_expr(self, s: SymState, p: ca.SX) -> ca.SX:
        """Pose error e (6,) ``[m; rad]`` of the end-effector toward the target (SX)."""
        return pose_error_expr(ca.reshape(p[:12], 4, 3).T, s.pose)

    def expr(self, s: SymState, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        twist, gain, weight = p[12:18], p[18:24], p[24:30]
        b = twist + gain * self.error_expr(s, p)
        WJ = ca.mtimes(ca.diag(weight), s.J)
        return 2.0 * ca.mtimes(s.J.T, WJ), -2.0 * ca.mtimes(WJ.T, b)

    def error(self, state: State) -> np.ndarray:
        """Pose error e (6,) ``[m; rad]`` of the current end-effector toward the target."""
        (e,) = evaluate(self, state, lambda s: [self.error_expr(s, s.params_of(self))])
        return e.reshape(-1)


class PostureTask(Task):
    r"""Pull the joints toward a reference: :math:`w\,\|v - k (q_{ref} - q)\|^2`.

    Parameters (n + 2): q_ref, k, w.

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

    def structure(self) -> tuple:
        return ()

    def param_size(self, n: int) -> int:
        return n + 2

    def params(self) -> np.ndarray:
        return np.concatenate((self.q_ref, (self.gain, self.weight)))

    def expr(self, s: SymState, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        n = s.n
        k, w = p[n], p[n + 1]
        return 2.0 * w * ca.SX.eye(n), (-2.0 * w * k) * (p[:n] - s.q)


class DampingTask(Task):
    r"""Velocity damping :math:`\lambda \|v\|^2` (λ per (rad/s)²): regularises the null space."""

    name = "damping"

    def __init__(self, weight: float = 1e-4):
        self.weight = float(weight)

    def structure(self) -> tuple:
        return ()

    def param_size(self, n: int) -> int:
        return 1

    def params(self) -> np.ndarray:
        return np.array((self.weight,))

    def expr(self, s: SymState, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        return 2.0 * p[0] * ca.SX.eye(s.n), ca.SX.zeros(s.n)


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

    def param_size(self, n: int) -> int:
        return 1

    def params(self) -> np.ndarray:
        return np.array((self.weight,))

    def structure(self) -> tuple:
        return (self.translational,)

    def expr(self, s: SymState, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        """∇m(q) from :func:`qpik.robots.dh.manipulability_gradient_expr`, traced into the state."""
        return ca.SX.zeros(s.n, s.n), -p[0] * s.manipulability_gradient(self.translational)
