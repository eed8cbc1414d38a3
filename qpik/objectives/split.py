"""split: see :mod:`qpik.objectives`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import casadi as ca

if TYPE_CHECKING:
    pass


@dataclass
class Split:
    r"""An objective as :math:`s + \sum_k w_k \max(h_k)` (SX).

    Attributes:
        smooth: the smooth part s, a scalar.
        maxima: ``(w_k, h_k)``: a weight (scalar, ≥ 0) and the pieces (m_k,) of each maximum.
    """

    smooth: ca.SX
    maxima: list[tuple[ca.SX, ca.SX]] = field(default_factory=list)

    def value(self) -> ca.SX:
        """:math:`s + \\sum_k w_k \\max(h_k)`."""
        out = self.smooth
        for w, h in self.maxima:
            out = out + w * ca.mmax(h)
        return out

    def epigraph(self) -> tuple[ca.SX, ca.SX, ca.SX]:
        """The epigraph form: ``(t, cost, g)`` with new variables t (K,), the smooth cost
        :math:`s + \\sum_k w_k t_k` and the constraints ``g ≤ 0``, :math:`h_{k,i} - t_k` stacked."""
        t = ca.SX.sym("t", len(self.maxima))
        cost = self.smooth
        g = [ca.SX(0, 1)]
        for k, (w, h) in enumerate(self.maxima):
            cost = cost + w * t[k]
            g.append(h - t[k])
        return t, cost, ca.vertcat(*g)
