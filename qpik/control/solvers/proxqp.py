r"""ProxQP (proxsuite's dense solver) called directly: ``solver="proxqp"``.

ProxQP solves :math:`\min \tfrac12 x^T H x + g^T x` s.t. :math:`l \le C x \le u`,
:math:`l_{box} \le x \le u_{box}`; the QP goes in as it is: ``H = P``, ``g = c``, ``C = A``
(every row, ``±inf`` where absent) and the box natively. proxsuite is in the ``test``
extra only: without it ``get_solver("proxqp")`` raises :class:`~qpik.core.errors.SolverError`.

Every step starts afresh (``init`` on one object per shape, equality-constrained initial
guess) with :data:`DEFAULTS`. A step reports a solution only if ProxQP says
``PROXQP_SOLVED``; an infeasible QP ends at ``max_iter`` (or ``PROXQP_PRIMAL_INFEASIBLE``)
with no solution, and the controller falls back to DAQP. Measured on the 480 QPs of
``tests/control/test_solvers.py`` (relaxed steps included), against DAQP:

- ``eps_primal_inf = 1e-10`` (default 1e-4): on degenerate QPs (a separating row at its
  bound, most joints at their velocity bound) the proximal method may stall, x moving
  3e-8 per outer iteration while the multipliers grow by 1e3 along a direction Δz with
  :math:`\|C^T \Delta z\| \approx 2\cdot10^{-8} \|\Delta z\|`; ProxQP's relative test takes Δz
  for a Farkas certificate and answers ``PROXQP_PRIMAL_INFEASIBLE`` for ``eps_primal_inf``
  ≥ 1e-7 (1 QP here; 3, and 23 with the relaxed ones, through ``qpsolvers``, which
  cannot pass the option), never at ≤ 1e-8;
- ``eps_abs = 1e-9``, ``eps_rel = 0`` and the duality gap checked to 1e-9: the answers
  agree with DAQP to 6e-10 in at most 16 outer (29 inner) iterations. Without the gap
  check 1.5e-8; with ``eps_abs = 1e-10`` a relaxed QP stalls for 727 outer iterations;
- a fresh start: warm-starting from the previous step (``update``) reached 1e-7 without
  the gap check and missed 26 steps (``max_iter``) with it; with
  ``COLD_START_WITH_PREVIOUS_RESULT`` it reported answers 1e-4 away from DAQP as solved;
- ``max_iter = 100`` outer iterations (6 × the most needed): with ``eps_primal_inf = 1e-10``
  an infeasible QP runs to it (~2 ms); ProxQP's default 1e-4 detected 1 of 3 infeasible
  test QPs (a row beyond the box, two conflicting rows) earlier, so little is lost.
"""

from __future__ import annotations

import numpy as np

from qpik.control.qp import QP
from qpik.control.solvers.base import Solution, Solver
from qpik.core.errors import SolverError

try:
    from proxsuite import proxqp
except ImportError as exc:  # only in the test extra
    raise SolverError("solver 'proxqp' needs proxsuite (pip install proxsuite)") from exc

DEFAULTS: dict[str, object] = {
    "eps_abs": 1e-9,
    "eps_rel": 0.0,
    "check_duality_gap": True,
    "eps_duality_gap_abs": 1e-9,
    "eps_duality_gap_rel": 0.0,
    "eps_primal_inf": 1e-10,
    "max_iter": 100,
    "verbose": False,
}
"""ProxQP settings of ``"proxqp"`` (any attribute of ``proxqp.Settings``); see the module docstring."""


class ProxqpSolver(Solver):
    """ProxQP's dense solver; ``options`` override :data:`DEFAULTS` (attributes of ``proxqp.Settings``)."""

    name = "proxqp"

    def __init__(self, **options: object):
        self.settings = {**DEFAULTS, **options}
        self._qp = None
        self._shape: tuple[int, int] | None = None

    def solve(self, qp: QP) -> Solution:
        shape = (qp.n, len(qp.l))
        if self._shape != shape:
            self._qp = proxqp.dense.QP(qp.n, 0, shape[1], True)
            for key, value in self.settings.items():
                setattr(self._qp.settings, key, value)
            self._shape = shape
        solver = self._qp
        try:
            solver.init(qp.P, qp.c, None, None, qp.A, qp.l, qp.u, qp.lb, qp.ub)
            solver.solve()
        except (RuntimeError, ValueError) as exc:  # ProxQP's own data checks: report, never raise in the loop
            return Solution(None, False, f"error: {exc}")
        info, x = solver.results.info, solver.results.x
        found = info.status == proxqp.QPSolverOutput.PROXQP_SOLVED and bool(np.isfinite(x).all())
        return Solution(x.copy() if found else None, found, info.status.name, int(info.iter))
