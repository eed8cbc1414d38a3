r"""The path NLP's formulation: :class:`PathModel` builds it as a :class:`PathProblem` (CasADi MX) for IPOPT.

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
(:func:`qpik.algebra.lie.log_expr`), the same objective and constraints.

Sparse by construction: the per-waypoint closed form (or pose error), objective and distances are
one CasADi ``Function`` mapped over the waypoints of each run of one branch row (``Function.map``),
so the constraint Jacobian and the Lagrangian's Hessian are block-banded (a waypoint couples only
with its neighbours).

The Lagrangian's Hessian of a closed-form arm is assembled rather than differentiated through the
graph (:meth:`PathModel._hessian`). With multipliers σ (objective), λ (epigraph pieces and distances of
waypoint k) and ν_k (n) on :math:`D_k = q_{k+1} - q_k` (the step bounds plus the acceleration rows
:math:`D_{k+1}/\Delta t_{k+1} - D_k/\Delta t_k` folded onto the D they hold), and
:math:`\eta_k = \nu_k + 2\sigma m_k D_k` (:math:`m_k` the motion weight of transition k),
it is tridiagonal in ψ:

.. math::

    H_{kk} = (\eta_{k-1} - \eta_k)^T q_k'' + 2\sigma (m_{k-1} + m_k) \lVert q_k' \rVert^2
             + \partial^2_{\psi_k}\big(\sigma w_k s + \lambda_k^T [h; d]\big),\qquad
    H_{k,k+1} = -2\sigma m_k\, q_k'^T q_{k+1}'

(the epigraph variables enter linearly: no second derivatives), with :math:`q_k', q_k''` and the last
term from one compiled function per waypoint (:meth:`PathModel._curvature`; machine code for paths of
at least :data:`NATIVE_WAYPOINTS` waypoints, where compiling it once pays). The objective's gradient
and the constraints' Jacobian are assembled from the same function's values and first derivatives
(:meth:`PathModel._derivatives`); CasADi differentiates the graph only for arms without a closed form.

"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.algebra.lie import log_expr
from qpik.geometry.contacts import capsule_pairs
from qpik.native.build import native
from qpik.objectives import Context, pair_count
from qpik.planning.dp import Transitions
from qpik.planning.grid import Grid
from qpik.scene.scene import Scene

NATIVE_WAYPOINTS = 200
"""Waypoints from which the per-waypoint curvature function runs as machine code (:func:`qpik.native.build.native`,
compiled once per arm, branch row and objective, cached on disk); shorter paths use CasADi's virtual machine."""
INSIDE = 1e-8
"""rad and m: the NLP keeps ψ this far inside its feasible interval (whose ends are exact to 1e-9 rad) and the
clearance this far above d_s, so that its answer, feasible to IPOPT's tolerance, meets every check exactly."""


@dataclass
class PathProblem:
    """One NLP of :class:`PathModel`: ``min f(x) s.t. lbg ≤ g(x) ≤ ubg`` over x = [vec(z); vec(t)] (CasADi MX).

    Attributes:
        z: (w, N) the variables per waypoint (ψ_k, or q_k without a closed form); t: (n_t, N) epigraph variables.
        x, f, g: the variables, objective and constraints; lbg, ubg: the constraints' bounds.
        hess_lag: IPOPT's ``(x, p, σ, λ) -> triu(∇²(σ f + λᵀ g))`` assembled by :meth:`PathModel._hessian`
            (closed-form arms), or None (CasADi differentiates the graph).
        grad_f, jac_g: ``(x, p) -> (f, ∇f)`` and ``(x, p) -> (g, ∂g/∂x)`` assembled likewise, or None.
    """

    z: ca.MX
    t: ca.MX
    x: ca.MX
    f: ca.MX
    g: ca.MX
    lbg: np.ndarray
    ubg: np.ndarray
    hess_lag: ca.Function | None = None
    grad_f: ca.Function | None = None
    jac_g: ca.Function | None = None


class PathModel:
    """The NLP of the module docstring for one path: its data and its CasADi functions; :meth:`problem` builds it
    with the clearance constraints of some waypoints, :meth:`value` evaluates the objective.

    Args:
        scene: the arm, the point objective (or None), the obstacles, d_safe (m), the objective's reference
            configuration q_ref (n,), rad (zeros without one: then no term reads it) and the capsule pairs kept
            apart (:attr:`~qpik.scene.Scene.self_pairs`).
        poses: (N, 4, 4) waypoints, base frame.
        tr: the transition bounds and weights.
        continuous: (N-1,) whether transition k is continuous (not a reconfiguration).
        grid: for a closed-form arm, the DP's grid (solver, feasible intervals) and ``rows`` (N,) its
            branch rows; None: the joints are the variables.
    """

    def __init__(
        self,
        scene: Scene,
        poses: np.ndarray,
        tr: Transitions,
        continuous: np.ndarray,
        grid: Grid | None = None,
        rows: np.ndarray | None = None,
    ):
        self.robot = robot = scene.robot
        self.poses, self.objective, self.obstacles = poses, scene.objective, scene.obstacles
        self.q_ref = np.zeros(robot.dof) if scene.q_ref is None else scene.q_ref
        self.d_safe, self.tr, self.grid, self.scene = scene.d_safe, tr, grid, scene
        self.continuous = np.asarray(continuous, bool)
        N, n = len(poses), robot.dof
        self.rows = np.zeros(N, int) if rows is None else np.asarray(rows, int)
        self.p_obj = np.zeros(0) if self.objective is None else self.objective.params(robot)
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
        g = [clearances (≥ d_s: capsule–obstacle, then capsule pairs) if ``near``; pose error (= 0, joints only)]."""
        key = (b, near)
        if key in self._points:
            return self._points[key]
        robot, n = self.robot, self.n
        cols, z = ca.SX.sym("T", 16), ca.SX.sym("z", self.width)
        T = ca.reshape(cols, 4, 4)  # the pose's entries in CasADi's column-major order
        p, q_ref = ca.SX.sym("p", self.p_obj.size), ca.SX.sym("q_ref", n)
        prm = ca.SX.sym("obstacles", self.obstacles.params.size)
        q = self.grid.solver.casadi_function(T, z)[0][b, :].T if self.grid is not None else z
        ctx = Context(robot, q, q_ref, self.obstacles, prm, self_pairs=self.scene.self_pairs)
        if self.objective is None:
            t, cost, g_epi = ca.SX.sym("t", 0), ca.SX(0.0), ca.SX(0, 1)
        else:
            t, cost, g_epi = self.objective.split(ctx, p).epigraph()
        g = [ctx.clearances if near else ca.SX(0, 1)]
        if self.grid is None:
            R, pos = ctx.frames[-1]
            D = ca.mtimes(T[:3, :3], ca.vertcat(*[ca.horzcat(*R[i]) for i in range(3)]).T)  # R* Rᵀ
            g.append(ca.vertcat(T[:3, 3] - ca.vertcat(*pos), log_expr(D)))
        name = f"plan_point_{robot.identifier}_{b}" + ("_near" if near else "")
        self._points[key] = ca.Function(name, [cols, z, t, p, q_ref, prm], [q, cost, g_epi, ca.vertcat(*g)])
        return self._points[key]

    def _curvature(self, b: int, near: bool) -> ca.Function:
        """``(T, ψ, t, p, q_ref, obstacle params, a, λ_E, λ_d) -> (q, q', q'', ∂²/∂ψ² (a·cost + λ_Eᵀ E + λ_dᵀ d),
        ∂[cost; E; d]/∂ψ, ∂cost/∂t, [cost; E; d])`` of one waypoint on row b of a closed-form arm (λ_d: the distances'
        multipliers if ``near``, else empty); machine code for long paths (:data:`NATIVE_WAYPOINTS`)."""
        key = (b, near, "curvature")
        if key in self._points:
            return self._points[key]
        point = self._point(b, near)
        args = [ca.SX.sym(point.name_in(i), point.sparsity_in(i)) for i in range(point.n_in())]
        q, cost, epi, g = point(*args)
        z, t = args[1], args[2]
        a, lam_e, lam_d = ca.SX.sym("a"), ca.SX.sym("lam_e", epi.numel()), ca.SX.sym("lam_d", g.numel())
        qp = ca.jacobian(q, z)
        lag = a * cost + ca.dot(lam_e, epi) + ca.dot(lam_d, g)
        fn = ca.Function(f"{point.name()}_curvature", [*args, a, lam_e, lam_d],
                         [q, qp, ca.jacobian(qp, z), ca.hessian(lag, z)[0], ca.jacobian(ca.vertcat(cost, epi, g), z),
                          ca.jacobian(cost, t).T, ca.vertcat(cost, epi, g)])  # fmt: skip
        self._points[key] = native(fn) if len(self.rows) >= NATIVE_WAYPOINTS else fn
        return self._points[key]

    def _hessian(self, z: ca.MX, t: ca.MX, near: np.ndarray, sizes: list[int]) -> ca.Function:
        """IPOPT's ``hess_lag`` of a closed-form arm (the module docstring): ``(x, p, σ, λ) -> triu(H)``, with the
        constraints in :meth:`_solve`'s order (epigraph pieces, per run [distances], D, acceleration rows)
        of ``sizes`` entries each."""
        tr, N, n = self.tr, len(self.rows), self.n
        sigma, lam = ca.MX.sym("sigma"), ca.MX.sym("lam", sum(sizes))
        parts = ca.vertsplit(lam, list(np.cumsum([0, *sizes])))
        Q, Qp, Qpp, Hp, _, _, _ = self._pieces(z, t, near, sigma, parts)
        m = ca.DM(self.tr.motion * self.continuous).T  # (1, N-1)
        nu = ca.reshape(parts[len(sizes) - (2 if self._accelerations else 1)], n, N - 1)
        if self._accelerations:
            lam_a = ca.reshape(parts[-1], n, N - 2)
            inv_dt = ca.repmat(ca.DM(1.0 / tr.dt).T, n, 1)
            zero = ca.MX(n, 1)
            nu = nu + ca.horzcat(zero, lam_a * inv_dt[:, 1:]) - ca.horzcat(lam_a * inv_dt[:, :-1], zero)
        eta = nu + 2 * sigma * (Q[:, 1:] - Q[:, :-1]) * ca.repmat(m, n, 1)
        c = ca.horzcat(ca.MX(n, 1), eta) - ca.horzcat(eta, ca.MX(n, 1))  # (n, N): η_{k-1} - η_k
        around = ca.horzcat(0, m) + ca.horzcat(m, 0)
        diag = Hp + ca.sum1(c * Qpp) + 2 * sigma * around * ca.sum1(Qp * Qp)
        off = -2 * sigma * m * ca.sum1(Qp[:, :-1] * Qp[:, 1:])
        above = np.arange(N - 1).tolist()
        shift = ca.DM(ca.Sparsity.triplet(N, N, above, [k + 1 for k in above]), 1.0)  # ones on the superdiagonal
        H = ca.diag(diag.T) + ca.mtimes(ca.diag(ca.horzcat(off, 0).T), shift)
        x = ca.vertcat(ca.vec(z), ca.vec(t))
        full = ca.diagcat(H, ca.MX(self.n_t * N, self.n_t * N))
        return ca.Function("plan_hess_lag", [x, ca.MX.sym("p", 0), sigma, lam], [full])

    def _pieces(self, z: ca.MX, t: ca.MX, near: np.ndarray, sigma: ca.MX, parts: list[ca.MX]):
        """:meth:`_curvature` over the runs: Q, Q', Q'' (n, N), the second derivatives (1, N) at the multipliers
        σ and ``parts`` (:meth:`_hessian`), the first derivatives ∂[cost; E; d]/∂ψ of each run, ∂cost/∂t (n_t, N)
        and the values [cost; E; d] of each run."""
        N = len(self.rows)
        lam_e = ca.reshape(parts[0], -1, N)
        cols = np.ascontiguousarray(np.swapaxes(self.poses, 1, 2)).reshape(N, 16).T
        weight = ca.DM(self.tr.point).T
        Q, Qp, Qpp, Hp, grads, cost_t, values = [], [], [], [], [], [], []
        for i, (a, b) in enumerate(self._runs(near)):
            lam_d = ca.reshape(parts[1 + i], -1, b - a) if near[a] else ca.MX(0, b - a)
            mapped = self._curvature(int(self.rows[a]), bool(near[a])).map(b - a, "serial")
            out = mapped(ca.DM(cols[:, a:b]), z[:, a:b], t[:, a:b], self.p_obj, self.q_ref, self.obstacles.params,
                         sigma * weight[:, a:b], lam_e[:, a:b], lam_d)  # fmt: skip
            for acc, x in zip((Q, Qp, Qpp, Hp, grads, cost_t, values), out):
                acc.append(x)
        return (*(ca.horzcat(*x) for x in (Q, Qp, Qpp, Hp)), grads, ca.horzcat(*cost_t), values)

    def _derivatives(self, nlp: PathProblem, near: np.ndarray, sizes: list[int]) -> tuple[ca.Function, ca.Function]:
        """IPOPT's ``grad_f`` ``(x, p) -> (f, ∇f)`` and ``jac_g`` ``(x, p) -> (g, ∂g/∂x)`` of a closed-form arm,
        assembled from :meth:`_curvature`'s first derivatives: q_k depends on ψ_k alone, so the rows of waypoint
        k's pieces and distances hold ψ_k, D_k holds ψ_k and ψ_{k+1}, an acceleration row three neighbours."""
        tr, N, n, n_t = self.tr, len(self.rows), self.n, self.n_t
        z, t = nlp.z, nlp.t
        zeros = [ca.MX(size, 1) for size in sizes]
        Q, Qp, _, _, grads, cost_t, values = self._pieces(z, t, near, ca.MX(0.0), zeros)
        n_e = sizes[0] // N
        weight = ca.DM(tr.point).T
        m = ca.DM(tr.motion * self.continuous).T
        eta = 2 * (Q[:, 1:] - Q[:, :-1]) * ca.repmat(m, n, 1)
        c = ca.horzcat(ca.MX(n, 1), eta) - ca.horzcat(eta, ca.MX(n, 1))
        dcost = ca.horzcat(*[g_[0, :] for g_ in grads])
        grad = ca.vertcat(ca.vec(ca.sum1(c * Qp) + weight * dcost), ca.vec(cost_t * ca.repmat(weight, n_t, 1)))
        f = self._cost(Q, ca.horzcat(*[v[0, :] for v in values]))
        D = Q[:, 1:] - Q[:, :-1]
        g = [ca.vec(ca.horzcat(*[v[1 : 1 + n_e, :] for v in values]))]
        g += [ca.vec(v[1 + n_e :, :]) for v, (a, _) in zip(values, self._runs(near)) if near[a]]
        g.append(ca.vec(D))
        if self._accelerations:
            V = D / ca.repmat(ca.DM(tr.dt).T, n, 1)
            g.append(ca.vec(V[:, 1:] - V[:, :-1]))

        def spread(values: ca.MX, cols: np.ndarray) -> ca.MX:
            """(R, N): row r holds values[r] in column cols[r]."""
            R = values.numel()
            return ca.mtimes(ca.diag(values), ca.DM(ca.Sparsity.triplet(R, N, list(range(R)), cols.tolist()), 1.0))

        k = np.arange(N)
        blocks = []
        dE = ca.horzcat(*[g_[1 : 1 + n_e, :] for g_ in grads])
        owner = np.repeat(np.arange(len(self.sizes)), self.sizes)  # the maximum of each piece
        rows_t = np.arange(N * n_e)
        cols_t = (rows_t // max(n_e, 1)) * n_t + owner[rows_t % max(n_e, 1)] if n_e else rows_t
        Jt = ca.DM(ca.Sparsity.triplet(N * n_e, N * n_t, rows_t.tolist(), cols_t.tolist()), -1.0)
        blocks.append(ca.horzcat(spread(ca.vec(dE), np.repeat(k, n_e)), Jt))
        for g_, (a, b) in zip(grads, self._runs(near)):
            if near[a]:
                d = g_[1 + n_e :, :]
                blocks.append(ca.horzcat(spread(ca.vec(d), np.repeat(k[a:b], d.size1())),
                                         ca.MX(d.numel(), N * n_t)))  # fmt: skip
        step = np.repeat(k[:-1], n)
        J_D = spread(ca.vec(Qp[:, 1:]), step + 1) - spread(ca.vec(Qp[:, :-1]), step)
        blocks.append(ca.horzcat(J_D, ca.MX(n * (N - 1), N * n_t)))
        if self._accelerations:
            inv = ca.repmat(ca.DM(1.0 / tr.dt).T, n, 1)  # (n, N-1)
            step = np.repeat(k[:-2], n)
            J_A = (spread(ca.vec(Qp[:, 2:] * inv[:, 1:]), step + 2) + spread(ca.vec(Qp[:, :-2] * inv[:, :-1]), step)
                   - spread(ca.vec(Qp[:, 1:-1] * (inv[:, 1:] + inv[:, :-1])), step + 1))  # fmt: skip
            blocks.append(ca.horzcat(J_A, ca.MX(n * (N - 2), N * n_t)))
        p = ca.MX.sym("p", 0)
        return (ca.Function("plan_grad_f", [nlp.x, p], [f, grad]),
                ca.Function("plan_jac_g", [nlp.x, p], [ca.vertcat(*g), ca.vertcat(*blocks)]))  # fmt: skip

    @property
    def _accelerations(self) -> bool:
        """Whether the NLP has the acceleration rows (times and ``a_max``, at least three waypoints)."""
        return self.tr.a_max is not None and len(self.rows) > 2

    def _runs(self, near: np.ndarray) -> list[tuple[int, int]]:
        """(start, stop) of the runs of equal rows and equal ``near``."""
        cut = np.flatnonzero((np.diff(self.rows) != 0) | (np.diff(near.astype(int)) != 0)) + 1
        edges = [0, *cut.tolist(), len(self.rows)]
        return list(itertools.pairwise(edges))

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

    def value(self) -> ca.Function:
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

    def problem(self, near: np.ndarray) -> PathProblem:
        """The NLP with the clearance constraints of the waypoints ``near`` (N,) (see :class:`PathProblem`)."""
        tr = self.tr
        z, t, Q, cost_pt, E, others = self._graph(near)
        D = Q[:, 1:] - Q[:, :-1]  # (n, N-1)
        f = self._cost(Q, cost_pt)
        n_d = pair_count(self.robot, self.obstacles) + len(self.scene.self_pairs)
        n_eq = 0 if self.grid is not None else 6
        g_parts, lbg, ubg = [ca.vec(E)], [np.full(E.numel(), -np.inf)], [np.zeros(E.numel())]
        # the pairs qpik.geometry.contacts leaves out (a base column on its table) constrain nothing
        floor = np.where(capsule_pairs(self.robot, self.obstacles)[~self.robot.fixed_capsules].ravel(),
                         self.d_safe + INSIDE, -np.inf)  # fmt: skip
        floor = np.r_[floor, np.full(len(self.scene.self_pairs), self.d_safe + INSIDE)]
        for a, b, g in others:
            d = n_d if near[a] else 0
            g_parts.append(ca.vec(g))
            lbg.append(np.tile(np.r_[floor[:d], np.zeros(n_eq)], b - a))
            ubg.append(np.tile(np.r_[np.full(d, np.inf), np.zeros(n_eq)], b - a))
        step = np.where(self.continuous[:, None], tr.step, np.inf)  # (N-1, n)
        g_parts.append(ca.vec(D)), lbg.append(-step.ravel()), ubg.append(step.ravel())
        if self._accelerations:
            V = D / ca.repmat(ca.DM(tr.dt).T, self.n, 1)
            both = self.continuous[1:] & self.continuous[:-1]
            bound = np.where(both[:, None], np.outer(0.5 * (tr.dt[1:] + tr.dt[:-1]), tr.a_max), np.inf)
            g_parts.append(ca.vec(V[:, 1:] - V[:, :-1])), lbg.append(-bound.ravel()), ubg.append(bound.ravel())
        nlp = PathProblem(z, t, ca.vertcat(ca.vec(z), ca.vec(t)), f, ca.vertcat(*g_parts), np.concatenate(lbg),
                      np.concatenate(ubg))  # fmt: skip
        if self.grid is not None:
            sizes = [part.numel() for part in g_parts]
            nlp.hess_lag = self._hessian(z, t, near, sizes)
            nlp.grad_f, nlp.jac_g = self._derivatives(nlp, near, sizes)
        return nlp
