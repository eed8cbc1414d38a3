r"""A persistent OSQP solver for the controller's QP (fixed sparsity, update + warm start).

OSQP solves :math:`\min \tfrac12 x^T P x + q^T x` s.t. :math:`l \le \bar A x \le u`.
The pattern is set up once, on the first :meth:`OSQPSolver.solve`:

- ``P``: the dense upper triangle of the (N, N) cost matrix;
- :math:`\bar A = [I_N;\ A]`: the box ``lb ≤ x ≤ ub`` as identity rows, then every row of
  the QP (inactive rows keep their place with ``±inf`` bounds and zero coefficients).

Each step only the values change, and OSQP starts from its previous primal–dual
iterate (``warm_starting``). ``q, l, u`` are given to OSQP before every ADMM run; ``P`` and ``Ā``
only when :data:`REFRESH_EVERY` steps have passed since they last were, because their update
refactors OSQP's KKT matrix (the largest part of an OSQP step here) and ADMM is used only to
guess the active set:
:func:`polish` always solves the *current* QP exactly. Between two control steps (1 ms)
P and Ā hardly change, so the guess is almost always the same.

A step first tries the previous step's answer as the guess: :func:`polish` from its solution ``x`` and
the multipliers ``y`` of the last ADMM run (exact from any guess, see below). Between two control steps
the active set rarely changes, and when it does the dual steps of :func:`polish` complete it, so most
steps need no ADMM run at all (status :data:`REUSED`, 0 iterations). Only when that answer is not
found (more than :data:`MAX_POLISH_STEPS` steps away, or no QP solution) does the step run OSQP:

One ADMM run and one polish, each with a hard bound on its work: ADMM runs
to ``eps_abs = eps_rel = 1e-5`` (enough to identify the active set), checking termination
every 5 iterations, at most ``max_iter`` = 200 iterations; :func:`polish` then solves the KKT system of
the guessed active set, and, if the guess was not exactly right, completes it with at most
:data:`MAX_POLISH_STEPS` dual active-set steps (Goldfarb–Idnani). No constraint guess is ever accepted
unchecked: the answer meets every bound and every multiplier has its sign, else the step reports no
solution (the controller then falls back to DAQP). OSQP's own ``polishing`` is off.

The extension object under ``osqp.OSQP`` is called directly; why, and the measurements behind these
choices, are in the design notes (docs/design-notes.md).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import osqp
from scipy import sparse
from scipy.linalg import lapack

from qpik.control.qp import QP
from qpik.control.solvers.base import Solution, Solver
from qpik.native.sources import load_source

DEFAULTS: dict[str, object] = {
    "eps_abs": 1e-5,
    "eps_rel": 1e-5,
    "polishing": False,
    "max_iter": 200,
    "check_termination": 5,
    "warm_starting": True,
    "verbose": False,
}


MAX_POLISH_STEPS = 16
"""Bound on the dual active-set steps (additions and removals) of :func:`polish`."""
POLISH_TOL = 1e-9
"""Relative tolerance of :func:`polish`'s final checks (bounds and multiplier signs)."""
REFRESH_EVERY = 10
"""Steps after which P and Ā are given to OSQP again before its next ADMM run (q, l, u are given before every
run); see the module docstring."""
REUSED = "solved (previous active set)"
"""The status of a step answered by :func:`polish` from the previous step's solution, without an ADMM run."""


INFTY = 1e30  # OSQP's infinity: bounds are clipped to it (the public ``update`` does the same)


class OSQPSolver(Solver):
    """One OSQP workspace, reused for every step of a controller.

    Each step calls the extension object under ``osqp.OSQP`` directly (``update_data_vec``,
    ``update_data_mat``, ``solve``): the public wrappers' Python costs more than OSQP's work here.
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
        self._guess: tuple[np.ndarray, np.ndarray] | None = None  # (x, y) whose active set the next step tries

    def solve(self, qp: QP) -> Solution:
        try:
            return self._solve(qp)
        except (osqp.OSQPException, ValueError) as exc:  # OSQP's own data checks: report, never raise in the loop
            self._shape = None  # set up again on the next call
            return Solution(None, False, f"error: {exc}")

    def _solve(self, qp: QP) -> Solution:
        N = qp.P.shape[0]
        if self._shape != (N, qp.A.shape[0]):
            self._setup(qp)
        else:
            self._stale += 1
            if self._guess is not None:  # the previous step's active set first (see the module docstring)
                x = self._polish(qp, *self._guess)
                if x is not None:
                    self._guess = (x, self._guess[1])
                    return Solution(x, True, REUSED, 0)
            self._load(qp)
            self._raw.update_data_vec(
                q=qp.c, l=np.maximum(self._l, -INFTY, out=self._lc), u=np.minimum(self._u, INFTY, out=self._uc)
            )
            if self._stale >= REFRESH_EVERY:
                self._refresh(qp)
        raw = self._raw
        raw.solve()
        info, sol = raw.info, raw.solution
        x, y = sol.x, sol.y
        if x is None or y is None or not (math.isfinite(x @ x) and math.isfinite(y @ y)):
            x = None
        else:
            x = self._polish(qp, x, y)
        self._guess = None if x is None else (x, y.copy())
        return Solution(x, x is not None, info.status, int(info.iter))

    def _load(self, qp: QP) -> None:
        """Copy the QP's rows and bounds into Ā (:attr:`_AbarT`, column-major) and its bounds ``[lb; l]``,
        ``[ub; u]``, as OSQP takes them."""
        N = qp.P.shape[0]
        self._AbarT[:, N:] = qp.A.T
        l, u = self._l, self._u
        l[:N], l[N:] = qp.lb, qp.l
        u[:N], u[N:] = qp.ub, qp.u

    def _polish(self, qp: QP, x: np.ndarray, y: np.ndarray) -> np.ndarray | None:
        """:func:`polish` (in C where it compiles: it reads the QP itself) of the current QP from the guess of
        ``(x, y)``."""
        if (compiled := _compiled_polish()) is not None:
            return compiled(qp.P, qp.c, qp.A, qp.lb, qp.ub, qp.l, qp.u, x, y, POLISH_TOL, MAX_POLISH_STEPS)
        self._load(qp)
        return polish(qp.P, qp.c, self._AbarT.T, self._l, self._u, (x, y), POLISH_TOL, MAX_POLISH_STEPS)

    def _refresh(self, qp: QP) -> None:
        """Give OSQP the current P and Ā (it refactors its KKT matrix)."""
        self._raw.update_data_mat(P_x=qp.P.ravel()[self._pflat], P_i=None, A_x=self._AbarT.ravel(), A_i=None)
        self._stale = 0


@cache
def _compiled_polish():
    """:func:`polish` in C (``polish.c``, the same steps; a CPython extension, :func:`qpik.native.sources.load_source`),
    or None without a compiler. It takes the QP's own arrays, ``polish(P, c, A, lb, ub, l, u, x, y, tol, max_steps)``
    (Ā = [I; A], lo = [lb; l], hi = [ub; u] formed in C)."""
    module = load_source("qpik_polish", "extension", ["polish.c"])
    return None if module is None else module.polish


def polish(
    P: np.ndarray,
    c: np.ndarray,
    Abar: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    iterate: tuple[np.ndarray, np.ndarray],
    tol: float = POLISH_TOL,
    max_steps: int = MAX_POLISH_STEPS,
) -> np.ndarray | None:
    r"""The exact solution, from the active set guessed by an ADMM iterate ``(x, y)`` (primal (n,), dual (M,));
    None if not found.

    QP: :math:`\min \tfrac12 x^T P x + c^T x` s.t. :math:`lo \le \bar A x \le hi`, P (n, n)
    SPD, :math:`\bar A` (M, n). With :math:`P = L L^T`, :math:`x_0 = -P^{-1} c` and
    :math:`H = \bar A P^{-1} \bar A^T` (M, M), the solution with the rows W at their bounds
    :math:`b_W` (``lo`` or ``hi``) is :math:`x = x_0 + P^{-1} \bar A_W^T \nu` with
    :math:`H_{WW}\, \nu = b_W - \bar A_W x_0`, and :math:`\bar A x = \bar A x_0 + H_{:W} \nu`;
    it is optimal when every other row is within its bounds and every multiplier has its
    sign (:math:`\mu = \sigma \nu \ge 0`, σ = +1 at a lower bound, −1 at an upper bound).

    1. Guess, OSQP's rule with :math:`z = \bar A x` and its duals ``y`` (> 0 at an upper,
       < 0 at a lower bound): row i is at its lower bound when :math:`z_i - lo_i < -y_i`,
       at its upper bound when :math:`hi_i - z_i < y_i`. Rows of the guess that are linearly
       dependent on others (duplicate dampers: two links, one witness point) are left out
       (pivoted Cholesky of :math:`H_{WW}` scaled to unit diagonal), so :math:`H_{WW}` is
       nonsingular — with both duplicates in, the KKT solve gave multipliers of ±1e16.
    2. While a multiplier is negative, the most negative constraint leaves W: x is then the
       minimiser subject to W's constraints alone (dual feasible), and the answer if it
       meets every other bound — ADMM's guess was right (most steps).
    3. Otherwise Goldfarb–Idnani dual active-set steps from there: the most violated row p
       enters on its violated side :math:`\sigma_p`; per unit t of its multiplier,
       :math:`\nu_W` changes by :math:`\sigma_p g`, :math:`g = -H_{WW}^{-1} H_{Wp}`, and
       :math:`\bar A x` by :math:`\sigma_p (H_{:p} + H_{:W} g)`, which closes the violation at
       the rate :math:`H_{pp} + H_{pW} g \ge 0`; t is the full step unless a multiplier of W
       reaches 0 first: that constraint leaves W and p goes on entering (if :math:`\bar A_p`
       is in the span of W only such steps exist; none means the QP is infeasible). The dual
       objective rises with every step, so the method ends; ``max_steps`` (additions and
       removals) bounds its cost.

    The answer is returned only if it meets every bound within ``tol`` and every multiplier
    is ≥ −``tol``, both scaled by 1 + max|c| + the largest finite bound (the problem's
    own scale: ADMM's iterate is huge on an infeasible QP and must not loosen the check).
    """
    x, y = iterate
    w = Abar @ x + y  # z + y: below lo ⇔ z - lo < -y, above hi ⇔ hi - z < y
    lower = w < lo
    guessed = lower | (w > hi)
    L, info = lapack.dpotrf(P, lower=1)
    if info:
        return None
    x0 = lapack.dpotrs(L, -c, lower=1)[0]
    r0 = Abar @ x0
    viol = np.maximum(lo - r0, r0 - hi).max()
    if viol <= 0.0 and not guessed.any():  # the common step: nothing active, every bound met strictly
        return x0
    bound = max(abs(lo[np.isfinite(lo)]).max(initial=0.0), abs(hi[np.isfinite(hi)]).max(initial=0.0))
    scale = tol * (1.0 + abs(c).max() + bound)
    guess = np.flatnonzero(guessed)
    if not len(guess) and viol <= scale:  # nothing active, a bound met within the tolerance
        return x0
    live = np.isfinite(lo) | np.isfinite(hi)  # a row bounded by ±inf on both sides is never violated nor active:
    C = np.zeros(Abar.T.shape)  # (n, M): P⁻¹ Āᵀ, and its part of H stays 0 (most of the M² n work)
    C[:, live] = lapack.dpotrs(L, Abar[live].T, lower=1)[0]  # not dtrtrs: OpenBLAS threads it even at n = 7
    H = Abar @ C
    b = np.where(lower, lo, hi)  # the bound each row is at (rows entering later set theirs)
    W = _independent(H, guess)
    sigma = np.where(lower[W], 1.0, -1.0)
    while True:  # a dual feasible start: drop the most negative multiplier until none is
        nu = _solve(H, W, b[W] - r0[W])
        if nu is None:
            return None
        mu = sigma * nu
        if not len(W) or mu.min() >= 0.0:
            break
        keep = np.arange(len(W)) != np.argmin(mu)
        W, sigma = W[keep], sigma[keep]
    z = r0 + H[:, W] @ nu
    steps = 0
    while True:
        below, above = lo - z, z - hi
        viol = np.maximum(below, above)
        p = int(np.argmax(viol))
        if viol[p] <= scale:
            break
        sp = 1.0 if below[p] > 0.0 else -1.0
        b[p] = lo[p] if sp > 0.0 else hi[p]
        gap, nu_p = viol[p], 0.0
        while True:  # raise p's multiplier until p is met (it joins W) or a constraint of W leaves
            steps += 1
            if steps > max_steps:
                return None
            g = -_solve(H, W, H[W, p]) if len(W) else nu[:0]
            dz = sp * (H[:, p] + H[:, W] @ g)
            rate = sp * dz[p]
            full = gap / rate if rate > 1e-10 * H[p, p] else np.inf
            u = sigma * sp * g  # dμ_W / dt
            shrink = np.flatnonzero(u < 0.0)
            ratios = sigma[shrink] * nu[shrink] / -u[shrink]
            j = int(np.argmin(ratios)) if len(shrink) else -1
            t = min(full, ratios[j]) if len(shrink) else full
            if not np.isfinite(t):  # p cannot be met with W's constraints: the QP is infeasible
                return None
            z, gap, nu, nu_p = z + t * dz, gap - t * rate, nu + t * sp * g, nu_p + sp * t
            if t == full:
                W, sigma, nu = np.append(W, p), np.append(sigma, sp), np.append(nu, nu_p)
                break
            keep = np.arange(len(W)) != shrink[j]
            W, sigma, nu = W[keep], sigma[keep], nu[keep]
    if steps:  # re-solve on the final W: the answer is not left with the steps' rounding
        nu = _solve(H, W, b[W] - r0[W])
        if nu is None:
            return None
    if len(W) and (sigma * nu).min() < -scale:
        return None
    xs = x0 + C[:, W] @ nu
    zs = Abar @ xs
    return xs if np.maximum(lo - zs, zs - hi).max() <= scale else None


def _independent(H: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The rows that are linearly independent: pivoted Cholesky of H[rows, rows] scaled to unit diagonal."""
    if len(rows) <= 1:
        return rows
    G = H[np.ix_(rows, rows)]
    s = 1.0 / np.sqrt(G.diagonal())
    _, piv, rank, _ = lapack.dpstrf(G * s * s[:, None], tol=1e-12)
    return rows if rank == len(rows) else rows[np.sort(piv[:rank] - 1)]


def _solve(H: np.ndarray, W: np.ndarray, rhs: np.ndarray) -> np.ndarray | None:
    """H[W, W]⁻¹ rhs (None if singular)."""
    if not len(W):
        return rhs
    sol, singular = lapack.dgesv(H[np.ix_(W, W)], rhs)[2:]
    return None if singular else sol
