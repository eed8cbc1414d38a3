"""QP solvers behind one registry: :func:`get_solver` by name.

- ``"osqp"``: a persistent OSQP object (:mod:`.osqp`), set up once with the fixed
  sparsity pattern of the controller's QP, then updated and warm-started every step;
- ``"daqp"``: DAQP called directly on the QP arrays (:mod:`.daqp`, a measured fast path);
- ``"proxqp"``: ProxQP's dense solver called directly (:mod:`.proxqp`, with settings under
  which it answers the controller's degenerate QPs), if proxsuite is installed;
- any other name that :mod:`qpsolvers` offers (``"quadprog"``, ``"clarabel"``,
  ``"piqp"``, ...) through ``qpsolvers.solve_problem`` (:mod:`.qpsolvers`).

Every solver returns a :class:`Solution` and never raises on a failed solve
(``found=False`` with a status); a solver that is not installed raises
:class:`~qpik.core.errors.SolverError` from :func:`get_solver`.
"""

from __future__ import annotations

from qpik.control.solvers.base import Solution, Solver
from qpik.core.errors import SolverError


def available() -> tuple[str, ...]:
    """Names accepted by :func:`get_solver` on this machine."""
    import qpsolvers

    return tuple(dict.fromkeys(("osqp", "daqp", *qpsolvers.available_solvers)))


def get_solver(name: str, **options: object) -> Solver:
    """A new solver by name; ``options`` go to the backend (e.g. ``eps_abs`` for OSQP).

    Raises:
        SolverError: the name is unknown or its package is not installed.
    """
    if not isinstance(name, str):
        raise SolverError(f"solver name: expected a string, got {name!r}")
    if name == "osqp":
        from qpik.control.solvers.osqp import OSQPSolver

        return OSQPSolver(**options)
    if name == "daqp":
        from qpik.control.solvers.daqp import DaqpSolver

        return DaqpSolver(**options)
    if name not in available():
        raise SolverError(f"unknown or uninstalled QP solver {name!r}; available: {', '.join(available())}")
    if name == "proxqp":
        from qpik.control.solvers.proxqp import ProxqpSolver

        return ProxqpSolver(**options)
    from qpik.control.solvers.qpsolvers import QpsolversSolver

    return QpsolversSolver(name, **options)


__all__ = ["Solution", "Solver", "available", "get_solver"]
