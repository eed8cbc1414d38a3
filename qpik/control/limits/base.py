r"""Limits: the constraints of the QP over the joint velocity ``v`` (n,), rad/s.

Two kinds:

- :class:`BoxLimit` gives bounds ``lb ≤ v ≤ ub`` (n,). The QP intersects every
  non-cap box, then clips the result into the *cap* boxes (:class:`~qpik.control.limits.velocity.VelocityLimit`):
  ``lb = clip(lb, cap_lb, cap_ub)``, ``ub = clip(ub, cap_lb, cap_ub)``. Clipping is
  monotone, so ``lb ≤ ub`` whenever the non-cap boxes are consistent — which their
  :meth:`Limit.check` proves at construction — and an arm past a position limit gets
  the bound that moves it back as fast as the velocity limit allows.
- :class:`RowLimit` gives a fixed number of rows ``l ≤ A v ≤ u`` (m, n); a row that
  does not apply this step has ``l = −∞, u = +∞``, so the sparsity pattern never changes.
  It sees the final box, so it can keep each row reachable inside it.

Like the tasks, a limit holds its math once, as a CasADi expression (``expr``) of the
symbolic state and of its own parameters (inputs of the controller's compiled function);
:meth:`BoxLimit.bounds` and :meth:`RowLimit.rows` evaluate the same expression on a
numeric :class:`~qpik.control.state.State`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.control.state import State, SymState, Traced, evaluate
from qpik.core.layout import Blocks

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


class Limit(Traced):
    """A constraint family of the QP (subclass :class:`BoxLimit` or :class:`RowLimit`)."""

    name: str = "limit"

    def check(self, robot: Robot, dt: float) -> None:
        """Raise :class:`InfeasibleError` if the limit can never be met (called at construction).

        The default accepts any robot and dt.
        """
        return None

    def observe(self, v: np.ndarray) -> None:
        """Called by the controller with each step's command ``v`` (n,), rad/s (the default keeps nothing)."""
        return None

    def parameters(self, s: SymState) -> Blocks:
        """This limit's parameters declared as inputs of ``s`` (SX blocks of :meth:`param_layout`)."""
        return s.params_of(self)


class BoxLimit(Limit, ABC):
    """Bounds ``lb ≤ v ≤ ub`` (n,) on the joint velocity (rad/s)."""

    cap: bool = False  # cap boxes (velocity limits) clip every other box
    rank: int = 0  # caps clip in increasing rank, the last wins: jerk (-2), acceleration (-1), velocity (0)

    @abstractmethod
    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        """``(lb, ub)``, each (n,) SX, rad/s; ``±inf`` for no bound."""

    def bounds(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """``(lb, ub)``, each (n,), rad/s, for the configuration in ``state`` (:meth:`expr` on numbers)."""
        self.check(state.robot, state.dt)
        lb, ub = evaluate(self, state, lambda s: list(self.expr(s, self.parameters(s))))
        return lb.reshape(-1), ub.reshape(-1)


class RowLimit(Limit, ABC):
    """A fixed number of rows ``l ≤ A v ≤ u``."""

    @abstractmethod
    def size(self, robot: Robot) -> int:
        """Number of rows m (constant for a controller)."""

    @abstractmethod
    def row_names(self, robot: Robot) -> list[str]:
        """One name per row (for :attr:`StepInfo.active`)."""

    @abstractmethod
    def expr(self, s: SymState, p: Blocks, lb: ca.SX, ub: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """``(A, l, u)``: (m, n), (m,), (m,) SX, given the step's final box ``lb ≤ v ≤ ub`` (n,)."""

    def recovery_expr(self, s: SymState, p: Blocks) -> ca.SX:
        """(m,) SX, ≥ 0: the part of each row's lower bound that asks to recover from inside its safety distance
        (the default: none). When rows conflict, the controller gives up these parts first."""
        return ca.SX.zeros(self.size(s.kin.robot))

    def rows(self, state: State, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, l, u)``: (m, n), (m,), (m,) for ``state`` and the final box (:meth:`expr` on numbers)."""
        self.check(state.robot, state.dt)
        lb, ub = (np.asarray(x, dtype=float).reshape(-1) for x in (lb, ub))
        A, lo, hi = evaluate(self, state, lambda s, a, b: list(self.expr(s, self.parameters(s), a, b)), lb, ub)
        return A, lo.reshape(-1), hi.reshape(-1)
