r"""The path NLP solved: the plan refined jointly over every waypoint by IPOPT (:class:`PathNLP`).

The NLP (its variables, objective, constraints and assembled derivatives) is :mod:`qpik.planning.path_problem`'s.
A closed-form arm's parameters ψ_k (rad, unwrapped) are bounded :data:`~qpik.planning.path_problem.INSIDE`
inside the exact feasible interval of their branch row (:func:`interval_bounds`), a joint-space path's joints
inside their limits. The clearance constraints enter only at waypoints near an obstacle, in at most
:data:`ROUNDS` solves.

:attr:`Refined.start_cost` is the objective at the start (for a DP start, the DP's cost).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.analytic.intervals import wrap
from qpik.core.layout import Layout
from qpik.core.stopwatch import Stopwatch
from qpik.geometry.contacts import capsule_clearance
from qpik.planning.grid import Grid
from qpik.planning.path_problem import INSIDE, PathModel

OPTIONS = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": 1e-9,
    "ipopt.constr_viol_tol": 1e-10,
    "ipopt.max_iter": 200,
    "ipopt.mu_strategy": "adaptive",
    "show_eval_warnings": False,
}
"""IPOPT options of the path NLP."""
NEAR = 0.05
"""m: a waypoint's clearance constraints enter the NLP where a capsule is closer than d_s + NEAR to an obstacle
at the start."""
ROUNDS = 3
"""Solves of the NLP at most, each with the waypoints that came near an obstacle in the one before."""


@dataclass
class Refined:
    """The NLP's answer.

    Attributes:
        param: (N,) parameters, rad (unwrapped; empty without a closed form); q: (N, n) configurations, rad.
        cost: the objective at the answer; start_cost: at the DP's plan.
        status: IPOPT's return status; iterations; time: the solve's seconds, without building the NLPs and their
            compiled functions.
    """

    param: np.ndarray
    q: np.ndarray
    cost: float
    start_cost: float
    status: str
    iterations: int
    time: float


def interval_bounds(grid: Grid, rows: np.ndarray, param: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) lower and upper bounds of ψ_k (rad, in the 2π-branch of ``param``, unwrapped): the exact feasible
    interval of row ``rows[k]`` at waypoint k that holds ``param[k]``, joined across ±π."""
    lo, hi = np.empty(len(param)), np.empty(len(param))
    for k, (b, p) in enumerate(zip(rows, param)):
        ivs = grid.intervals[k].intervals[int(b)]
        x = float(wrap(p))
        a, c = next(((u, v) for u, v in ivs if u - 1e-9 <= x <= v + 1e-9), (x, x))
        if np.isclose(c, np.pi) and ivs and np.isclose(ivs[0][0], -np.pi):
            c = ivs[0][1] + 2 * np.pi if ivs[0] != (a, c) else c
        if np.isclose(a, -np.pi) and ivs and np.isclose(ivs[-1][1], np.pi):
            a = ivs[-1][0] - 2 * np.pi if ivs[-1] != (a, c) else a
        shift = p - x
        lo[k], hi[k] = max(a, x - 2 * np.pi) + shift, min(c, x + 2 * np.pi) + shift
    return lo, hi


class PathNLP(PathModel):
    """The NLP of :class:`~qpik.planning.path_problem.PathModel` for one path, solved by :meth:`solve`.

    A waypoint's clearance constraints are in the NLP only where some link capsule is closer than
    ``d_safe`` + :data:`NEAR` to an obstacle, or to another capsule of a checked pair, at the start: far-away
    obstacles cost nothing. If the answer
    comes closer than d_s at a waypoint left out, that waypoint joins and the NLP is solved again from the
    answer (at most :data:`ROUNDS` solves); an answer that keeps d_s everywhere is a KKT point of the
    whole problem too (the constraints left out are inactive there). Arguments: as
    :class:`~qpik.planning.path_problem.PathModel`'s.
    """

    def _bounds(self, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.grid is not None:
            return interval_bounds(self.grid, self.rows, z0[0])
        return np.tile(self.robot.q_min[:, None], len(self.rows)), np.tile(self.robot.q_max[:, None], len(self.rows))

    def solve(self, z0: np.ndarray) -> Refined:
        """IPOPT from ``z0``: the parameters (N,) (rad; unwrapped here) or the joints (N, n) (rad)."""
        watch = Stopwatch()
        with watch.paused():
            self.value()  # built once, with the clock paused
        z0 = np.unwrap(np.asarray(z0, float))[None] if self.grid is not None else np.asarray(z0, float).T
        lo, hi = self._bounds(z0)
        inward = INSIDE if self.grid is not None else 0.0
        lo, hi = np.atleast_2d(lo) + inward, np.atleast_2d(hi) - inward
        z = np.clip(z0, lo, hi)
        near = self._clearance(z) < self.d_safe + NEAR
        start_cost, iterations = None, 0
        for _ in range(ROUNDS):
            z, cost0, its, status = self._solve(z, lo, hi, near, watch)
            start_cost = cost0 if start_cost is None else start_cost
            iterations += its
            grow = (self._clearance(z) < self.d_safe + INSIDE) & ~near
            if not grow.any():
                break
            near |= grow
        cost, _, q = self.value()(z, self._least_t(z))
        return Refined(z[0] if self.grid is not None else np.zeros(0), np.asarray(q), float(cost), float(start_cost),
                       status, iterations, watch.stop())  # fmt: skip

    def _clearance(self, z: np.ndarray) -> np.ndarray:
        """(N,) the smallest clearance at the variables z, m: the pairs :mod:`qpik.geometry.contacts` checks and the
        capsule pairs of the scene."""
        q = self._q(z)
        return np.minimum(capsule_clearance(self.robot, q, self.obstacles), self.scene.self_clearance(q))

    def _q(self, z: np.ndarray) -> np.ndarray:
        """(N, n) the configurations at the variables z (w, N)."""
        return np.asarray(self.value()(z, np.zeros((self.n_t, len(self.rows))))[2])

    def _solve(self, z0: np.ndarray, lo: np.ndarray, hi: np.ndarray, near: np.ndarray, watch: Stopwatch):
        """One IPOPT solve from z0 with the clearance constraints of ``near``; the NLP is built with ``watch``
        paused."""
        N = len(self.rows)
        with watch.paused():
            nlp = self.problem(near)
            options = dict(OPTIONS)
            if nlp.hess_lag is not None:
                options.update(hess_lag=nlp.hess_lag, grad_f=nlp.grad_f, jac_g=nlp.jac_g)
            solver = ca.nlpsol("plan_nlp", "ipopt", {"x": nlp.x, "f": nlp.f, "g": nlp.g}, options)
            cost = ca.Function("f", [nlp.z, nlp.t], [nlp.f])
        t0 = self._least_t(z0)
        start = float(cost(z0, t0))
        x0 = np.concatenate([z0.T.ravel(), t0.T.ravel()])
        lbx = np.concatenate([lo.T.ravel(), np.full(self.n_t * N, -np.inf)])
        ubx = np.concatenate([hi.T.ravel(), np.full(self.n_t * N, np.inf)])
        sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=nlp.lbg, ubg=nlp.ubg)
        stats = solver.stats()
        zs = np.clip(np.asarray(sol["x"]).ravel()[: self.width * N].reshape(N, self.width).T, lo, hi)
        return zs, start, int(stats.get("iter_count", 0)), str(stats.get("return_status", ""))

    def _least_t(self, z: np.ndarray) -> np.ndarray:
        """(n_t, N): each epigraph variable at the largest of its pieces (where the objective's true value is)."""
        N = len(self.rows)
        if not self.n_t:
            return np.zeros((0, N))
        h = np.asarray(self.value()(z, np.zeros((self.n_t, N)))[1])  # pieces h - t at t = 0: the pieces
        pieces = Layout(**{f"t{k}": size for k, size in enumerate(self.sizes)}).views(h.T)  # each (N, size)
        return np.array([p.max(axis=1) for p in pieces.values()])
