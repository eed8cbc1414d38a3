"""What every QP solver of the registry is: :class:`Solver`, and what it returns: :class:`Solution`."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from qpik.control.qp import QP


@dataclass
class Solution:
    """Result of one QP solve: ``x`` (N,) if ``found``, a solver ``status`` string, iterations."""

    x: np.ndarray | None
    found: bool
    status: str
    iterations: int = 0


class Solver(ABC):
    """A QP solver; one instance per controller (it may keep state between steps)."""

    name: str = ""

    @abstractmethod
    def solve(self, qp: QP) -> Solution:
        """Solve ``qp``; never raises on numerical failure (``found=False``)."""
