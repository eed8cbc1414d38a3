"""objective: see :mod:`qpik.objectives`."""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.core.errors import InputError
from qpik.core.layout import Layout
from qpik.core.validate import number

if TYPE_CHECKING:
    from qpik.robots.robot import Robot
from qpik.objectives.context import Context
from qpik.objectives.quantity import Quantity, _negated
from qpik.objectives.split import Split

_EMPTY = np.zeros(0)


_TOKENS = itertools.count()


class Objective(ABC):
    """A cost :math:`f(q)` to minimise (see the module docstring for the form).

    Subclasses implement :meth:`split`. Combine them with ``*`` (a weight) and ``+``.
    """

    name: str = "objective"
    bounded: bool = True
    """Whether the certificate bounds it (:class:`BoundFunction`); False where the Taylor models are too
    loose to prove anything at a useful cell width."""
    __array_ufunc__ = None  # ``array * objective`` calls :meth:`__rmul__` (which checks the weight), not numpy

    def param_size(self, robot: Robot) -> int:
        """Length of :meth:`params` for ``robot`` (default 0)."""
        return 0

    def params(self, robot: Robot) -> np.ndarray:
        """The current parameters, a flat vector (weights, sharpness, cap, ...)."""
        return _EMPTY

    def structure(self) -> tuple:
        """What fixes the expression's form beyond the parameters (part of a compiled function's key)."""
        return ()

    def key(self) -> tuple:
        """Type and :meth:`structure`: objectives with the same key share compiled functions."""
        return (type(self).__module__, type(self).__qualname__, self.structure())

    @abstractmethod
    def split(self, ctx: Context, p: ca.SX) -> Split:
        """The objective at ``ctx.q`` with parameters ``p`` (param_size,), as a :class:`Split`."""

    def expr(self, ctx: Context, p: ca.SX) -> ca.SX:
        """The value f(q) (SX scalar): :meth:`split` summed."""
        return self.split(ctx, p).value()

    @property
    def smooth(self) -> bool:
        """Whether f is twice differentiable (no maximum in its split)."""
        return True

    @property
    def terms(self) -> tuple[tuple[float, Objective], ...]:
        """``((weight, objective), ...)`` whose weighted sum this is (itself with weight 1)."""
        return ((1.0, self),)

    @property
    def quantity(self) -> Quantity:
        """How a value of it is shown (:class:`Quantity`); by default the objective itself, minimised."""
        return Quantity(self.name if self.name != Objective.name else "objective")

    def __mul__(self, weight: float) -> Sum:
        weight = number(weight, "weight")
        return Sum([(w * weight, o) for w, o in self.terms])

    __rmul__ = __mul__

    def __add__(self, other: Objective) -> Sum:
        if not isinstance(other, Objective):
            return NotImplemented
        return Sum([*self.terms, *other.terms])


class Sum(Objective):
    r"""A weighted sum :math:`\sum_i w_i f_i` (weights ≥ 0, parameters: the weights then each term's).

    Args:
        terms: ``(weight, objective)`` pairs (nested sums are flattened).
    """

    name = "sum"

    @property
    def bounded(self) -> bool:
        return all(o.bounded for _, o in self._terms)

    def __init__(self, terms: Sequence[tuple[float, Objective]]):
        flat: list[tuple[float, Objective]] = []
        for w, o in terms:
            if not isinstance(o, Objective):
                raise InputError(f"terms: expected Objective instances, got {type(o).__name__}")
            weight = number(w, "terms: weight", minimum=None)
            flat += [(weight * v, t) for v, t in o.terms]
        if not flat:
            raise InputError("terms: a Sum needs at least one objective")
        weights = np.array([w for w, _ in flat])
        if not np.isfinite(weights).all() or (weights < 0).any():
            raise InputError(f"terms: weights must be finite and >= 0, got {weights.tolist()}")
        self._terms = tuple(flat)
        self.weights = weights

    @property
    def terms(self) -> tuple[tuple[float, Objective], ...]:
        return tuple((float(w), o) for w, (_, o) in zip(self.weights, self._terms))

    def param_size(self, robot: Robot) -> int:
        return len(self._terms) + sum(o.param_size(robot) for _, o in self._terms)

    def params(self, robot: Robot) -> np.ndarray:
        return np.concatenate([self.weights, *(o.params(robot) for _, o in self._terms)])

    def structure(self) -> tuple:
        return tuple(o.key() for _, o in self._terms)

    @property
    def quantity(self) -> Quantity:
        """One term of weight w > 0: its quantity, read from f / w. Several terms that each measure the negative of
        a maximised quantity (margin, clearance): their weighted sum, maximised, −f. Otherwise the objective f,
        minimised."""
        if len(self._terms) == 1 and self.weights[0] > 0:
            return self._terms[0][1].quantity.scaled(self.weights[0])
        quantities = [o.quantity for _, o in self._terms]
        if all(q.maximised and q.of is _negated for q in quantities):
            name = " + ".join(("" if w == 1.0 else f"{w:g} × ") + q.name for w, q in zip(self.weights, quantities))
            units = {q.unit for q in quantities}
            return Quantity(name, units.pop() if len(units) == 1 else "", True, f"−({name})", of=_negated)
        parts = [f"{w:g} × ({q.minimised or q.name})" for w, q in zip(self.weights, quantities)]
        return Quantity("objective", meaning=" + ".join(parts))

    def layout(self, robot: Robot) -> Layout:
        """The blocks of :meth:`params`: ``weights`` (one per term), then ``term{k}``, the k-th term's parameters."""
        return Layout(
            weights=len(self._terms), **{f"term{k}": o.param_size(robot) for k, (_, o) in enumerate(self._terms)}
        )

    def split(self, ctx: Context, p: ca.SX) -> Split:
        out = Split(ca.SX(0.0))
        blocks = self.layout(ctx.robot).symbols(p)
        for k, (_, o) in enumerate(self._terms):
            part = o.split(ctx, blocks[f"term{k}"])
            w = blocks.weights[k]
            out.smooth = out.smooth + w * part.smooth
            out.maxima += [(w * v, h) for v, h in part.maxima]
        return out

    @property
    def smooth(self) -> bool:
        return all(o.smooth for _, o in self._terms)
