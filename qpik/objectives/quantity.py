"""quantity: see :mod:`qpik.objectives`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    pass


def _same(f: np.ndarray) -> np.ndarray:
    return f


def _negated(f: np.ndarray) -> np.ndarray:
    return -f


def _exp_negated(f: np.ndarray) -> np.ndarray:
    return np.exp(-f)


@dataclass(frozen=True)
class Quantity:
    """How an objective's value is shown to a person: the quantity it measures, in its own sense.

    The solvers minimise f; :meth:`value` is the measured quantity (the margin for f = −margin, the
    manipulability m for f = −log m, f itself for a quantity that is minimised).

    Attributes:
        name: what the number is (``"margin"``, ``"clearance"``, ``"objective"``, ...).
        unit: its unit (``""``: unitless).
        maximised: whether the best value is the largest.
        minimised: what qpik minimises to maximise it (``"−margin"``), ``""`` when it minimises the quantity itself.
        meaning: what it measures, in words (``""`` when the name says it).
        of: the quantity from the minimised value f (numpy, elementwise).
    """

    name: str
    unit: str = ""
    maximised: bool = False
    minimised: str = ""
    meaning: str = ""
    of: Callable[[np.ndarray], np.ndarray] = _same

    def value(self, f: float | np.ndarray) -> float | np.ndarray:
        """The quantity at the minimised value(s) f (a float for a number, an array for an array)."""
        out = self.of(np.asarray(f, dtype=float))
        return float(out) if np.ndim(out) == 0 else out

    @property
    def header(self) -> str:
        """A table column's title: the name and unit (``"clearance [m]"``)."""
        return self.name + (f" [{self.unit}]" if self.unit else "")

    @property
    def sense(self) -> str:
        """``"maximised (qpik minimises −margin)"`` or ``"minimised"``."""
        if not self.maximised:
            return "minimised"
        return "maximised" + (f" (qpik minimises {self.minimised})" if self.minimised else "")

    @property
    def label(self) -> str:
        """An axis label: the header and the sense (``"margin, maximised (qpik minimises −margin)"``)."""
        return f"{self.header}, {self.sense}"

    @property
    def goal(self) -> str:
        """What a solve asks for, in words: ``"maximise the margin (the smallest ...; qpik minimises −margin)"``."""
        verb = "maximise" if self.maximised else "minimise"
        notes = [x for x in (self.meaning, f"qpik minimises {self.minimised}" if self.minimised else "") if x]
        return f"{verb} the {self.name}" + (f" ({'; '.join(notes)})" if notes else "")

    def text(self, f: float, spec: str = ".6g") -> str:
        """``"margin 0.377787"``, ``"clearance 0.0421 m"``: the quantity at the minimised value f, with its unit."""
        return f"{self.name} {format(self.value(f), spec)}" + (f" {self.unit}" if self.unit else "")

    def scaled(self, weight: float) -> Quantity:
        """The quantity of ``weight`` × the objective (weight > 0): the same quantity, read from f / weight."""
        inner, w = self.of, float(weight)
        what = self.minimised or self.name
        return Quantity(self.name, self.unit, self.maximised, f"{w:g} × ({what})" if w != 1.0 else self.minimised,
                        self.meaning, lambda f: inner(f / w))  # fmt: skip
