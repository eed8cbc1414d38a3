r"""Joint velocity limits, the cap box of the QP: :class:`VelocityLimit`.

:math:`-v_{max} \le v \le v_{max}` (n,), rad/s; as a cap, it clips every other box
(:mod:`qpik.control.limits.base`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.control.limits.base import BoxLimit
from qpik.control.state import SymState
from qpik.core.errors import InfeasibleError, InputError
from qpik.core.layout import Blocks, Layout
from qpik.core.validate import finite_array

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


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

    @property
    def range(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(−v_max, v_max)``, each (n,), rad/s: the range kept (after :meth:`check`; None before)."""
        return self._bounds

    def structure(self) -> tuple:
        return ()

    def param_layout(self, n: int) -> Layout:
        return Layout(v_max=n)

    def param_values(self) -> dict[str, np.ndarray]:
        return {"v_max": self._bounds[1]}

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        return -p.v_max, p.v_max
