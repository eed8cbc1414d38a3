r"""Limits: the constraints of the QP over the joint velocity ``v`` (n,), rad/s.

Two kinds:

- :class:`BoxLimit` gives bounds ``lb ≤ v ≤ ub`` (n,). The QP intersects every
  non-cap box, then clips the result into the *cap* boxes (:class:`VelocityLimit`):
  ``lb = clip(lb, cap_lb, cap_ub)``, ``ub = clip(ub, cap_lb, cap_ub)``. Clipping is
  monotone, so ``lb ≤ ub`` whenever the non-cap boxes are consistent — which their
  :meth:`Limit.check` proves at construction — and an arm past a position limit gets
  the bound that moves it back as fast as the velocity limit allows.
- :class:`RowLimit` gives a fixed number of rows ``l ≤ A v ≤ u`` (m, n); a row that
  does not apply this step has ``l = −∞, u = +∞``, so the sparsity pattern never changes.
  It sees the final box, so it can keep each row reachable inside it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from qpik.control.state import State
from qpik.errors import InfeasibleError, InputError
from qpik.validate import finite_array

if TYPE_CHECKING:
    from qpik.geometry.shapes import Shape
    from qpik.robots.robot import Robot


class Limit:
    """A constraint family of the QP (subclass :class:`BoxLimit` or :class:`RowLimit`)."""

    name: str = "limit"

    def check(self, robot: Robot, dt: float) -> None:
        """Raise :class:`InfeasibleError` if the limit can never be met (called at construction).

        The default accepts any robot and dt.
        """
        return None


class BoxLimit(Limit, ABC):
    """Bounds ``lb ≤ v ≤ ub`` (n,) on the joint velocity (rad/s)."""

    cap: bool = False  # cap boxes (velocity limits) clip every other box

    @abstractmethod
    def bounds(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """``(lb, ub)``, each (n,), rad/s; ``±inf`` for no bound."""


class RowLimit(Limit, ABC):
    """A fixed number of rows ``l ≤ A v ≤ u``."""

    @abstractmethod
    def size(self, robot: Robot) -> int:
        """Number of rows m (constant for a controller)."""

    @abstractmethod
    def row_names(self, robot: Robot) -> list[str]:
        """One name per row (for :attr:`StepInfo.active`)."""

    @abstractmethod
    def rows(self, state: State, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, l, u)``: (m, n), (m,), (m,), given the step's final box ``lb ≤ v ≤ ub`` (n,)."""


class ConfigurationLimit(BoxLimit):
    r"""Joint position limits through one step: :math:`q_{min} + \mu \le q + v\,dt \le q_{max} - \mu`.

    As a box: :math:`(q_{min} + \mu - q)/dt \le v \le (q_{max} - \mu - q)/dt`. A joint
    past its limit gets a lower (upper) bound > 0 (< 0): it must move back, and the
    velocity cap bounds how fast.

    Args:
        margin: μ ≥ 0, rad, kept from both limits.
        q_min, q_max: (n,) overrides of the robot's limits, rad (None: the robot's).
    """

    name = "position"

    def __init__(self, margin: float = 0.0, q_min: np.ndarray | None = None, q_max: np.ndarray | None = None):
        self.margin = float(margin)
        if not np.isfinite(self.margin) or self.margin < 0:
            raise InputError(f"ConfigurationLimit.margin: must be finite and >= 0, got {margin}")
        self.q_min = None if q_min is None else finite_array(q_min, "q_min", (None,)).copy()
        self.q_max = None if q_max is None else finite_array(q_max, "q_max", (None,)).copy()
        self._lo = self._hi = None

    def check(self, robot: Robot, dt: float) -> None:
        lo = (robot.q_min if self.q_min is None else self.q_min) + self.margin
        hi = (robot.q_max if self.q_max is None else self.q_max) - self.margin
        if lo.shape != (robot.dof,) or hi.shape != (robot.dof,):
            raise InputError(f"ConfigurationLimit: q_min/q_max must have shape ({robot.dof},)")
        bad = np.flatnonzero(lo > hi)
        if len(bad):
            raise InfeasibleError(
                "ConfigurationLimit: empty joint range (q_min + margin > q_max - margin) for joint(s) "
                + ", ".join(str(j + 1) for j in bad)
            )
        self._lo, self._hi = lo, hi

    def bounds(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        if self._lo is None:
            self.check(state.robot, state.dt)
        inv = 1.0 / state.dt
        return (self._lo - state.q) * inv, (self._hi - state.q) * inv


class VelocityLimit(BoxLimit):
    r"""Joint velocity limits :math:`|v| \le v_{max}` (a cap box: every other box is clipped into it).

    Args:
        v_max: (n,) limits, rad/s, ≥ 0 (None: the robot's).
    """

    name = "velocity"
    cap = True

    def __init__(self, v_max: np.ndarray | None = None):
        self.v_max = None if v_max is None else finite_array(v_max, "v_max", (None,)).copy()
        self._bounds: tuple[np.ndarray, np.ndarray] | None = None

    def check(self, robot: Robot, dt: float) -> None:
        vmax = robot.v_max if self.v_max is None else self.v_max
        if vmax.shape != (robot.dof,):
            raise InputError(f"VelocityLimit.v_max: expected shape ({robot.dof},), got {vmax.shape}")
        bad = np.flatnonzero(vmax < 0)
        if len(bad):
            raise InfeasibleError("VelocityLimit: negative v_max for joint(s) " + ", ".join(str(j + 1) for j in bad))
        self._bounds = (-vmax.copy(), vmax.copy())

    def bounds(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        if self._bounds is None:
            self.check(state.robot, state.dt)
        return self._bounds


class ObstacleLimit(RowLimit):
    r"""Velocity dampers that keep every link capsule away from every obstacle.

    One row per (capsule c, obstacle o) pair; it is active when the signed distance
    :math:`d < d_i` (influence distance):

    .. math::  \dot d = n^T J_p(p_{link})\, v \;\ge\; -\xi\,\frac{d - d_s}{d_i - d_s}

    with the witness point :math:`p_{link}` on the capsule, the unit normal ``n`` from the
    obstacle toward the capsule and the point Jacobian :math:`J_p` (the geometry contract
    :math:`\dot d = n^T J_p \dot q`, :mod:`qpik.geometry.distance`). ξ (m/s) is the largest
    approach speed, allowed at :math:`d = d_i`; it falls linearly to 0 at :math:`d_s`, and
    below :math:`d_s` the row demands a separating speed :math:`\xi (d_s - d)/(d_i - d_s)`.

    Discrete time: with :math:`q_{k+1} = q_k + v\,dt`, to first order
    :math:`d_{k+1} - d_s \ge (1 - \gamma)(d_k - d_s)` with :math:`\gamma = \xi\,dt/(d_i - d_s)`,
    so ``check`` requires γ ≤ 1 (no overshoot in one step). The second-order term of the
    motion (the curvature of link points' paths, ~|ω|²·r·dt² per step) is not linear in v;
    ``buffer`` (m) raises the safety distance seen by the rows to :math:`d_s + \delta` so that
    these terms, which accumulate to about (per-step term)/γ, stay above :math:`d_s`.

    Feasibility: ``v = 0`` meets every row with :math:`d \ge d_s + \delta`. A row that
    demands separation (:math:`d < d_s + \delta`, the arm starts inside the safety
    distance) is relaxed to what the box allows: its bound is capped at half of
    :math:`\max_{lb \le v \le ub} a^T v = \sum_j \max(a_j lb_j, a_j ub_j)`, so the QP stays
    feasible with one such row and moves away as fast as the limits let it. (Several
    separating rows at once, or a hard row against a box that forces a joint back
    from past its limit, can still conflict: the controller then relaxes the rows,
    see :class:`~qpik.control.controller.Controller`.) A pair that no joint moves (a
    zero row, e.g. the base link and a table) gets no row.

    Args:
        obstacles: shapes of :mod:`qpik.geometry` (world frame).
        d_influence: :math:`d_i`, m.
        d_safe: :math:`d_s`, m (< d_influence).
        xi: ξ, m/s (> 0).
        buffer: δ, m (≥ 0).
    """

    name = "obstacle"

    def __init__(
        self,
        obstacles: Sequence[Shape],
        d_influence: float = 0.10,
        d_safe: float = 0.02,
        xi: float = 0.5,
        buffer: float = 1e-3,
    ):
        from qpik.geometry.distance import ObstacleSet

        self.obstacles = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
        self.d_influence, self.d_safe, self.xi, self.buffer = map(float, (d_influence, d_safe, xi, buffer))
        if not (np.isfinite([self.d_influence, self.d_safe, self.xi, self.buffer]).all()):
            raise InputError("ObstacleLimit: d_influence, d_safe, xi, buffer must be finite")
        if not self.d_safe + self.buffer < self.d_influence:
            raise InfeasibleError("ObstacleLimit: need d_safe + buffer < d_influence")
        if self.xi <= 0 or self.buffer < 0:
            raise InputError("ObstacleLimit: need xi > 0 and buffer >= 0")
        self._upper: np.ndarray | None = None

    def check(self, robot: Robot, dt: float) -> None:
        if self.xi * dt > self.d_influence - self.d_safe - self.buffer:
            raise InfeasibleError(
                f"ObstacleLimit: xi·dt = {self.xi * dt:g} m exceeds d_influence - d_safe - buffer; "
                "the damper would overshoot d_safe in one step"
            )

    def size(self, robot: Robot) -> int:
        return len(robot.capsules) * len(self.obstacles)

    def row_names(self, robot: Robot) -> list[str]:
        names = [sh.name or f"{type(sh).__name__.lower()}{o}" for o, sh in enumerate(self.obstacles.shapes)]
        return [f"obstacle {nm} / link{c.link}" for c in robot.capsules for nm in names]

    def rows(self, state: State, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # every pair's row (fixed shape, from the step's compiled kinematics); pairs beyond d_i get l = -inf
        A = state.damper_rows(self.obstacles)
        d = state.distances(self.obstacles).d.reshape(-1)
        if self._upper is None or len(self._upper) != len(d):
            self._upper = np.full(len(d), np.inf)
        ds = self.d_safe + self.buffer
        lower = (-self.xi / (self.d_influence - ds)) * (d - ds)
        lower[d >= self.d_influence] = -np.inf
        sep = np.flatnonzero(lower > 0.0)
        if len(sep):  # inside d_s + δ: ask for at most half of what the box can give
            reach = np.maximum(A[sep] * lb, A[sep] * ub).sum(axis=1)
            lower[sep] = np.minimum(lower[sep], 0.5 * reach)
            lower[sep[reach < 1e-12]] = -np.inf  # a pair no joint moves apart gets no row
        return A, lower, self._upper
