"""terms: see :mod:`qpik.objectives`."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import finite_array, flag, number

if TYPE_CHECKING:
    from qpik.robots.robot import Robot
from qpik.objectives.context import Context
from qpik.objectives.objective import _EMPTY, _TOKENS, Objective
from qpik.objectives.quantity import Quantity, _exp_negated, _negated
from qpik.objectives.split import Split


def _positive(x: object, name: str) -> float:
    """``x`` as a finite float > 0, else :class:`InputError` naming ``name``."""
    value = number(x, name)
    if value <= 0:
        raise InputError(f"{name}: must be > 0, got {value:g}")
    return value


def _normalised(robot: Robot, q: ca.SX) -> ca.SX:
    """The 2n normalised distances to the limits, :math:`(q - l)/\\rho` and :math:`(u - q)/\\rho`."""
    lo, hi = np.asarray(robot.q_min, float), np.asarray(robot.q_max, float)
    half = 0.5 * (hi - lo)
    return ca.vertcat((q - lo) / half, (hi - q) / half)


def _soft_max(h: ca.SX, beta: ca.SX) -> ca.SX:
    r""":math:`\tfrac1\beta \log \sum_i e^{\beta h_i}` (≥ max h, within log(m)/β), shifted by max h for range."""
    top = ca.mmax(h)
    return top + ca.log(ca.sum1(ca.exp(beta * (h - top)))) / beta


class JointLimitMargin(Objective):
    r"""Minus the smallest normalised distance to a joint limit.

    With :math:`g = ((q - l)/\rho,\ (u - q)/\rho)` (2n values, :math:`\rho = (u - l)/2`):
    :math:`f = \max_i(-g_i) = -\min_j \min(q_j - l_j, u_j - q_j)/\rho_j` (epigraph form), or with
    ``smooth=True`` :math:`f = \tfrac1\beta \log \sum_i e^{-\beta g_i}`, which is smooth, lies
    above the exact value by at most :math:`\log(2n)/\beta` and has the same minimiser as β → ∞.

    Parameters: β (``sharpness``, only with ``smooth=True``).
    """

    name = "margin"

    def __init__(self, smooth: bool = False, sharpness: float = 20.0):
        self._smooth = flag(smooth, "smooth")
        self.sharpness = _positive(sharpness, "sharpness")

    def structure(self) -> tuple:
        return (self._smooth,)

    def param_size(self, robot: Robot) -> int:
        return 1 if self._smooth else 0

    def params(self, robot: Robot) -> np.ndarray:
        return np.array([self.sharpness]) if self._smooth else _EMPTY

    @property
    def smooth(self) -> bool:
        return self._smooth

    @property
    def quantity(self) -> Quantity:
        r"""The margin :math:`-f` (unitless: a fraction of the half range), maximised; with ``smooth=True`` the soft
        minimum, at most :math:`\log(2n)/\beta` below the margin."""
        if self._smooth:
            return Quantity("smooth margin", "", True, "−smooth margin",
                            f"soft minimum (β = {self.sharpness:g}) of the distances to the joint limits over the"
                            " half ranges, a little below the margin", _negated)  # fmt: skip
        return Quantity("margin", "", True, "−margin",
                        "the smallest distance to a joint limit over the joint's half range", _negated)  # fmt: skip

    def split(self, ctx: Context, p: ca.SX) -> Split:
        g = _normalised(ctx.robot, ctx.q)
        if self._smooth:
            return Split(_soft_max(-g, p[0]))
        return Split(ca.SX(0.0), [(ca.SX(1.0), -g)])


class Manipulability(Objective):
    r"""Minus the log of Yoshikawa's manipulability: :math:`f = -\log \sqrt{\det J J^T}`.

    ``translational``: of the rows :math:`J_v` (m) only. Infinite at a singular configuration.

    Not :attr:`~Objective.bounded`: the Taylor model of m through the QR of J is finite only on
    very narrow δ/ψ ranges (the design notes give the figures); answers with it are the search's,
    not certified.
    """

    name = "manipulability"
    bounded = False

    def __init__(self, translational: bool = False):
        self.translational = flag(translational, "translational")

    def structure(self) -> tuple:
        return (self.translational,)

    @property
    def quantity(self) -> Quantity:
        """Yoshikawa's m itself, :math:`e^{-f}` (m³), maximised."""
        name = "translational manipulability" if self.translational else "manipulability"
        meaning = "√det(J_v J_vᵀ)" if self.translational else "√det(J Jᵀ)"
        return Quantity(name, "m³", True, f"−log {name}", meaning, _exp_negated)

    def split(self, ctx: Context, p: ca.SX) -> Split:
        return Split(-ca.log(ctx.manipulability(self.translational)))


class Clearance(Objective):
    r"""Minus the smallest link-capsule/obstacle distance, capped: :math:`f = -\min(c, \min_{k,o} d_{k,o})`.

    The pairs are every link capsule against every obstacle of the problem (m). Distances
    beyond the cap c (m) do not count. Epigraph form, or with ``smooth=True`` the soft
    minimum :math:`\tfrac1\beta \log(e^{-\beta c} + \sum e^{-\beta d_{k,o}})` (β in 1/m).

    Parameters: c, then β (with ``smooth=True``).
    """

    name = "clearance"

    def __init__(self, cap: float = 0.1, smooth: bool = False, sharpness: float = 100.0):
        self.cap, self.sharpness = _positive(cap, "cap"), _positive(sharpness, "sharpness")
        self._smooth = flag(smooth, "smooth")

    def structure(self) -> tuple:
        return (self._smooth,)

    def param_size(self, robot: Robot) -> int:
        return 2 if self._smooth else 1

    def params(self, robot: Robot) -> np.ndarray:
        return np.array([self.cap, self.sharpness][: self.param_size(robot)])

    @property
    def smooth(self) -> bool:
        return self._smooth

    @property
    def quantity(self) -> Quantity:
        """The capped clearance :math:`-f` (m), maximised; with ``smooth=True`` the soft minimum."""
        name = "smooth clearance" if self._smooth else "clearance"
        meaning = f"the smallest link-capsule/obstacle distance, capped at {self.cap:g} m"
        if self._smooth:
            meaning = (f"soft minimum (β = {self.sharpness:g} 1/m) of the link-capsule/obstacle distances and the cap"
                       f" {self.cap:g} m, a little below the smallest")  # fmt: skip
        return Quantity(name, "m", True, f"−{name}", meaning, _negated)

    def split(self, ctx: Context, p: ca.SX) -> Split:
        h = -ca.vertcat(ctx.distances, p[0])
        if self._smooth:
            return Split(_soft_max(h, p[1]))
        return Split(ca.SX(0.0), [(ca.SX(1.0), h)])


class ReferenceDistance(Objective):
    r"""Distance to a reference configuration: :math:`f = \tfrac12 \sum_j w_j (q_j - q_{ref,j})^2` (rad²).

    ``q_ref`` is the problem's (the ``q_ref`` argument of :func:`qpik.solve_best`, or
    :class:`~qpik.control.tasks.ObjectiveTask`'s): the current configuration, for continuity.

    Parameters: the weights w (n,), default 1.

    Args:
        weights: (n,) per-joint weights ≥ 0 (None: all 1).
    """

    name = "distance"

    def __init__(self, weights: np.ndarray | None = None):
        self.weights = None if weights is None else finite_array(weights, "weights", (None,)).copy()
        if self.weights is not None and (self.weights < 0).any():
            raise InputError("weights: must be >= 0")

    def _w(self, robot: Robot) -> np.ndarray:
        if self.weights is None:
            return np.ones(robot.dof)
        if self.weights.shape != (robot.dof,):
            raise InputError(f"weights: expected shape ({robot.dof},), got {self.weights.shape}")
        return self.weights

    def param_size(self, robot: Robot) -> int:
        return robot.dof

    def params(self, robot: Robot) -> np.ndarray:
        return self._w(robot)

    @property
    def quantity(self) -> Quantity:
        """f itself (rad²), minimised."""
        return Quantity("distance to q_ref", "rad²", meaning="½ Σ w_j (q_j − q_ref,j)²")

    def split(self, ctx: Context, p: ca.SX) -> Split:
        e = ctx.q - ctx.q_ref
        return Split(0.5 * ca.dot(p * e, e))


class Expression(Objective):
    """A user's objective: ``fn(q)``, a CasADi expression (SX scalar) of q (n,) SX.

    ``fn`` is a :class:`casadi.Function` of one (n,) input, or a Python function building the
    expression. Answers with it can be certified when every operation of the expression has a
    Taylor-model rule (:func:`qpik.algebra.enclosure.taylor_function`); otherwise the certificate says so.

    Args:
        fn: the expression's builder.
        smooth: whether it is twice differentiable (the QP task and the cross-check need that).
        name: a label for tables.
    """

    def __init__(self, fn: Callable[[ca.SX], ca.SX] | ca.Function, smooth: bool = True, name: str = "expression"):
        if not callable(fn):
            raise InputError(f"fn: expected a casadi.Function or a callable, got {type(fn).__name__}")
        self.fn, self._smooth, self.name = fn, flag(smooth, "smooth"), str(name)
        self._token = next(_TOKENS)

    def structure(self) -> tuple:
        return (self._token,)

    @property
    def smooth(self) -> bool:
        return self._smooth

    def split(self, ctx: Context, p: ca.SX) -> Split:
        out = self.fn(ctx.q)
        if isinstance(out, (list, tuple)) and out:
            out = out[0]
        if not isinstance(out, ca.SX):
            try:
                out = ca.SX(out)
            except (NotImplementedError, TypeError, RuntimeError):
                raise InputError(f"fn: must return a scalar CasADi expression of q, got {type(out).__name__}") from None
        if out.numel() != 1:
            raise InputError(f"fn: must return a scalar expression of q, got shape {out.shape}")
        return Split(out)


_NAMED: dict[str, Callable[[], Objective]] = {
    "margin": JointLimitMargin,
    "smooth-margin": lambda: JointLimitMargin(smooth=True),
    "manipulability": Manipulability,
    "clearance": Clearance,
    "smooth-clearance": lambda: Clearance(smooth=True),
    "distance": ReferenceDistance,
}


NAMES = tuple(_NAMED)


def resolve(objective: Objective | str) -> Objective:
    """An objective, or one with default parameters from its name (:data:`NAMES`)."""
    if isinstance(objective, Objective):
        return objective
    if not isinstance(objective, str) or objective not in _NAMED:
        raise InputError(f"objective: expected an Objective or one of {list(NAMES)}, got {objective!r}")
    return _NAMED[objective]()
