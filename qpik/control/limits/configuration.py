r"""Joint position limits as a box on the joint velocity: :class:`ConfigurationLimit`.

Through one step of ``dt`` (s): :math:`q_{min} + \mu \le q + v\,dt \le q_{max} - \mu`, i.e.
:math:`(q_{min} + \mu - q)/dt \le v \le (q_{max} - \mu - q)/dt` (n,), rad/s, with a margin μ (rad).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.control.limits.base import BoxLimit
from qpik.control.state import SymState
from qpik.core.errors import InfeasibleError, InputError
from qpik.core.layout import Blocks, Layout
from qpik.core.validate import finite_array, number

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


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
        self.margin = number(margin, "ConfigurationLimit.margin")
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

    @property
    def range(self) -> tuple[np.ndarray, np.ndarray]:
        """``(q_min + μ, q_max − μ)``, each (n,), rad: the range kept (after :meth:`check`)."""
        return self._lo, self._hi

    def structure(self) -> tuple:
        return ()

    def param_layout(self, n: int) -> Layout:
        return Layout(lo=n, hi=n)

    def param_values(self) -> dict[str, np.ndarray]:
        return {"lo": self._lo, "hi": self._hi}

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        return (p.lo - s.q) / s.dt, (p.hi - s.q) / s.dt
