r"""A persistent OSQP solver for the controller's QP (fixed sparsity, update + warm start).

OSQP solves :math:`\min \tfrac12 x^T P x + q^T x` s.t. :math:`l \le \bar A x \le u`.
The pattern is set up once, on the first :meth:`OSQPSolver.solve`:

- ``P``: the dense upper triangle of the (N, N) cost matrix;
- :math:`\bar A = [I_N;\ A]`: the box ``lb ≤ x ≤ ub`` as identity rows, then every row of
  the QP (inactive rows keep their place with ``±inf`` bounds and zero coefficients).

Each step only the values change, and OSQP starts from the previous primal–dual
solution (``warm_starting``). ``q, l, u`` are updated every step; ``P`` and ``Ā`` only
every :data:`REFRESH_EVERY` steps, because their update refactors OSQP's KKT matrix (the
largest part of an OSQP step here) and ADMM is used only to guess the active set: the
:func:`polish` below always solves and checks the KKT conditions of the *current* QP,
and a guess it rejects makes the solver refresh P, Ā and run ADMM again before anything
else. Between two control steps (1 ms) P and Ā hardly change, so the guess is almost
always the same.

Accuracy (:data:`DEFAULTS`, measured on QPs recorded from controller episodes against
daqp, an exact active-set solver): ADMM runs to ``eps_abs = eps_rel = 1e-5`` (enough to
identify the active set), checking termination every 5 iterations (OSQP's default 25
made every warm-started step run 25 iterations; with 5 the bench's closed loop averages
~10), then :func:`polish` solves the KKT system of that active set exactly and accepts
it only if it is primal and dual feasible — the answer then agrees with daqp to ~1e-12.
If the check fails (ADMM stopped short of the right active set), ADMM is resumed once
with 1e-3 × the tolerances and polished again. An iterate stopped by ``max_iter`` is
polished too — the KKT check decides whether it is the answer: on degenerate QPs
(joints resting on their limits with a damper row nearly active) ADMM can crawl for
thousands of iterations after it has found the active set, so the first attempt stops
at 200 iterations and only the retry runs up to 4000. OSQP's own ``polishing`` is off:
version 1.1.3 prints "Polishing not needed" to stdout, regardless of ``verbose``, on
every solve where no constraint is active, which is most control steps.
"""

from __future__ import annotations

import numpy as np
import osqp
from scipy import sparse
from scipy.linalg import lapack

from qpik.control.qp import QP
from qpik.control.solvers import Solution, Solver

DEFAULTS: dict[str, object] = {
    "eps_abs": 1e-5,
    "eps_rel": 1e-5,
    "polishing": False,
    "max_iter": 200,
    "check_termination": 5,
    "warm_starting": True,
    "verbose": False,
}


RETRY_MAX_ITER = 4000
REFRESH_EVERY = 10
"""Steps between updates of P and Ā in OSQP (q, l, u are updated every step); see the module docstring."""


INFTY = 1e30  # OSQP's infinity: bounds are clipped to it (the public ``update`` does the same)


class OSQPSolver(Solver):
    """One OSQP workspace, reused for every step of a controller.

    Each step calls the extension object under ``osqp.OSQP`` directly (``update_data_vec``,
    ``update_data_mat``, ``solve``): measured on the controller bench, the public wrappers
    spent ~15 µs of Python per step (clipping bounds, derivative caches, building an info
    namespace) around ~30 µs of OSQP work.
    """

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
        self._pflat = self._pr * N + self._pc  # positions in P.ravel()
        P = sparse.csc_matrix((qp.P[self._pr, self._pc], self._pr, np.r_[0, np.cumsum(np.arange(1, N + 1))]), (N, N))
        # Ā = [I; A] dense: column j holds rows 0..N+m-1; _AbarT is its column-major storage (N, N+m)
        self._AbarT = np.zeros((N, N + m))
        self._AbarT[:, :N] = np.eye(N)
        self._AbarT[:, N:] = qp.A.T
        self._Abar = self._AbarT.T  # (N+m, N) view
        rows = np.tile(np.arange(N + m), N)
        A = sparse.csc_matrix((self._AbarT.ravel(), rows, np.arange(0, (N + m) * N + 1, N + m)), (N + m, N))
        self._l = np.concatenate([qp.lb, qp.l])
        self._u = np.concatenate([qp.ub, qp.u])
        self._lc, self._uc = np.empty(N + m), np.empty(N + m)
        self._solver = osqp.OSQP()
        self._solver.setup(P, qp.c.copy(), A, self._l, self._u, **self.settings)
        self._raw = self._solver._solver
        self._shape = (N, m)
        self._stale = 0  # steps since OSQP last got P and Ā

    def solve(self, qp: QP) -> Solution:
        N = qp.P.shape[0]
        if self._shape != (N, qp.A.shape[0]):
            self._setup(qp)
        else:
            self._AbarT[:, N:] = qp.A.T
            l, u = self._l, self._u
            l[:N], l[N:] = qp.lb, qp.l
            u[:N], u[N:] = qp.ub, qp.u
            self._raw.update_data_vec(
                q=qp.c, l=np.maximum(l, -INFTY, out=self._lc), u=np.minimum(u, INFTY, out=self._uc)
            )
            self._stale += 1
            if self._stale >= REFRESH_EVERY:
                self._refresh(qp)
        x, status, iters = self._run(qp)
        if x is None and self._stale:  # the guess may come from the stale P, Ā: refresh and run again
            self._refresh(qp)
            x, status, iters = self._run(qp)
        if x is None:  # ADMM stopped short of the active set: tighten once, then restore
            tight = {k: float(self.settings[k]) * 1e-3 for k in ("eps_abs", "eps_rel")}
            self._solver.update_settings(**tight, max_iter=RETRY_MAX_ITER)
            x, status, iters = self._run(qp, fallback=True)
            self._solver.update_settings(**{k: self.settings[k] for k in (*tight, "max_iter")})
        found = x is not None and bool(np.all(np.isfinite(x)))
        return Solution(x if found else None, found, status, iters)

    def _refresh(self, qp: QP) -> None:
        """Give OSQP the current P and Ā (it refactors its KKT matrix)."""
        self._raw.update_data_mat(P_x=qp.P.ravel()[self._pflat], P_i=None, A_x=self._AbarT.ravel(), A_i=None)
        self._stale = 0

    def _run(self, qp: QP, fallback: bool = False) -> tuple[np.ndarray | None, str, int]:
        """Run ADMM and polish its iterate (also one stopped at ``max_iter``: the KKT check decides).

        With ``fallback``, an unpolishable iterate that OSQP reports solved is returned clipped to the box.
        """
        raw = self._raw
        raw.solve()
        info, sol = raw.info, raw.solution
        x, y = sol.x, sol.y
        out = None
        if x is not None and y is not None and np.isfinite(x).all() and np.isfinite(y).all():
            out = polish(qp.P, qp.c, self._Abar, self._l, self._u, x, y)
        if out is None and fallback and info.status_val in (1, 2):
            out = np.minimum(np.maximum(x, qp.lb), qp.ub)
        return out, info.status, int(info.iter)


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
    w = Abar @ x + y  # z + y: below lo ⇔ z - lo < -y, above hi ⇔ hi - z < y
    at_lo = w < lo
    at_hi = (w > hi) & ~at_lo
    act = np.flatnonzero(at_lo | at_hi)
    for _ in range(corrections + 1):
        if len(act):
            k = n + len(act)
            Aact = Abar[act]
            K = np.zeros((k, k))
            K[:n, :n] = P
            K[:n, n:] = Aact.T
            K[n:, :n] = Aact
            lower = at_lo[act]
            rhs = np.concatenate((-c, np.where(lower, lo[act], hi[act])))
        else:  # the common step: no constraint active, x = -P⁻¹c
            K, rhs = P, -c
        sol, singular = lapack.dgesv(K, rhs)[2:]  # LAPACK directly: np.linalg.solve adds ~5 µs of checks
        if singular:  # duplicate active rows (two links, one witness point): consistent but singular
            sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
        scale = tol * (1.0 + abs(rhs).max() + abs(sol[:n]).max())
        if singular and abs(K @ sol - rhs).max() > scale:  # inconsistent active set (conflicting bounds)
            return None
        xs = sol[:n]
        zs = Abar @ xs
        # multipliers: ≤ 0 at a lower bound, ≥ 0 at an upper bound
        signed = np.where(lower, sol[n:], -sol[n:]) if len(act) else None
        if (lo - zs).max() <= scale and (zs - hi).max() <= scale and (signed is None or signed.max() <= scale):
            return xs
        wrong = np.zeros(len(lo), dtype=bool)
        if signed is not None:
            wrong[act] = signed > scale
        at_lo = (at_lo | (zs < lo - scale)) & ~wrong
        at_hi = (at_hi | (zs > hi + scale)) & ~wrong & ~at_lo
        act = np.flatnonzero(at_lo | at_hi)
    return None
