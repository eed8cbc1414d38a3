r"""Any :mod:`qpsolvers` backend by name (daqp, quadprog, proxqp, clarabel, piqp, ...).

The two-sided rows ``l ≤ A x ≤ u`` become one-sided ``G x ≤ h``: ``A_r x ≤ u_r`` for
finite ``u_r`` and ``−A_r x ≤ −l_r`` for finite ``l_r``; rows with both bounds infinite
(limits that do not apply this step) are left out. The box goes to the solver as
``lb``/``ub``, except a joint whose box is a single value (``lb = ub``: a joint pushed back
from past its limit at full speed), which becomes an equality ``v_j = lb_j`` with a box
loosened by 1 rad/s around it — active-set solvers such as quadprog fail on the two
opposite inequalities. Each call builds a ``qpsolvers.Problem`` and calls ``solve_problem``.
"""

from __future__ import annotations

import numpy as np
import qpsolvers
from scipy import sparse

from qpik.control.qp import QP
from qpik.control.solvers.base import Solution, Solver


class QpsolversSolver(Solver):
    """A qpsolvers backend; ``options`` are forwarded to it (e.g. tolerances)."""

    def __init__(self, name: str, **options: object):
        self.name = name
        self.options = options
        # backends that only take sparse matrices get CSC (qpsolvers would convert and warn)
        self._sparse = name in qpsolvers.sparse_solvers and name not in qpsolvers.dense_solvers

    def solve(self, qp: QP) -> Solution:
        up = np.isfinite(qp.u)
        lo = np.isfinite(qp.l)
        G = np.concatenate([qp.A[up], -qp.A[lo]]) if (up.any() or lo.any()) else None
        h = np.concatenate([qp.u[up], -qp.l[lo]]) if G is not None else None
        lb, ub = qp.lb, qp.ub
        E = b = None
        fixed = lb == ub
        if fixed.any():
            E, b = np.eye(qp.n)[fixed], lb[fixed]
            lb, ub = np.where(fixed, lb - 1.0, lb), np.where(fixed, ub + 1.0, ub)
        P = qp.P
        if self._sparse:
            P, G, E = (None if M is None else sparse.csc_matrix(M) for M in (P, G, E))
        problem = qpsolvers.Problem(P, qp.c, G, h, E, b, lb=lb, ub=ub)
        try:
            sol = qpsolvers.solve_problem(problem, solver=self.name, **self.options)
        except Exception as exc:  # a backend's own error: report it, never raise in the loop
            return Solution(None, False, f"error: {exc}")
        found = bool(sol.found) and sol.x is not None and np.all(np.isfinite(sol.x))
        return Solution(np.asarray(sol.x) if found else None, found, "solved" if found else "not found")
