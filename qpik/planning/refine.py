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
(:func:`qpik.nlp.full.rotation_error`), the same objective and constraints.

Sparse by construction: the per-waypoint closed form (or pose error), objective and distances are
one CasADi ``Function`` mapped over the waypoints of each run of one branch row (``Function.map``),
so the constraint Jacobian and the Lagrangian's Hessian are block-banded (a waypoint couples only
with its neighbours). :attr:`Refined.start_cost` is the objective at the start (for a DP start,
the DP's cost).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.analytic.intervals import wrap
from qpik.geometry.distance import ObstacleSet
from qpik.nlp.full import rotation_error
from qpik.objectives import Context, Objective
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
    """The NLP of the module docstring for one path, built once and solved by :meth:`solve`.

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
        self._points = {int(b): self._point(int(b)) for b in np.unique(self.rows)}

    def _point(self, b: int) -> ca.Function:
        """``(T, z, t, p, q_ref, obstacle params) -> (q, cost, g)`` of one waypoint: g = [epigraph (≤ 0); distances
        (≥ d_s); pose error (= 0, joints only)]."""
        robot, n = self.robot, self.n
        cols, z = ca.SX.sym("T", 16), ca.SX.sym("z", self.width)
        T = ca.reshape(cols, 4, 4)  # the pose's entries in CasADi's column-major order
        p, q_ref = ca.SX.sym("p", self.p_obj.size), ca.SX.sym("q_ref", n)
        prm = ca.SX.sym("obstacles", self.obstacles.params.size)
        q = self.grid.solver.casadi_function(T, z)[0][b, :].T if self.grid is not None else z
        ctx = Context(robot, q, q_ref, self.obstacles, prm)
        if self.objective is None:
            t, cost, g_epi, sizes = ca.SX.sym("t", 0), ca.SX(0.0), ca.SX(0, 1), []
        else:
            split = self.objective.split(ctx, p)
            t, cost, g_epi = split.epigraph()
            sizes = [h.numel() for _, h in split.maxima]
        self.n_t, self.sizes = t.numel(), sizes
        g = [g_epi, ctx.distances if len(self.obstacles) else ca.SX(0, 1)]
        if self.grid is None:
            R, pos = ctx.frames[-1]
            D = ca.mtimes(T[:3, :3], ca.vertcat(*[ca.horzcat(*R[i]) for i in range(3)]).T)  # R* Rᵀ
            g.append(ca.vertcat(T[:3, 3] - ca.vertcat(*pos), rotation_error(D)))
        return ca.Function(f"plan_point_{robot.name or 'robot'}_{b}", [cols, z, t, p, q_ref, prm],
                           [q, cost, ca.vertcat(*g)])  # fmt: skip

    def _runs(self) -> list[tuple[int, int]]:
        """(start, stop) of the runs of equal rows."""
        cut = np.flatnonzero(np.diff(self.rows)) + 1
        edges = [0, *cut.tolist(), len(self.rows)]
        return list(zip(edges[:-1], edges[1:]))

    def _bounds(self, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.grid is not None:
            return interval_bounds(self.grid, self.rows, z0[0])
        return np.tile(self.robot.q_min[:, None], len(self.rows)), np.tile(self.robot.q_max[:, None], len(self.rows))

    def solve(self, z0: np.ndarray) -> Refined:
        """IPOPT from ``z0``: the parameters (N,) (rad; unwrapped here) or the joints (N, n) (rad)."""
        t_start = time.perf_counter()
        tr, N, n, w = self.tr, len(self.rows), self.n, self.width
        z0 = np.unwrap(np.asarray(z0, float))[None] if self.grid is not None else np.asarray(z0, float).T
        lo, hi = self._bounds(z0)
        inward = INSIDE if self.grid is not None else 0.0
        lo, hi = np.atleast_2d(lo) + inward, np.atleast_2d(hi) - inward
        z = ca.MX.sym("z", w, N)
        t = ca.MX.sym("t", self.n_t, N)
        cols = np.ascontiguousarray(np.swapaxes(self.poses, 1, 2)).reshape(N, 16).T  # (16, N) column-major poses
        Qs, costs, gs = [], [], []
        for a, b in self._runs():
            mapped = self._points[int(self.rows[a])].map(b - a, "serial")
            q, c, g = mapped(ca.DM(cols[:, a:b]), z[:, a:b], t[:, a:b], self.p_obj, self.q_ref, self.obstacles.params)
            Qs.append(q), costs.append(c), gs.append(g)
        Q, cost_pt, G_pt = ca.horzcat(*Qs), ca.horzcat(*costs), ca.horzcat(*gs)
        D = Q[:, 1:] - Q[:, :-1]  # (n, N-1)
        cont = self.continuous.astype(float)
        f = ca.sum2(ca.sum1(D * D) * ca.DM(tr.motion * cont).T) + ca.sum2(cost_pt * ca.DM(tr.point).T)
        n_epi, n_d = sum(self.sizes), len(self.robot.capsules) * len(self.obstacles)
        n_eq = 0 if self.grid is not None else 6
        point_lo = np.r_[np.full(n_epi, -np.inf), np.full(n_d, self.d_safe + INSIDE), np.zeros(n_eq)]
        point_hi = np.r_[np.zeros(n_epi), np.full(n_d, np.inf), np.zeros(n_eq)]
        step = np.where(self.continuous[:, None], tr.step, np.inf)  # (N-1, n)
        g_parts, lbg, ubg = [ca.vec(G_pt), ca.vec(D)], [np.tile(point_lo, N), -step.ravel()], [np.tile(point_hi, N), step.ravel()]
        if tr.a_max is not None and N > 2:
            V = D / ca.DM(tr.dt).T
            both = self.continuous[1:] & self.continuous[:-1]
            bound = np.where(both[:, None], np.outer(0.5 * (tr.dt[1:] + tr.dt[:-1]), tr.a_max), np.inf)
            g_parts.append(ca.vec(V[:, 1:] - V[:, :-1])), lbg.append(-bound.ravel()), ubg.append(bound.ravel())
        x = ca.vertcat(ca.vec(z), ca.vec(t))
        solver = ca.nlpsol("plan_nlp", "ipopt", {"x": x, "f": f, "g": ca.vertcat(*g_parts)}, OPTIONS)
        value = ca.Function("value", [z, t], [f, G_pt[:n_epi, :], Q.T])
        t0 = self._least_t(value, z0, N)
        x0 = np.concatenate([z0.T.ravel(), t0.T.ravel()])
        lbx = np.concatenate([lo.T.ravel(), np.full(self.n_t * N, -np.inf)])
        ubx = np.concatenate([hi.T.ravel(), np.full(self.n_t * N, np.inf)])
        start_cost = float(value(z0, t0)[0])
        sol = solver(x0=np.clip(x0, lbx, ubx), lbx=lbx, ubx=ubx, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
        stats = solver.stats()
        zs = np.clip(np.asarray(sol["x"]).ravel()[: w * N].reshape(N, w).T, lo, hi)
        ts = self._least_t(value, zs, N)  # the epigraph variables at their least: the objective's true value
        cost, _, q = value(zs, ts)
        return Refined(zs[0] if self.grid is not None else np.zeros(0), np.asarray(q), float(cost), start_cost,
                       str(stats.get("return_status", "")), int(stats.get("iter_count", 0)),
                       time.perf_counter() - t_start)  # fmt: skip

    def _least_t(self, value: ca.Function, z: np.ndarray, N: int) -> np.ndarray:
        """(n_t, N): each epigraph variable at the largest of its pieces (where the objective's true value is)."""
        if not self.n_t:
            return np.zeros((0, N))
        h = np.asarray(value(z, np.zeros((self.n_t, N)))[1])  # pieces h - t at t = 0: the pieces themselves
        out, start = [], 0
        for size in self.sizes:
            out.append(h[start : start + size].max(axis=0))
            start += size
        return np.array(out)
