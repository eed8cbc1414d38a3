r"""A persistent OSQP solver for the controller's QP (fixed sparsity, update + warm start).

OSQP solves :math:`\min \tfrac12 x^T P x + q^T x` s.t. :math:`l \le \bar A x \le u`.
The pattern is set up once, on the first :meth:`OSQPSolver.solve`:

- ``P``: the dense upper triangle of the (N, N) cost matrix;
- :math:`\bar A = [I_N;\ A]`: the box ``lb ≤ x ≤ ub`` as identity rows, then every row of
  the QP (inactive rows keep their place with ``±inf`` bounds and zero coefficients).

Each step only the values change: ``update(Px=…, q=…, Ax=…, l=…, u=…)``, and OSQP
starts from the previous primal–dual solution (``warm_starting``).

Accuracy (:data:`DEFAULTS`, measured on QPs recorded from controller episodes against
daqp, an exact active-set solver): ADMM runs to ``eps_abs = eps_rel = 1e-5`` (enough to
identify the active set; ~40 iterations per warm-started step), then :func:`polish`
solves the KKT system of that active set exactly and accepts it only if it is primal
and dual feasible — the answer then agrees with daqp to ~1e-12. If the check fails
(ADMM stopped short of the right active set), ADMM is resumed once with 1e-3 × the
tolerances and polished again. An iterate stopped by ``max_iter`` is polished too — the
KKT check decides whether it is the answer: on degenerate QPs (joints resting on their
limits with a damper row nearly active) ADMM can crawl for thousands of iterations after
it has found the active set, so the first attempt stops at 200 iterations (a warm-started
step needs ~25–40) and only the retry runs up to 4000. OSQP's own ``polishing`` is off: version 1.1.3 prints
"Polishing not needed" to stdout, regardless of ``verbose``, on every solve where no
constraint is active, which is most control steps.
"""

from __future__ import annotations

import numpy as np
import osqp
from scipy import sparse

from qpik.control.qp import QP
from qpik.control.solvers import Solution, Solver

DEFAULTS: dict[str, object] = {
    "eps_abs": 1e-5,
    "eps_rel": 1e-5,
    "polishing": False,
    "max_iter": 200,
    "warm_starting": True,
    "verbose": False,
}


RETRY_MAX_ITER = 4000


class OSQPSolver(Solver):
    """One OSQP workspace, reused for every step of a controller."""

    name = "osqp"

    def __init__(self, **options: object):
        self.settings = {**DEFAULTS, **options}
        self._solver: osqp.OSQP | None = None
        self._shape: tuple[int, int] | None = None

    def _setup(self, qp: QP) -> None:
        N, m = qp.P.shape[0], qp.A.shape[0]
        iu = np.triu_indices(N)
        # CSC order of the upper triangle: column by column, rows 0..j
        order = np.lexsort((iu[0], iu[1]))
        self._pr, self._pc = iu[0][order], iu[1][order]
        P = sparse.csc_matrix((qp.P[self._pr, self._pc], self._pr, np.r_[0, np.cumsum(np.arange(1, N + 1))]), (N, N))
        # Ā = [I; A] dense: column j holds rows 0..N+m-1
        self._Abar = np.zeros((N + m, N))
        self._Abar[:N] = np.eye(N)
        self._Abar[N:] = qp.A
        rows = np.tile(np.arange(N + m), N)
        A = sparse.csc_matrix((self._Abar.ravel(order="F"), rows, np.arange(0, (N + m) * N + 1, N + m)), (N + m, N))
        self._l = np.concatenate([qp.lb, qp.l])
        self._u = np.concatenate([qp.ub, qp.u])
        self._solver = osqp.OSQP()
        self._solver.setup(P, qp.c.copy(), A, self._l, self._u, **self.settings)
        self._shape = (N, m)

    def solve(self, qp: QP) -> Solution:
        N = qp.P.shape[0]
        if self._shape != (N, qp.A.shape[0]):
            self._setup(qp)
        else:
            self._Abar[N:] = qp.A
            self._l[:N], self._l[N:] = qp.lb, qp.l
            self._u[:N], self._u[N:] = qp.ub, qp.u
            self._solver.update(
                Px=qp.P[self._pr, self._pc], q=qp.c, Ax=self._Abar.ravel(order="F"), l=self._l, u=self._u
            )
        res = self._solver.solve(raise_error=False)
        x = self._polish(qp, res)
        if x is None:  # ADMM stopped short of the active set: tighten once, then restore
            tight = {k: float(self.settings[k]) * 1e-3 for k in ("eps_abs", "eps_rel")}
            self._solver.update_settings(**tight, max_iter=RETRY_MAX_ITER)
            res = self._solver.solve(raise_error=False)
            self._solver.update_settings(**{k: self.settings[k] for k in (*tight, "max_iter")})
            x = self._polish(qp, res)
            if x is None and res.info.status_val in (1, 2):
                x = np.minimum(np.maximum(res.x, qp.lb), qp.ub)
        found = x is not None and bool(np.all(np.isfinite(x)))
        return Solution(x if found else None, found, res.info.status, int(res.info.iter))

    def _polish(self, qp: QP, res) -> np.ndarray | None:
        """Polish any finite iterate (also one stopped at ``max_iter``: the KKT check decides)."""
        if res.x is None or res.y is None or not (np.all(np.isfinite(res.x)) and np.all(np.isfinite(res.y))):
            return None
        return polish(qp.P, qp.c, self._Abar, self._l, self._u, res.x, res.y)


def polish(
    P: np.ndarray,
    c: np.ndarray,
    Abar: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    tol: float = 1e-9,
    corrections: int = 5,
) -> np.ndarray | None:
    r"""The exact solution on the active set guessed from an ADMM iterate, or None if that guess fails.

    For :math:`\min \tfrac12 x^T P x + c^T x` s.t. :math:`lo \le \bar A x \le hi`, with
    :math:`z = \bar A x` and OSQP's duals ``y`` (> 0 at an upper bound, < 0 at a lower
    bound), a constraint is taken as active at its lower bound when :math:`z_i - lo_i < -y_i`
    and at its upper bound when :math:`hi_i - z_i < y_i` (OSQP's own rule). The KKT system
    :math:`[P\ \bar A_S^T; \bar A_S\ 0][x; y_S] = [-c; b_S]` is solved; a constraint it
    violates is added to the set and one whose multiplier has the wrong sign is removed
    (up to ``corrections`` times: degenerate steps, where ADMM leaves a weakly active row
    with a ~0 dual, need one or two). The result is returned only if it meets every bound
    within ``tol`` (scaled) and every multiplier has the right sign.
    """
    n = len(c)
    z = Abar @ x
    at_lo = z - lo < -y
    at_hi = (hi - z < y) & ~at_lo
    for _ in range(corrections + 1):
        act = np.flatnonzero(at_lo | at_hi)
        k = len(act)
        K = np.zeros((n + k, n + k))
        K[:n, :n] = P
        K[:n, n:] = Abar[act].T
        K[n:, :n] = Abar[act]
        rhs = np.concatenate([-c, np.where(at_lo[act], lo[act], hi[act])])
        try:
            sol = np.linalg.solve(K, rhs)
        except np.linalg.LinAlgError:  # duplicate active rows (two links, one witness point): consistent but singular
            sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
        scale = tol * (1.0 + np.abs(rhs).max() + np.abs(sol[:n]).max())
        if np.abs(K @ sol - rhs).max() > scale:  # inconsistent active set (conflicting bounds)
            return None
        xs, ys = sol[:n], sol[n:]
        zs = Abar @ xs
        below, above = zs < lo - scale, zs > hi + scale
        wrong = np.zeros(len(lo), dtype=bool)
        wrong[act] = (at_lo[act] & (ys > scale)) | (at_hi[act] & (ys < -scale))
        if not (below.any() or above.any() or wrong.any()):
            return xs
        at_lo = (at_lo | below) & ~wrong
        at_hi = (at_hi | above) & ~wrong & ~at_lo
    return None
