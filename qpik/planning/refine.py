r"""The path NLP: the plan refined jointly over every waypoint by a sparse NLP, solved by IPOPT.

Closed-form arms: the variables are the parameter :math:`\psi_k` at every waypoint on the DP's
branch row :math:`b_k` (unwrapped, so that it moves continuously) and the epigraph variables
:math:`t_k` of the point objective's maxima (:class:`qpik.objectives.Split`). With
:math:`q_k = q_{b_k}(T_k, \psi_k)` the closed form
(:meth:`~qpik.analytic.solver.AnalyticSolver.casadi_function`):

.. math::

    \min\ \sum_{k \in C} \frac{\lVert q_{k+1} - q_k \rVert^2}{\Delta_k}
          + \sum_k w_k \Big(s(q_k) + \sum_m \omega_m t_{k,m}\Big)
    \quad\text{s.t.}\quad
    \psi_k \in I_k,\quad h_{k,m,i}(q_k) \le t_{k,m},\quad d_{c,o}(q_k) \ge d_s,\quad
    |q_{k+1,j} - q_{k,j}| \le \ell_{k,j}\ (k \in C)

and, with times and ``a_max``, :math:`|(q_{k+2} - q_{k+1})/\Delta t_{k+1} - (q_{k+1} - q_k)/\Delta t_k|
\le a_{max} (\Delta t_k + \Delta t_{k+1})/2`. C are the continuous transitions (not the
reconfigurations) and :math:`I_k` the exact feasible interval of the DP's state (every joint
inside its limits there, the branch reaches the pose), so the bounds on ψ_k keep the limits.

Arms without a closed form: the variables are the joints :math:`q_k` themselves (bounded by the
limits), with the pose as an equality at every waypoint, :math:`[p_k^* - p(q_k);\ \log(R_k^* R(q_k)^T)] = 0`
(:func:`qpik.lie.log_expr`), the same objective and constraints.

Sparse by construction: the per-waypoint closed form (or pose error), objective and distances are
one CasADi ``Function`` mapped over the waypoints of each run of one branch row (``Function.map``),
so the constraint Jacobian and the Lagrangian's Hessian are block-banded (a waypoint couples only
with its neighbours). :attr:`Refined.start_cost` is the objective at the start (for a DP start,
the DP's cost).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.analytic.intervals import wrap
from qpik.geometry.distance import ObstacleSet, distances
from qpik.lie import log_expr
from qpik.objectives import Context, Objective, pair_count
from qpik.planning.dp import Transitions
from qpik.planning.grid import Grid
from qpik.robots.robot import Robot

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
INSIDE = 1e-8
"""rad and m: the NLP keeps ψ this far inside its feasible interval (whose ends are exact to 1e-9 rad) and the
clearance this far above d_s, so that its answer, feasible to IPOPT's tolerance, meets every check exactly."""


@dataclass
class Refined:
    """The NLP's answer.

    Attributes:
        param: (N,) parameters, rad (unwrapped; empty without a closed form); q: (N, n) configurations, rad.
        cost: the objective at the answer; start_cost: at the DP's plan.
        status: IPOPT's return status; iterations; time (s).
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


class PathNLP:
    """The NLP of the module docstring for one path, built and solved by :meth:`solve`.

    A waypoint's clearance constraints are in the NLP only where some link capsule is closer than
    ``d_safe`` + :data:`NEAR` to an obstacle at the start: far-away obstacles cost nothing. If the answer
    comes closer than d_s at a waypoint left out, that waypoint joins and the NLP is solved again from the
    answer (at most :data:`ROUNDS` solves); an answer that keeps d_s everywhere is a KKT point of the
    whole problem too (the constraints left out are inactive there).

    Args:
        robot: the arm.
        poses: (N, 4, 4) waypoints, base frame.
        objective: the point objective, or None.
        obstacles: the obstacles (packed); d_safe: m.
        tr: the transition bounds and weights.
        continuous: (N-1,) whether transition k is continuous (not a reconfiguration).
        q_ref: (n,) the objective's reference configuration, rad.
        grid: for a closed-form arm, the DP's grid (solver, feasible intervals) and ``rows`` (N,) its
            branch rows; None: the joints are the variables.
    """

    def __init__(
        self,
        robot: Robot,
        poses: np.ndarray,
        objective: Objective | None,
        obstacles: ObstacleSet,
        d_safe: float,
        tr: Transitions,
        continuous: np.ndarray,
        q_ref: np.ndarray,
        grid: Grid | None = None,
        rows: np.ndarray | None = None,
    ):
        self.robot, self.poses, self.objective, self.obstacles = robot, poses, objective, obstacles
        self.d_safe, self.tr, self.q_ref, self.grid = float(d_safe), tr, q_ref, grid
        self.continuous = np.asarray(continuous, bool)
        N, n = len(poses), robot.dof
        self.rows = np.zeros(N, int) if rows is None else np.asarray(rows, int)
        self.p_obj = np.zeros(0) if objective is None else objective.params(robot)
        self.n = n
        self.width = 1 if grid is not None else n  # variables per waypoint
        self._points: dict[tuple[int, bool], ca.Function] = {}
        self._value_fn: ca.Function | None = None
        self.sizes = self._sizes()
        self.n_t = len(self.sizes)

    def _sizes(self) -> list[int]:
        """The number of pieces of each maximum of the objective's split (the epigraph variables per waypoint)."""
        if self.objective is None:
            return []
        q = ca.SX.sym("q", self.n)
        ctx = Context(self.robot, q, ca.SX.sym("r", self.n), self.obstacles,
                      ca.SX.sym("o", self.obstacles.params.size))  # fmt: skip
        return [h.numel() for _, h in self.objective.split(ctx, ca.SX.sym("p", self.p_obj.size)).maxima]

    def _point(self, b: int, near: bool) -> ca.Function:
        """``(T, z, t, p, q_ref, obstacle params) -> (q, cost, epigraph (≤ 0), g)`` of one waypoint on row b:
        g = [distances (≥ d_s) if ``near``; pose error (= 0, joints only)]."""
        key = (b, near)
        if key in self._points:
            return self._points[key]
        robot, n = self.robot, self.n
        cols, z = ca.SX.sym("T", 16), ca.SX.sym("z", self.width)
        T = ca.reshape(cols, 4, 4)  # the pose's entries in CasADi's column-major order
        p, q_ref = ca.SX.sym("p", self.p_obj.size), ca.SX.sym("q_ref", n)
        prm = ca.SX.sym("obstacles", self.obstacles.params.size)
        q = self.grid.solver.casadi_function(T, z)[0][b, :].T if self.grid is not None else z
        ctx = Context(robot, q, q_ref, self.obstacles, prm)
        if self.objective is None:
            t, cost, g_epi = ca.SX.sym("t", 0), ca.SX(0.0), ca.SX(0, 1)
        else:
            t, cost, g_epi = self.objective.split(ctx, p).epigraph()
        g = [ctx.distances if near else ca.SX(0, 1)]
        if self.grid is None:
            R, pos = ctx.frames[-1]
            D = ca.mtimes(T[:3, :3], ca.vertcat(*[ca.horzcat(*R[i]) for i in range(3)]).T)  # R* Rᵀ
            g.append(ca.vertcat(T[:3, 3] - ca.vertcat(*pos), log_expr(D)))
        name = f"plan_point_{robot.name or 'robot'}_{b}" + ("_near" if near else "")
        self._points[key] = ca.Function(name, [cols, z, t, p, q_ref, prm], [q, cost, g_epi, ca.vertcat(*g)])
        return self._points[key]

    def _runs(self, near: np.ndarray) -> list[tuple[int, int]]:
        """(start, stop) of the runs of equal rows and equal ``near``."""
        cut = np.flatnonzero((np.diff(self.rows) != 0) | (np.diff(near.astype(int)) != 0)) + 1
        edges = [0, *cut.tolist(), len(self.rows)]
        return list(itertools.pairwise(edges))

    def _bounds(self, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.grid is not None:
            return interval_bounds(self.grid, self.rows, z0[0])
        return np.tile(self.robot.q_min[:, None], len(self.rows)), np.tile(self.robot.q_max[:, None], len(self.rows))

    def _clearance(self, q: np.ndarray) -> np.ndarray:
        """(N,) the smallest capsule–obstacle distance of configurations q (N, n), m (inf without obstacles)."""
        if not len(self.obstacles):
            return np.full(len(q), np.inf)
        moving = ~self.robot.fixed_capsules
        d = distances(self.robot.capsule_segments(q)[:, moving], self.robot.capsule_radii[moving], self.obstacles).d
        return d.reshape(len(q), -1).min(axis=1)

    def solve(self, z0: np.ndarray) -> Refined:
        """IPOPT from ``z0``: the parameters (N,) (rad; unwrapped here) or the joints (N, n) (rad)."""
        t_start = time.perf_counter()
        z0 = np.unwrap(np.asarray(z0, float))[None] if self.grid is not None else np.asarray(z0, float).T
        lo, hi = self._bounds(z0)
        inward = INSIDE if self.grid is not None else 0.0
        lo, hi = np.atleast_2d(lo) + inward, np.atleast_2d(hi) - inward
        z = np.clip(z0, lo, hi)
        near = self._clearance(self._q(z)) < self.d_safe + NEAR
        start_cost, iterations = None, 0
        for _ in range(ROUNDS):
            z, cost0, its, status = self._solve(z, lo, hi, near)
            start_cost = cost0 if start_cost is None else start_cost
            iterations += its
            grow = (self._clearance(self._q(z)) < self.d_safe + INSIDE) & ~near
            if not grow.any():
                break
            near |= grow
        cost, _, q = self._value()(z, self._least_t(z))
        return Refined(z[0] if self.grid is not None else np.zeros(0), np.asarray(q), float(cost), float(start_cost),
                       status, iterations, time.perf_counter() - t_start)  # fmt: skip

    def _q(self, z: np.ndarray) -> np.ndarray:
        """(N, n) the configurations at the variables z (w, N)."""
        return np.asarray(self._value()(z, np.zeros((self.n_t, len(self.rows))))[2])

    def _graph(self, near: np.ndarray):
        """MX symbols z (w, N), t (n_t, N) and expressions Q (n, N), the cost per waypoint (1, N), the epigraph
        pieces (n_epi, N) and the other constraints per run (a list)."""
        N = len(self.rows)
        z, t = ca.MX.sym("z", self.width, N), ca.MX.sym("t", self.n_t, N)
        cols = np.ascontiguousarray(np.swapaxes(self.poses, 1, 2)).reshape(N, 16).T  # (16, N) column-major poses
        Qs, costs, epis, others = [], [], [], []
        for a, b in self._runs(near):
            mapped = self._point(int(self.rows[a]), bool(near[a])).map(b - a, "serial")
            q, c, e, g = mapped(ca.DM(cols[:, a:b]), z[:, a:b], t[:, a:b], self.p_obj, self.q_ref,
                                self.obstacles.params)  # fmt: skip
            Qs.append(q), costs.append(c), epis.append(e), others.append((a, b, g))
        return z, t, ca.horzcat(*Qs), ca.horzcat(*costs), ca.horzcat(*epis), others

    def _value(self) -> ca.Function:
        """``(z, t) -> (J, epigraph pieces (n_epi, N), Q^T (N, n))`` (built once)."""
        if self._value_fn is None:
            z, t, Q, cost_pt, E, _ = self._graph(np.zeros(len(self.rows), bool))
            self._value_fn = ca.Function("value", [z, t], [self._cost(Q, cost_pt), E, Q.T])
        return self._value_fn

    def _cost(self, Q: ca.MX, cost_pt: ca.MX) -> ca.MX:
        """J: the motion term over the continuous transitions plus the weighted point costs."""
        D = Q[:, 1:] - Q[:, :-1]
        motion = ca.sum2(ca.sum1(D * D) * ca.DM(self.tr.motion * self.continuous).T)
        return motion + ca.sum2(cost_pt * ca.DM(self.tr.point).T)

    def _solve(self, z0: np.ndarray, lo: np.ndarray, hi: np.ndarray, near: np.ndarray):
        tr, N = self.tr, len(self.rows)
        z, t, Q, cost_pt, E, others = self._graph(near)
        D = Q[:, 1:] - Q[:, :-1]  # (n, N-1)
        f = self._cost(Q, cost_pt)
        n_d = pair_count(self.robot, self.obstacles)
        n_eq = 0 if self.grid is not None else 6
        g_parts, lbg, ubg = [ca.vec(E)], [np.full(E.numel(), -np.inf)], [np.zeros(E.numel())]
        for a, b, g in others:
            d = n_d if near[a] else 0
            g_parts.append(ca.vec(g))
            lbg.append(np.tile(np.r_[np.full(d, self.d_safe + INSIDE), np.zeros(n_eq)], b - a))
            ubg.append(np.tile(np.r_[np.full(d, np.inf), np.zeros(n_eq)], b - a))
        step = np.where(self.continuous[:, None], tr.step, np.inf)  # (N-1, n)
        g_parts.append(ca.vec(D)), lbg.append(-step.ravel()), ubg.append(step.ravel())
        if tr.a_max is not None and N > 2:
            V = D / ca.DM(tr.dt).T
            both = self.continuous[1:] & self.continuous[:-1]
            bound = np.where(both[:, None], np.outer(0.5 * (tr.dt[1:] + tr.dt[:-1]), tr.a_max), np.inf)
            g_parts.append(ca.vec(V[:, 1:] - V[:, :-1])), lbg.append(-bound.ravel()), ubg.append(bound.ravel())
        x = ca.vertcat(ca.vec(z), ca.vec(t))
        solver = ca.nlpsol("plan_nlp", "ipopt", {"x": x, "f": f, "g": ca.vertcat(*g_parts)}, OPTIONS)
        t0 = self._least_t(z0)
        start = float(ca.Function("f", [z, t], [f])(z0, t0))
        x0 = np.concatenate([z0.T.ravel(), t0.T.ravel()])
        lbx = np.concatenate([lo.T.ravel(), np.full(self.n_t * N, -np.inf)])
        ubx = np.concatenate([hi.T.ravel(), np.full(self.n_t * N, np.inf)])
        sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
        stats = solver.stats()
        zs = np.clip(np.asarray(sol["x"]).ravel()[: self.width * N].reshape(N, self.width).T, lo, hi)
        return zs, start, int(stats.get("iter_count", 0)), str(stats.get("return_status", ""))

    def _least_t(self, z: np.ndarray) -> np.ndarray:
        """(n_t, N): each epigraph variable at the largest of its pieces (where the objective's true value is)."""
        N = len(self.rows)
        if not self.n_t:
            return np.zeros((0, N))
        h = np.asarray(self._value()(z, np.zeros((self.n_t, N)))[1])  # pieces h - t at t = 0: the pieces
        out, start = [], 0
        for size in self.sizes:
            out.append(h[start : start + size].max(axis=0))
            start += size
        return np.array(out)
