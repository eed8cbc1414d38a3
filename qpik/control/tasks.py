r"""Tasks: the cost terms of the QP over the joint velocity ``v`` (n,), rad/s.

Every task adds :math:`\tfrac12 v^T P_i v + c_i^T v` to the cost
(:meth:`Task.compute`). Least-squares tasks are written as
:math:`\|A v - b\|^2_W = v^T A^T W A v - 2 b^T W A v + b^T W b`, so
:math:`P_i = 2 A^T W A`, :math:`c_i = -2 A^T W b` (the constant is dropped).

Pose errors are world-frame by default: :func:`pose_error` gives
:math:`e = [p^* - p;\ \log(R^* R^T)]` (m; rad; :mod:`qpik.algebra.lie`), the quantity that the geometric
Jacobian's rows ``[v; ω]`` change at first order: :math:`\dot e = \dot x^*_d - J \dot q`.
``FrameTask(error="se3")`` uses the body-frame SE(3) error of mink/pink instead,
:math:`e = \log(T^{-1} T^*)` (:func:`se3_log_expr`, :func:`se3_ljacinv_expr`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Literal

import casadi as ca
import numpy as np

from qpik.algebra.lie import pose_error_expr, se3_ljacinv_expr, se3_log_expr
from qpik.control.state import State, SymState, Traced, evaluate
from qpik.core.errors import InputError
from qpik.core.layout import Blocks, Layout
from qpik.core.validate import finite_array, number, single_pose
from qpik.geometry.distance import ObstacleSet
from qpik.objectives import Context, Objective, resolve
from qpik.robots.robot import as_robot


class Task(Traced, ABC):
    """A cost term :math:`\\tfrac12 v^T P v + c^T v` of the QP (v in rad/s).

    A task holds its math once, as a CasADi expression (:meth:`expr`) of the symbolic
    state and of its own parameters (:meth:`param_layout`, :meth:`param_values`: targets, gains, weights —
    inputs of the compiled function, so changing them never recompiles). The controller composes
    every task's expression into one compiled function; :meth:`compute` evaluates the
    same expression on a numeric :class:`State`.
    """

    name: str = "task"

    @abstractmethod
    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        """``(P, c)``: (n, n) symmetric PSD and (n,) SX, given the state ``s`` and the parameters ``p`` (SX blocks
        of :meth:`param_layout`, by name)."""

    def bind(self, s: SymState) -> tuple[ca.SX, ca.SX]:
        """:meth:`expr` with this task's parameters declared as inputs of ``s``."""
        return self.expr(s, s.params_of(self))

    def compute(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """``(P, c)``: (n, n) and (n,) for the configuration in ``state`` (:meth:`expr` on numbers)."""
        P, c = evaluate(self, state, lambda s: list(self.bind(s)))
        return P, c.reshape(-1)


class FrameTask(Task):
    r"""Track an end-effector pose and twist.

    Cost :math:`\|A v - (f + K e)\|^2_W` with :math:`K = \mathrm{diag}(k_p I_3, k_o I_3)` (1/s),
    :math:`W = \mathrm{diag}(w_p I_3, w_o I_3)`, the pose error ``e`` (m; rad) and its Jacobian ``A``
    (6, n) of the chosen convention (``error``): :math:`\dot e = f - A \dot q` with the feed-forward ``f``:

    - ``"world"``: :math:`e = [p^* - p;\ \log(R^* R^T)]` (base frame, :func:`pose_error`), ``A = J`` the
      geometric Jacobian, the feed-forward :math:`f = \dot x^*` the target's twist. Exact for the
      translation, first order in e for the rotation (the rate of log brings SO(3) Jacobians of e).
    - ``"se3"``: the body-frame SE(3) error of mink/pink, :math:`e = \log(T^{-1} T^*)`
      (:func:`se3_log_expr`, ee frame, [translation; rotation]),
      :math:`A = J_l^{-1}(e)\, J_b` with the ee-frame Jacobian :math:`J_b = [R^T J_v;\ R^T J_\omega]`
      (:func:`se3_ljacinv_expr`; mink's ``jlog(T^{*-1} T) J_b``), and the feed-forward
      :math:`f = J_r^{-1}(e)\, [R^{*T} v^*;\ R^{*T} \omega^*]`, the target's base-frame twist as its body
      twist, mapped through the error: exact, :math:`\dot e = f - A \dot q`.

    With ``A v = f + K e`` the error obeys :math:`\dot e = -K e` (closed-loop IK, Zheng et al. 2019 eq. 18 with
    K_d = 1; exactly for ``"se3"``). mink's ``FrameTask`` with costs :math:`c_p, c_o`, gain g and step dt
    is ``error="se3"`` with :math:`w = c^2`, :math:`k = g/dt`.

    Parameters: the target's first three rows (3, 4), twist, gain and weight (6 each).

    Args:
        target: (4, 4) target pose in the base frame (may be set later by :meth:`set_target`).
        position_gain, orientation_gain: :math:`k_p, k_o`, 1/s (finite, ≥ 0).
        position_weight, orientation_weight: :math:`w_p` (per m²/s²), :math:`w_o` (per rad²/s²) (finite, ≥ 0).
        twist: (6,) feedforward twist ``[v; ω]`` of the target, base frame (m/s; rad/s), in both conventions.
        error: the error convention, ``"world"`` or ``"se3"`` (fixed: it sets the compiled expression's form).

    Attributes:
        convention: ``error`` as given.
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
        error: Literal["world", "se3"] = "world",
    ):
        if not isinstance(error, str) or error not in ("world", "se3"):
            raise InputError(f"error: FrameTask error must be 'world' or 'se3', got {error!r}")
        self.convention = error
        self.target: np.ndarray | None = None
        self.twist = np.zeros(6)
        self.gain = np.repeat([number(position_gain, "position_gain"), number(orientation_gain, "orientation_gain")], 3)
        self.weight = np.repeat(
            [number(position_weight, "position_weight"), number(orientation_weight, "orientation_weight")], 3
        )
        if target is not None:
            self.set_target(target, twist)

    def set_target(self, target: np.ndarray, twist: np.ndarray | None = None) -> None:
        """Set the target pose (4, 4) and feedforward twist (6,) ``[v; ω]``, base frame (zero if omitted)."""
        self.target = single_pose(target, "target")
        self.twist = np.zeros(6) if twist is None else finite_array(twist, "twist", (6,)).copy()

    def structure(self) -> tuple:
        """The convention: ``()`` for ``"world"``, ``("se3",)`` for the body-frame error."""
        return () if self.convention == "world" else (self.convention,)

    def param_layout(self, n: int) -> Layout:
        return Layout(target=(3, 4), twist=6, gain=6, weight=6)

    def param_values(self) -> dict[str, np.ndarray]:
        if self.target is None:
            raise InputError("target: FrameTask has no target (call set_target)")
        return {"target": self.target[:3], "twist": self.twist, "gain": self.gain, "weight": self.weight}

    def error_expr(self, s: SymState, p: Blocks) -> ca.SX:
        """Pose error e (6,) ``[m; rad]`` of the end-effector toward the target (SX), in the task's convention."""
        target = p.target
        if self.convention == "world":
            return pose_error_expr(target, s.pose)
        R = s.pose[:3, :3]
        # T⁻¹ T* = [Rᵀ R*, Rᵀ (p* − p)]
        return se3_log_expr(ca.horzcat(ca.mtimes(R.T, target[:, :3]), ca.mtimes(R.T, target[:, 3] - s.pose[:3, 3])))

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        twist, gain, weight = p.twist, p.gain, p.weight
        e = self.error_expr(s, p)
        if self.convention == "world":
            A, b = s.J, twist + gain * e
        else:
            R, R_t = s.pose[:3, :3], p.target[:, :3]
            J_b = ca.vertcat(ca.mtimes(R.T, s.J[:3, :]), ca.mtimes(R.T, s.J[3:, :]))
            twist_b = ca.vertcat(ca.mtimes(R_t.T, twist[:3]), ca.mtimes(R_t.T, twist[3:]))
            A, b = ca.mtimes(se3_ljacinv_expr(e), J_b), ca.mtimes(se3_ljacinv_expr(-e), twist_b) + gain * e
        WA = ca.mtimes(ca.diag(weight), A)
        return 2.0 * ca.mtimes(A.T, WA), -2.0 * ca.mtimes(WA.T, b)

    def error(self, state: State) -> np.ndarray:
        """Pose error e (6,) ``[m; rad]`` of the current end-effector toward the target, in the task's convention."""
        (e,) = evaluate(self, state, lambda s: [self.error_expr(s, s.params_of(self))])
        return e.reshape(-1)


class PostureTask(Task):
    r"""Pull the joints toward a reference: :math:`w\,\|v - k (q_{ref} - q)\|^2`.

    Parameters (n + 2): q_ref, k, w.

    Args:
        q_ref: (n,) reference configuration, rad.
        gain: k, 1/s (finite, ≥ 0).
        weight: w, per (rad/s)² (finite, ≥ 0).
    """

    name = "posture"

    def __init__(self, q_ref: np.ndarray, gain: float = 1.0, weight: float = 1e-3):
        self.q_ref = finite_array(q_ref, "q_ref", (None,)).copy()
        self.gain = number(gain, "gain")
        self.weight = number(weight, "weight")

    def set_target(self, q_ref: np.ndarray) -> None:
        """Set the reference configuration (n,), rad (same length as before: the QP's form is fixed)."""
        q_ref = finite_array(q_ref, "q_ref", (len(self.q_ref),))
        self.q_ref = q_ref.copy()

    def structure(self) -> tuple:
        return ()

    def param_layout(self, n: int) -> Layout:
        return Layout(q_ref=n, gain=(), weight=())

    def param_values(self) -> dict[str, object]:
        return {"q_ref": self.q_ref, "gain": self.gain, "weight": self.weight}

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        return 2.0 * p.weight * ca.SX.eye(s.n), (-2.0 * p.weight * p.gain) * (p.q_ref - s.q)


class DampingTask(Task):
    r"""Velocity damping :math:`\lambda \|v\|^2` (λ per (rad/s)², finite, ≥ 0): regularises the null space."""

    name = "damping"

    def __init__(self, weight: float = 1e-4):
        self.weight = number(weight, "damping weight")

    def structure(self) -> tuple:
        return ()

    def param_layout(self, n: int) -> Layout:
        return Layout(weight=())

    def param_values(self) -> dict[str, object]:
        return {"weight": self.weight}

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        return 2.0 * p.weight * ca.SX.eye(s.n), ca.SX.zeros(s.n)


class ManipulabilityTask(Task):
    r"""Manipulability ascent: the linear cost :math:`-w\,\nabla m(q)^T v`.

    :math:`m = \sqrt{\det(J J^T)}` (Zheng et al. 2019 eq. 6; ``translational`` uses :math:`J_v`),
    :math:`\partial m/\partial q_k = m\,\mathrm{tr}((JJ^T)^{-1} J H_k^T)` from the
    kinematic Hessian :math:`H_k = \partial J/\partial q_k`. Minimising
    :math:`-w \nabla m^T v` moves v along the gradient wherever the other terms leave
    freedom (its magnitude is set by the quadratic terms).

    Args:
        weight: w (s/rad per unit of m; finite, ≥ 0).
        translational: use the translational part of the Jacobian only.
    """

    name = "manipulability"

    def __init__(self, weight: float = 1e-2, translational: bool = False):
        self.weight = number(weight, "manipulability weight")
        self.translational = bool(translational)

    def param_layout(self, n: int) -> Layout:
        return Layout(weight=())

    def param_values(self) -> dict[str, object]:
        return {"weight": self.weight}

    def structure(self) -> tuple:
        return (self.translational,)

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        """∇m(q) from :func:`qpik.robots.manipulability.manipulability_gradient_expr`, traced into the state."""
        return ca.SX.zeros(s.n, s.n), -p.weight * s.manipulability_gradient(self.translational)


class ObjectiveTask(Task):
    r"""An objective of :mod:`qpik.objectives` as a secondary task: the linear cost :math:`w\,\nabla f(q)^T v`.

    Minimising :math:`w \nabla f^T v` moves v down the gradient wherever the other terms leave
    freedom, as :class:`ManipulabilityTask` does for −m. ∇f is CasADi's exact derivative of the
    objective's expression (for capsule–obstacle distances, :math:`n^T J_p` at the closest points,
    :class:`qpik.objectives.Context`). At a minimum of f over the self-motion, ∇f lies in the row
    space of J, so with a dominant frame task the step is 0 (:mod:`qpik.checks.crosscheck` checks this).

    Parameters: w, the objective's parameters, q_ref (n), the obstacles' parameters.

    Args:
        robot: the arm (fixes the objective's parameters).
        objective: a smooth objective, or its name (:func:`qpik.objectives.resolve`); an epigraph term
            has no gradient at its kinks, where one active piece's is used.
        weight: w ≥ 0, s/rad per unit of f.
        q_ref: (n,) reference configuration of a :class:`~qpik.objectives.ReferenceDistance` term, rad.
        obstacles: shapes for the objective's clearance terms (world frame).

    Raises:
        InputError: ``robot`` is not a Robot, ``objective`` is neither an objective nor a known name,
            ``weight`` is not a finite number ≥ 0, or ``q_ref`` has NaN or the wrong shape.
    """

    name = "objective"

    def __init__(
        self, robot, objective: Objective | str, weight: float = 1e-2, q_ref: np.ndarray | None = None, obstacles=()
    ):
        self.robot, self.objective = as_robot(robot), resolve(objective)
        self.weight = number(weight, "weight")
        self.q_ref = np.zeros(robot.dof) if q_ref is None else finite_array(q_ref, "q_ref", (robot.dof,)).copy()
        self.obstacles = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)

    def structure(self) -> tuple:
        return (self.objective.key(), self.obstacles.kinds)

    def param_layout(self, n: int) -> Layout:
        return Layout(weight=(), objective=self.objective.param_size(self.robot), q_ref=n,
                      obstacles=len(self.obstacles.params))  # fmt: skip

    def param_values(self) -> dict[str, object]:
        return {"weight": self.weight, "objective": self.objective.params(self.robot), "q_ref": self.q_ref,
                "obstacles": self.obstacles.params}  # fmt: skip

    def gradient_expr(self, s: SymState, p: Blocks) -> ca.SX:
        """∇f (n,) at the state's q (SX)."""
        w = ca.SX.sym("witness", s.n)
        ctx = Context(self.robot, s.q, p.q_ref, self.obstacles, p.obstacles, witness=w)
        grad = ca.gradient(self.objective.expr(ctx, p.objective), s.q)
        return ca.substitute(grad, w, s.q)

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        return ca.SX.zeros(s.n, s.n), p.weight * self.gradient_expr(s, p)
