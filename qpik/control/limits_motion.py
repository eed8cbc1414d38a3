r"""Limits that look at the motion, not only the configuration: acceleration, jerk and braking.

The controller commands ``v_k`` (n,), rad/s, every ``dt`` seconds; the commands before it are
``v_{k-1}`` and ``v_{k-2}``. With finite differences, acceleration :math:`a_k = (v_k - v_{k-1})/dt`
(rad/s²) and jerk :math:`j_k = (a_k - a_{k-1})/dt` (rad/s³). A limit that needs the past commands
keeps them and is told each command by :meth:`~qpik.control.limits.base.Limit.observe` (the controller
calls it after every step; before the first, the arm is taken at rest, or :meth:`reset` sets it).

- :class:`AccelerationLimit` and :class:`JerkLimit` are *cap* boxes around the last command. Caps clip
  the box in increasing :attr:`~qpik.control.limits.base.BoxLimit.rank` and the last wins: the jerk first,
  then the acceleration, then :class:`~qpik.control.limits.velocity.VelocityLimit`. Where they conflict the velocity
  limit is kept, then the acceleration: a jerk box extrapolates the last two commands, and if it won it
  could carry the velocity away.
- :class:`BrakingLimit` bounds the position so that the arm can still stop before a limit at the
  acceleration limit (Flacco, Kröger, De Luca and Khatib, 2015, eq. 17, in discrete time).

Consistency: clipping an interval that lies in one box into a second box that meets the first gives an
interval in both. The acceleration box :math:`[v_{k-1} - \bar a\,dt,\ v_{k-1} + \bar a\,dt]` meets the
velocity box since :math:`|v_{k-1}| \le \bar v`, so the final box meets the velocity and acceleration
limits whenever the last command did. The jerk box is centred on :math:`v_{k-1} + a_{k-1} dt`, inside the
acceleration box since :math:`|a_{k-1}| \le \bar a`; it may leave the velocity box at full speed while
still accelerating, so :class:`JerkLimit` also bounds the acceleration so that it can fall to zero (at the
jerk limit) before the velocity limit: :math:`v + a\,|a| / (2\bar j) \le \bar v` (the same braking, one
derivative up). The jerk is the limit given up first (a conflict with a position bound that needs a
faster stop, for example).
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


def _limits(value: np.ndarray | None, default: np.ndarray | None, robot: Robot, name: str) -> np.ndarray:
    """The (n,) limit ``value`` or the robot's ``default``, checked > 0."""
    out = default if value is None else value
    if out is None:
        raise InputError(f"{name}: the robot has no such limits in its catalog entry; give them")
    out = np.asarray(out, dtype=float)
    if out.shape != (robot.dof,):
        raise InputError(f"{name}: expected shape ({robot.dof},), got {out.shape}")
    if np.any(out <= 0.0):
        raise InfeasibleError(f"{name}: must be > 0")
    return out.copy()


class _History(BoxLimit):
    """A box around the past commands (kept here, updated by :meth:`observe`)."""

    cap = True
    depth = 1  # how many past commands the box reads

    def __init__(self, limit: np.ndarray | None):
        self.limit = None if limit is None else finite_array(limit, f"{type(self).__name__} limit", (None,)).copy()
        self._max: np.ndarray | None = None
        self._past = np.zeros((self.depth, 0))

    def reset(self, *past: np.ndarray) -> None:
        """Set the past commands (each (n,), rad/s; newest first; missing ones: at rest)."""
        n = self._past.shape[1]
        self._past = np.zeros((self.depth, n))
        for i, v in enumerate(past[: self.depth]):
            self._past[i] = finite_array(v, "past command", (n,))

    def observe(self, v: np.ndarray) -> None:
        self._past[1:] = self._past[:-1]
        self._past[0] = v

    def structure(self) -> tuple:
        return ()

    @property
    def range(self) -> None:
        """None: not a velocity range (:attr:`StepInfo.active` names its bounds by the velocity limits)."""
        return None


class AccelerationLimit(_History):
    r"""Joint acceleration limits from the last command: :math:`|v - v_{k-1}| \le \bar a\,dt`.

    Args:
        a_max: (n,) limits :math:`\bar a`, rad/s², > 0 (None: ``robot.a_max``, from the catalog).
    """

    name = "acceleration"
    rank = -1

    def __init__(self, a_max: np.ndarray | None = None):
        super().__init__(a_max)

    def check(self, robot: Robot, dt: float) -> None:
        self._max = _limits(self.limit, robot.a_max, robot, "AccelerationLimit.a_max")
        if self._past.shape[1] != robot.dof:
            self._past = np.zeros((self.depth, robot.dof))

    def param_layout(self, n: int) -> Layout:
        return Layout(v1=n, a_max=n)

    def param_values(self) -> dict[str, np.ndarray]:
        return {"v1": self._past[0], "a_max": self._max}

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        return p.v1 - p.a_max * s.dt, p.v1 + p.a_max * s.dt


class JerkLimit(_History):
    r"""Joint jerk limits from the last two commands: :math:`|v - 2 v_{k-1} + v_{k-2}| \le \bar j\,dt^2`.

    With the velocity limits :math:`\bar v` also known, the acceleration :math:`a = (v - v_{k-1})/dt`
    is kept where it can return to zero before :math:`\pm\bar v` at the jerk limit:
    :math:`v + a^2/(2\bar j) \le \bar v` while accelerating (and the mirror image), i.e.
    :math:`a \le \bar j\,(-dt + \sqrt{dt^2 + 2 (\bar v - v_{k-1})/\bar j})` in discrete time
    (the velocity gained while the acceleration falls by :math:`\bar j\,dt` per step is at most
    :math:`a^2/(2\bar j)`, as :class:`BrakingLimit` one derivative down). Where the jerk box and this
    bound do not meet, the jerk box wins within this limit (and the acceleration and velocity caps after it).

    Args:
        j_max: (n,) limits :math:`\bar j`, rad/s³, > 0 (None: ``robot.j_max``, from the catalog).
        v_max: (n,) velocity limits for the bound above, rad/s (None: the robot's).
    """

    name = "jerk"
    rank = -2
    depth = 2

    def __init__(self, j_max: np.ndarray | None = None, v_max: np.ndarray | None = None):
        super().__init__(j_max)
        self.v_max = None if v_max is None else finite_array(v_max, "JerkLimit.v_max", (None,)).copy()
        self._vmax: np.ndarray | None = None

    def check(self, robot: Robot, dt: float) -> None:
        self._max = _limits(self.limit, robot.j_max, robot, "JerkLimit.j_max")
        self._vmax = _limits(self.v_max, robot.v_max, robot, "JerkLimit.v_max")
        if self._past.shape[1] != robot.dof:
            self._past = np.zeros((self.depth, robot.dof))

    def param_layout(self, n: int) -> Layout:
        return Layout(v1=n, v2=n, j_max=n, v_max=n)

    def param_values(self) -> dict[str, np.ndarray]:
        return {"v1": self._past[0], "v2": self._past[1], "j_max": self._max, "v_max": self._vmax}

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        dt, j = s.dt, p.j_max
        centre = 2.0 * p.v1 - p.v2
        lo, hi = centre - j * dt * dt, centre + j * dt * dt
        # the acceleration that can still fall to 0 before ±v_max: a ≤ j(-dt + sqrt(dt² + 2 (v_max - v1)/j))
        room_up, room_down = ca.fmax(p.v_max - p.v1, 0.0), ca.fmax(p.v_max + p.v1, 0.0)
        a_up = j * (-dt + ca.sqrt(dt * dt + 2.0 * room_up / j))
        a_down = j * (-dt + ca.sqrt(dt * dt + 2.0 * room_down / j))
        hi = ca.fmax(lo, ca.fmin(hi, p.v1 + a_up * dt))
        lo = ca.fmin(hi, ca.fmax(lo, p.v1 - a_down * dt))
        return lo, hi


class BrakingLimit(BoxLimit):
    r"""Position limits that leave room to brake: the arm can stop before :math:`q_{max} - \mu` at the
    acceleration limit :math:`\bar a` (Flacco et al. 2015, eq. 17, in discrete time).

    Stepping :math:`q_{k+1} = q + v\,dt` and then braking by :math:`\bar a\,dt` per step covers at most
    :math:`v^2/(2\bar a)` more
    (:math:`\sum_{i \ge 1} (v - i\bar a\,dt)^+\,dt \le (v - \bar a\,dt/2)^2/(2\bar a)`);
    with a jerk limit :math:`\bar j` the deceleration needs up to :math:`\tau = \bar a/\bar j` to build up,
    covering at most :math:`v\tau` more. So with the gap :math:`g = q_{max} - \mu - q \ge 0`:

    .. math::  v\,(dt + \tau) + \frac{v^2}{2\bar a} \le g
        \iff v \le \bar a\left(-(dt + \tau) + \sqrt{(dt + \tau)^2 + 2g/\bar a}\right)

    and the mirror image at :math:`q_{min} + \mu`. Recursively feasible with :class:`AccelerationLimit`
    alone (τ = 0): if the last command met it, :math:`v = v_{k-1} - \bar a\,dt` (or 0) meets it again
    (:math:`q + v_{k-1}^2/(2\bar a) - \bar a\,dt^2/2 \le q_{max} - \mu`). With the jerk, the τ term is a
    conservative allowance, not a proof. Past the limit (g < 0) the bound is :math:`g/dt < 0`, as
    :class:`~qpik.control.limits.configuration.ConfigurationLimit`: move back (as fast as the caps allow).

    Args:
        a_max: (n,) :math:`\bar a`, rad/s², > 0 (None: ``robot.a_max``).
        j_max: (n,) :math:`\bar j`, rad/s³, > 0, for τ (None: ``robot.j_max`` if it has one, else τ = 0).
        margin: μ ≥ 0, rad.
    """

    name = "braking"

    def __init__(self, a_max: np.ndarray | None = None, j_max: np.ndarray | None = None, margin: float = 0.0):
        self.a_max = None if a_max is None else finite_array(a_max, "BrakingLimit.a_max", (None,)).copy()
        self.j_max = None if j_max is None else finite_array(j_max, "BrakingLimit.j_max", (None,)).copy()
        self.margin = number(margin, "BrakingLimit.margin")
        self._values: dict[str, np.ndarray] = {}

    def check(self, robot: Robot, dt: float) -> None:
        a = _limits(self.a_max, robot.a_max, robot, "BrakingLimit.a_max")
        has_jerk = self.j_max is not None or robot.j_max is not None
        tau = a / _limits(self.j_max, robot.j_max, robot, "BrakingLimit.j_max") if has_jerk else np.zeros(robot.dof)
        lo, hi = robot.q_min + self.margin, robot.q_max - self.margin
        if np.any(lo > hi):
            raise InfeasibleError("BrakingLimit: empty joint range (q_min + margin > q_max - margin)")
        self._values = {"lo": lo, "hi": hi, "a_max": a, "tau": tau}

    def structure(self) -> tuple:
        return ()

    def param_layout(self, n: int) -> Layout:
        return Layout(lo=n, hi=n, a_max=n, tau=n)

    def param_values(self) -> dict[str, np.ndarray]:
        return self._values

    def expr(self, s: SymState, p: Blocks) -> tuple[ca.SX, ca.SX]:
        a, lead = p.a_max, s.dt + p.tau

        def bound(gap: ca.SX) -> ca.SX:
            brake = a * (-lead + ca.sqrt(lead * lead + 2.0 * ca.fmax(gap, 0.0) / a))
            return ca.if_else(gap >= 0.0, brake, gap / s.dt)

        return -bound(s.q - p.lo), bound(p.hi - s.q)
