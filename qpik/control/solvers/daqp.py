r"""DAQP called directly (the fast path of ``"daqp"``).

DAQP takes two-sided constraints natively: the box ``lb ≤ v ≤ ub`` as its simple bounds
(the first n entries of ``blower``/``bupper``) and every row ``l ≤ A v ≤ u`` as it is;
an absent bound (±inf) goes in as it is too, since DAQP counts every bound beyond its
``DAQP_INF`` (1e30) as absent (the tests compare the answers with quadprog's on QPs with absent
bounds). Measured on the controller bench (iiwa14, 14 rows),
going through ``qpsolvers.solve_problem`` cost more than the solve itself (building the
``Problem``, splitting each two-sided row into two one-sided rows, packing them back for
DAQP); calling ``daqp.solve`` on the QP buffers removes that overhead. The answer is the
same (both are DAQP's exact active-set solution).
"""

from __future__ import annotations

import math

import daqp
import numpy as np

from qpik.control.qp import QP
from qpik.control.solvers.base import Solution, Solver

STATUS = {
    1: "solved",
    2: "solved (soft constraints)",
    -1: "infeasible",
    -2: "cycling",
    -3: "unbounded",
    -4: "iteration limit",
    -5: "nonconvex",
    -6: "initial working set overdetermined",
}


class DaqpSolver(Solver):
    """DAQP on the QP's own arrays; ``options`` go to ``daqp.solve`` (e.g. ``primal_tol``)."""

    name = "daqp"

    def __init__(self, **options: object):
        self.options = options
        self._lo = self._hi = None
        self._sense = None

    def solve(self, qp: QP) -> Solution:
        n, m = qp.n, len(qp.l)
        if self._lo is None or len(self._lo) != n + m:
            self._lo, self._hi = np.empty(n + m), np.empty(n + m)
            self._sense = np.zeros(n + m, dtype=np.intc)
        lo, hi = self._lo, self._hi
        lo[:n], lo[n:], hi[:n], hi[n:] = qp.lb, qp.l, qp.ub, qp.u
        x, _, flag, info = daqp.solve(qp.P, qp.c, qp.A, hi, lo, self._sense, **self.options)
        found = flag > 0 and math.isfinite(x @ x)  # finite iff every entry is (and none beyond 1e154 rad/s)
        return Solution(
            np.asarray(x) if found else None,
            found,
            STATUS.get(flag, f"exitflag {flag}"),
            int(info.get("iterations", 0)) if isinstance(info, dict) else 0,
        )
