r"""The DP's states: a grid of the redundancy parameter on every branch at every waypoint.

For a closed-form arm (offset shoulder: δ, S-R-S: ψ) the configurations that reach waypoint k
form, per branch b, the curve :math:`q_b(T_k, \psi)`. The grid samples it at G values

.. math:: \psi_i = -\pi + (i + \tfrac12)\,\frac{2\pi}{G},\qquad i = 0, \dots, G - 1,

the same values on every branch and at every waypoint (so that a slowly changing parameter
stays on nearby indices). A state (k, b, i) is *feasible* when ψ_i lies in branch b's exact
feasible set at waypoint k (:func:`qpik.feasible_intervals`: every joint inside its limits, the
branch reaches the pose) and every link capsule is at least ``d_safe`` from every obstacle.
Parameter values outside the exact feasible set are never evaluated.

Offset-shoulder arms have 16 branches, but branch k + 8 at δ is branch k at δ + π (Nammoto &
Kosuge 2012, eq. 7), so only the first 8 are gridded (over the whole circle); with G even the
grid maps onto itself under δ → δ + π. :meth:`Grid.branch_of` gives the public branch id of
a state.

Per feasible state the compiled row function (:func:`qpik.compiled.RowMap`, one row = a
waypoint and a parameter value, every branch at once) gives q (n,), the point objective
f(q) (:mod:`qpik.objectives`) and the smallest capsule–obstacle distance (m).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from qpik import symbolic as sy
from qpik.analytic import feasible_intervals, solver_for
from qpik.analytic.intervals import FeasibleIntervals, wrap
from qpik.compiled import RowMap
from qpik.geometry.distance import ObstacleSet
from qpik.nlp.selfmotion import MIRRORED
from qpik.objectives import Context, Objective
from qpik.robots.robot import Robot

ROW_CHUNKS = (64, 16)
"""Rows (waypoint, parameter value) per call of the compiled state function."""


@dataclass
class Layers:
    """The states of waypoints k0 .. k0 + K - 1 (:meth:`Grid.layers`).

    Attributes:
        q: (K, B, G, n) configurations, rad (zeros where not feasible).
        ok: (K, B, G) feasible.
        f: (K, B, G) the point objective (0 without one; inf where not feasible).
        clearance: (K, B, G) smallest capsule–obstacle distance, m (inf without obstacles).
    """

    q: np.ndarray
    ok: np.ndarray
    f: np.ndarray
    clearance: np.ndarray


class Grid:
    """The parameter grid of a closed-form arm along N poses (see the module docstring).

    Args:
        robot: an arm with a closed form.
        poses: (N, 4, 4) end-effector poses, base frame (checked by the caller).
        objective: the point objective, or None.
        obstacles: the obstacles (packed).
        d_safe: smallest capsule–obstacle distance of a feasible state, m.
        resolution: G, the number of parameter values (≥ 4, even).
        q_ref: (n,) reference configuration of the objective, rad.

    Attributes:
        values: (G,) the parameter values ψ_i, rad.
        rows: B, the branches gridded (the closed form's first B output rows).
        intervals: per waypoint, its :class:`FeasibleIntervals`.
        inside: (N, B, G) the grid values inside each branch's exact feasible set.
    """

    def __init__(
        self,
        robot: Robot,
        poses: np.ndarray,
        objective: Objective | None,
        obstacles: ObstacleSet,
        d_safe: float,
        resolution: int,
        q_ref: np.ndarray,
    ):
        self.robot, self.poses, self.objective = robot, poses, objective
        self.obstacles, self.d_safe, self.q_ref = obstacles, float(d_safe), q_ref
        self.solver = solver_for(robot)
        self.G = int(resolution)
        self.values = -np.pi + (np.arange(self.G) + 0.5) * (2.0 * np.pi / self.G)
        self.rows = MIRRORED.get(self.solver.kind, self.solver.n_branches)
        self.mirrored = self.rows < self.solver.n_branches
        self.intervals: list[FeasibleIntervals] = [feasible_intervals(robot, T) for T in poses]
        self.inside = self._inside()

    def _inside(self) -> np.ndarray:
        """(N, B, G): the grid values inside each branch's exact feasible set at each waypoint."""
        N, B, G = len(self.intervals), self.rows, self.G
        cells = [(k * B + b, lo, hi) for k, fi in enumerate(self.intervals) for b in range(B)
                 for lo, hi in fi.intervals[b]]  # fmt: skip
        count = np.zeros(N * B * (G + 1), np.int64)
        if cells:
            row, lo, hi = (np.array(x) for x in zip(*cells))
            start = row * (G + 1) + np.searchsorted(self.values, lo, "left")
            stop = row * (G + 1) + np.searchsorted(self.values, hi, "right")
            count += np.bincount(start, minlength=count.size) - np.bincount(stop, minlength=count.size)
        return (np.cumsum(count.reshape(N * B, G + 1)[:, :G], axis=1) > 0).reshape(N, B, G)

    @property
    def spacing(self) -> float:
        """The grid step, 2π/G (rad)."""
        return 2.0 * np.pi / self.G

    @property
    def param_name(self) -> str:
        return self.solver.param_name

    def branch_of(self, row: np.ndarray | int) -> np.ndarray | int:
        """Public branch id(s) of grid row(s)."""
        ids = np.asarray(self.solver.branch_ids)
        out = ids[np.asarray(row, int)]
        return int(out) if np.ndim(out) == 0 else out

    def public(self, rows: np.ndarray, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Public branch ids and parameters (rad, wrapped) of rows (N,) at parameters (N,), as
        :func:`qpik.redundancy_parameter` gives them: a mirrored arm's row b at |δ| > π/2 is branch
        b + 8 at δ ∓ π."""
        rows, params = np.asarray(rows, int), wrap(np.asarray(params, float))
        if not self.mirrored:
            return self.branch_of(rows), params
        far = np.abs(params) > 0.5 * np.pi
        return self.branch_of(np.where(far, rows + self.rows, rows)), np.where(far, wrap(params + np.pi), params)

    def row_of(self, branch: int, param: float) -> tuple[int, float]:
        """The grid row and parameter (rad) of public branch ``branch`` at ``param``: a mirrored branch is its
        row at the parameter − π."""
        k = list(self.solver.branch_ids).index(int(branch))
        if k < self.rows:
            return k, float(param)
        return k - self.rows, float(wrap(param + np.pi))

    @cached_property
    def _rows(self) -> RowMap:
        return RowMap(self.function(), shared=(2, 3, 4), chunks=ROW_CHUNKS)

    def function(self) -> ca.Function:
        """``(T (4x4), ψ, objective params, q_ref (n), obstacle params) -> (B·(n + 3),)``: per gridded branch,
        ``[q (n), valid and within the limits, f(q), smallest clearance (m)]``.

        Branches whose link capsules always coincide (:meth:`twins`) share one distance computation."""
        robot, n = self.robot, self.robot.dof
        T, psi = ca.SX.sym("T", 4, 4), ca.SX.sym(self.param_name)
        p = ca.SX.sym("p", self.objective_params.size)
        q_ref = ca.SX.sym("q_ref", n)
        prm = ca.SX.sym("obstacles", self.obstacles.params.size)
        Q, valid, _ = self.solver.casadi_function(T, psi)
        contexts = [Context(robot, Q[b, :].T, q_ref, self.obstacles, prm) for b in range(self.rows)]
        twin = self.twins() if len(self.obstacles) else list(range(self.rows))
        out = []
        for b, ctx in enumerate(contexts):
            ok = valid[b]
            for j in range(n):
                ok = ok * (ctx.q[j] >= robot.q_min[j]) * (ctx.q[j] <= robot.q_max[j])
            f = self.objective.expr(ctx, p) if self.objective is not None else ca.SX(0.0)
            d = ca.mmin(contexts[twin[b]].distances) if len(self.obstacles) else ca.SX(np.inf)
            out.append(ca.vertcat(ctx.q, ok, f, d))
        name = f"plan_states_{self.solver.kind}_{robot.name or 'robot'}"
        return ca.Function(name, [T, psi, p, q_ref, prm], [ca.densify(ca.vertcat(*out))])

    def twins(self, samples: int = 16) -> list[int]:
        """For each gridded branch, the first branch whose link capsules are at the same place for every pose
        and parameter (itself if none): found by evaluating the capsule segments of every branch at
        ``samples`` random poses (FK of random configurations, seeded) and parameters, equal to 1e-9 m at all.

        Branches that differ only by a joint turned by π about a capsule's own axis (the S-R-S shoulder
        (θ1 + π, −θ2, θ3 + π) and wrist (θ5 + π, −θ6, θ7 + π) pairs, with capsules on the joint axes) are twins."""
        robot = self.robot
        T, psi = ca.SX.sym("T", 4, 4), ca.SX.sym("psi")
        Q, valid, _ = self.solver.casadi_function(T, psi)
        segs = []
        for b in range(self.rows):
            frames = robot.chain.frames_expr([Q[b, j] for j in range(robot.dof)], sy.CASADI)
            segs.append(ca.vertcat(*[x for ab in robot.capsule_segments_expr(frames) for p_ in ab for x in p_]))
        probe = ca.Function("capsule_probe", [T, psi], [ca.horzcat(*segs), valid])
        rng = np.random.default_rng(0)
        X, ok = [], []
        for _ in range(samples):
            S, v = probe(robot.fk(rng.uniform(robot.q_min, robot.q_max)), rng.uniform(-np.pi, np.pi))
            X.append(np.asarray(S)), ok.append(np.asarray(v).ravel()[: self.rows] > 0.5)
        X, ok = np.array(X), np.array(ok)  # (samples, 6C, B), (samples, B)
        twin = list(range(self.rows))
        for b in range(self.rows):
            for a in range(b):
                both = ok[:, a] & ok[:, b]
                if both.sum() >= samples // 2 and np.abs(X[both, :, a] - X[both, :, b]).max() < 1e-9 and twin[a] == a:
                    twin[b] = a
                    break
        return twin

    @cached_property
    def objective_params(self) -> np.ndarray:
        return np.zeros(0) if self.objective is None else self.objective.params(self.robot)

    def configurations(self, ks: np.ndarray, rows: np.ndarray, index: np.ndarray) -> np.ndarray:
        """(M, n) the configurations of the states (waypoint ks, grid row, grid index) (M,) each."""
        n = self.robot.dof
        cols = np.ascontiguousarray(np.swapaxes(self.poses[ks], 1, 2)).reshape(len(ks), 16)
        (out,) = self._rows(cols, self.values[index], self.objective_params, self.q_ref, self.obstacles.params)
        return out.reshape(len(ks), self.rows, n + 3)[np.arange(len(ks)), rows, :n]

    def layers(self, k0: int, k1: int) -> Layers:
        """The states of waypoints k0 .. k1 - 1 (see :class:`Layers`); every grid value is evaluated (all but a
        few are inside some branch's feasible set) and only those inside count."""
        K, B, G, n = k1 - k0, self.rows, self.G, self.robot.dof
        cols = np.ascontiguousarray(np.swapaxes(self.poses[k0:k1], 1, 2)).reshape(K, 16)
        (out,) = self._rows(np.repeat(cols, G, axis=0), np.tile(self.values, K), self.objective_params, self.q_ref,
                            self.obstacles.params)  # fmt: skip
        out = out.reshape(K, G, B, n + 3).transpose(0, 2, 1, 3)
        q = np.ascontiguousarray(out[..., :n])
        clear = out[..., n + 2].copy()
        ok = (out[..., n] > 0.5) & self.inside[k0:k1] & (clear >= self.d_safe) & np.isfinite(out[..., n + 1])
        return Layers(q, ok, np.where(ok, out[..., n + 1], np.inf), clear)
