r"""The DP's states: a grid of the redundancy parameter on every branch at every waypoint.

For a closed-form arm (offset shoulder: δ, S-R-S: ψ) the configurations that reach waypoint k
form, per branch b, the curve :math:`q_b(T_k, \psi)`. The grid samples it at G values

.. math:: \psi_i = -\pi + (i + \tfrac12)\,\frac{2\pi}{G},\qquad i = 0, \dots, G - 1,

the same values on every branch and at every waypoint (so that a slowly changing parameter
stays on nearby indices). A state (k, b, i) is *feasible* when ψ_i lies in branch b's exact
feasible set at waypoint k (:func:`qpik.feasible_intervals`: every joint inside its limits, the
branch reaches the pose), every link capsule is at least ``d_safe`` from every obstacle and the capsules of every
pair of the scene's :attr:`~qpik.scene.Scene.self_pairs` are at least ``d_safe`` apart.
Parameter values outside the exact feasible set are never evaluated.

Offset-shoulder arms have 16 branches, but branch k + 8 at δ is branch k at δ + π (Nammoto &
Kosuge 2012, eq. 7), so only the first 8 are gridded (over the whole circle); with G even the
grid maps onto itself under δ → δ + π. :meth:`Grid.branch_of` gives the public branch id of
a state.

Per feasible state the compiled row function (one row = a waypoint and a parameter value, every
branch at once) gives q (n,), the point objective f(q) (:mod:`qpik.objectives`) and the smallest
clearance (m; capsule–obstacle and capsule pairs). With a C compiler one loop in C (``grid.c``) calls its
generated C for the rows where some branch is inside its feasible set and writes the states in place; without one,
:class:`qpik.native.compiled.RowMap` evaluates every row and numpy sorts them.
"""

from __future__ import annotations

import ctypes
import itertools
from dataclasses import dataclass
from functools import cache, cached_property

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.analytic import closed_form_for, feasible_intervals
from qpik.analytic.intervals import FeasibleIntervals, wrap
from qpik.core.errors import SolverError
from qpik.core.layout import Layout
from qpik.geometry.contacts import capsule_pairs
from qpik.native.compiled import Compiled, NativeFunction, RowMap
from qpik.native.sources import load_source
from qpik.nlp.selfmotion import MIRRORED
from qpik.objectives import Context
from qpik.scene.scene import Scene

UNCHECKED = 1e6
"""m added to the distance of a pair :mod:`qpik.geometry.contacts` leaves out (no motion changes it)."""
ROW_CHUNKS = (64, 16)
"""Rows (waypoint, parameter value) per call of the compiled state function."""


@dataclass
class Layers:
    """The states of waypoints k0 .. k0 + K - 1 (:meth:`Grid.layers`).

    Attributes:
        q: (K, B, G, n) configurations, rad (meaningful where ``ok``).
        ok: (K, B, G) feasible.
        f: (K, B, G) the point objective (0 without one; inf where not feasible).
    """

    q: np.ndarray
    ok: np.ndarray
    f: np.ndarray


class Grid:
    """The parameter grid of a closed-form arm along N poses (see the module docstring).

    Args:
        scene: an arm with a closed form, the point objective (or None), the obstacles, d_safe (the smallest
            capsule–obstacle distance of a feasible state, and of the capsule pairs :attr:`~Scene.self_pairs`, m)
            and the objective's reference configuration q_ref (n,), rad (zeros without one: then no term reads it).
        poses: (N, 4, 4) end-effector poses, base frame (checked by the caller).
        resolution: G, the number of parameter values (≥ 4, even).

    Attributes:
        values: (G,) the parameter values ψ_i, rad.
        rows: B, the branches gridded (the closed form's first B output rows).
        intervals: per waypoint, its :class:`FeasibleIntervals` (None for a
            :class:`~qpik.planning.search_grid.SearchGrid`: no sets).
        inside: (N, B, G) the grid values inside each branch's exact feasible set (a ``SearchGrid``'s: the branches
            the search finds inside the joint limits).
    """

    def __init__(self, scene: Scene, poses: np.ndarray, resolution: int):
        self.robot = robot = scene.robot
        self.poses, self.objective = poses, scene.objective
        self.obstacles, self.d_safe, self.self_pairs = scene.obstacles, float(scene.d_safe), scene.self_pairs
        self.q_ref = np.zeros(robot.dof) if scene.q_ref is None else scene.q_ref
        self.solver = closed_form_for(robot)
        self.G = int(resolution)
        self.values = -np.pi + (np.arange(self.G) + 0.5) * (2.0 * np.pi / self.G)
        self.rows = MIRRORED.get(self.solver.kind, self.solver.n_branches)
        self.mirrored = self.rows < self.solver.n_branches
        self.intervals, self.inside = self._feasible()

    def _feasible(self) -> tuple[list[FeasibleIntervals] | None, np.ndarray]:
        """:attr:`intervals` and :attr:`inside`: the exact feasible sets at every waypoint and the grid values inside
        them, (N, B, G)."""
        intervals = [feasible_intervals(self.robot, T) for T in self.poses]
        N, B, G = len(intervals), self.rows, self.G
        cells = [(k * B + b, lo, hi) for k, fi in enumerate(intervals) for b in range(B)
                 for lo, hi in fi.intervals[b]]  # fmt: skip
        inside = np.zeros((N * B, G), bool)
        if cells:
            row, lo, hi = (np.array(x) for x in zip(*cells))
            start, stop = np.searchsorted(self.values, lo, "left"), np.searchsorted(self.values, hi, "right")
            for r, a, b in zip(row.tolist(), start.tolist(), stop.tolist()):
                inside[r, a:b] = True
        return intervals, inside.reshape(N, B, G)

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
        r"""Public branch ids and parameters (rad, wrapped) of rows (N,) at parameters (N,), as
        :func:`qpik.redundancy_parameter` gives them: a mirrored arm's row b at :math:`|\delta| > \pi/2` is branch
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
    def _function(self) -> ca.Function:
        return self.function()

    @cached_property
    def _compiled(self) -> Compiled:
        """The row function, one row per call (machine code when a compiler works)."""
        return Compiled(self._function)

    @cached_property
    def _rows(self) -> RowMap:
        return RowMap(self._function, shared=(2, 3, 4), chunks=ROW_CHUNKS)

    def function(self) -> ca.Function:
        """``(T (4x4), ψ, objective params, q_ref (n), obstacle input) -> (B · state size,)``: per gridded branch
        a record of :attr:`state_layout` (q (n), valid and within the limits, f(q), smallest clearance (m)).

        Only the branches that are their own twin (:meth:`twins`) compute distances; the others' clearance is
        their twin's at ψ + π or ψ, another row of the grid (:meth:`clearance_sources`), and is inf here."""
        robot, n = self.robot, self.robot.dof
        T, psi = ca.SX.sym("T", 4, 4), ca.SX.sym(self.param_name)
        p = ca.SX.sym("p", self.objective_params.size)
        q_ref = ca.SX.sym("q_ref", n)
        prm = ca.SX.sym("obstacles", self.obstacle_layout.size)
        given = self.obstacle_layout.symbols(prm)
        Q, valid, _ = self.solver.casadi_function(T, psi)
        contexts = [Context(robot, Q[b, :].T, q_ref, self.obstacles, given.params, self_pairs=self.self_pairs)
                    for b in range(self.rows)]  # fmt: skip
        unchecked = (1.0 - given.checked) * UNCHECKED  # a pair qpik.geometry.contacts leaves out counts as far away
        root, _ = self.clearance_sources
        out = []
        for b, ctx in enumerate(contexts):
            ok = valid[b]
            for j in range(n):
                ok = ok * (ctx.q[j] >= robot.q_min[j]) * (ctx.q[j] <= robot.q_max[j])
            f, clear = self.point_terms(ctx, p, unchecked)
            d = ca.mmin(clear) if clear.numel() and root[b] == b else ca.SX(np.inf)
            out.append(self.state_layout.pack(q=ctx.q, valid=ok, f=f, clearance=d))
        name = f"plan_states_{self.solver.kind}_{robot.identifier}"
        return ca.Function(name, [T, psi, p, q_ref, prm], [ca.densify(ca.vertcat(*out))])

    def point_terms(self, ctx: Context, p: ca.SX, unchecked: ca.SX) -> tuple[ca.SX, ca.SX]:
        """At a state's configuration ``ctx.q``: the point objective f (0 without one; its parameters ``p``) and the
        clearances (m), capsule–obstacle (plus ``unchecked`` for the pairs :mod:`qpik.geometry.contacts` leaves
        out) then the checked capsule pairs."""
        f = self.objective.expr(ctx, p) if self.objective is not None else ca.SX(0.0)
        return f, ca.vertcat(ctx.distances + unchecked, ctx.self_distances)

    @cached_property
    def state_layout(self) -> Layout:
        """One branch's record of :meth:`function`'s output: ``q`` (n,) rad, ``valid`` (1.0: valid and within the
        limits), ``f`` (the objective at q), ``clearance`` (m, the smallest); ``grid.c`` reads records of this
        order."""
        return Layout(q=self.robot.dof, valid=(), f=(), clearance=())

    @cached_property
    def obstacle_layout(self) -> Layout:
        """The function's obstacle input: ``params`` (the obstacles' packed parameters) and ``checked``: per pair
        of :attr:`Context.distances` (capsules a joint moves × obstacles) 1.0 if :mod:`qpik.geometry.contacts`
        checks it, else 0.0."""
        return Layout(params=self.obstacles.params.size, checked=self._checked.size)

    @cached_property
    def _checked(self) -> np.ndarray:
        return capsule_pairs(self.robot, self.obstacles)[~self.robot.fixed_capsules].ravel().astype(float)

    @cached_property
    def obstacle_input(self) -> np.ndarray:
        """The function's obstacle input (:attr:`obstacle_layout`) filled in."""
        return self.obstacle_layout.packer()({"params": self.obstacles.params, "checked": self._checked}).copy()

    @cached_property
    def clearance_sources(self) -> tuple[np.ndarray, np.ndarray]:
        """(B,) root and (B,) index shift: the clearance of state (k, b, i) is the root's at grid index
        (i + shift) mod G (:meth:`twins`; every branch its own root without obstacles)."""
        pairs = self.twins() if len(self.obstacles) or self.self_pairs else [(b, False) for b in range(self.rows)]
        root = np.array([a for a, _ in pairs], np.int64)
        return root, np.array([self.G // 2 if half else 0 for _, half in pairs], np.int64)

    def twins(self, samples: int = 16) -> list[tuple[int, bool]]:
        """For each gridded branch b, the first branch a and whether b's link capsules at ψ are a's at ψ + π
        (else at ψ) for every pose and parameter ((b, False) if none): equal capsules have equal clearances, to the
        obstacles and between themselves. Found by evaluating the capsule segments of
        every branch at ``samples`` random poses (FK of random configurations, seeded) and parameters, equal to
        1e-9 m at all. The grid maps onto itself under ψ → ψ + π (G even), so a twin's clearance is another row.

        Branches that differ only by a joint turned by π about a capsule's own axis (the S-R-S shoulder
        (θ1 + π, −θ2, θ3 + π) and wrist (θ5 + π, −θ6, θ7 + π) pairs, with capsules on the joint axes) are twins
        at ψ; the S-R-S elbow pairs (θ4 → −θ4) are twins at ψ + π (the elbow on the same circle, half a turn on)."""
        robot = self.robot
        T, psi = ca.SX.sym("T", 4, 4), ca.SX.sym("psi")
        Q, valid, _ = self.solver.casadi_function(T, psi)
        segs = []
        for b in range(self.rows):
            frames = robot.chain.frames_expr([Q[b, j] for j in range(robot.dof)], sy.CASADI)
            segs.append(ca.vertcat(*[x for ab in robot.capsule_segments_expr(frames) for p_ in ab for x in p_]))
        probe = ca.Function("capsule_probe", [T, psi], [ca.horzcat(*segs), valid])
        rng = np.random.default_rng(0)
        X, ok = [], []  # per sample, at ψ and at ψ + π
        for _ in range(samples):
            pose, psi0 = robot.fk(rng.uniform(robot.q_min, robot.q_max)), rng.uniform(-np.pi, np.pi)
            pair = [probe(pose, x) for x in (psi0, psi0 + np.pi)]
            X.append([np.asarray(S) for S, _ in pair])
            ok.append([np.asarray(v).ravel()[: self.rows] > 0.5 for _, v in pair])
        X, ok = np.array(X), np.array(ok)  # (samples, 2, 6C, B), (samples, 2, B)
        twin = [(b, False) for b in range(self.rows)]
        for b in range(self.rows):
            for a, half in itertools.product(range(b), (False, True)):
                both = ok[:, int(half), a] & ok[:, 0, b]
                same = both.sum() >= samples // 2 and np.abs(X[both, int(half), :, a] - X[both, 0, :, b]).max() < 1e-9
                if same and twin[a] == (a, False):
                    twin[b] = (a, half)
                    break
        return twin

    @cached_property
    def objective_params(self) -> np.ndarray:
        return np.zeros(0) if self.objective is None else self.objective.params(self.robot)

    def configurations(self, ks: np.ndarray, rows: np.ndarray, index: np.ndarray) -> np.ndarray:
        """(M, n) the configurations of the states (waypoint ks, grid row, grid index) (M,) each."""
        n, call, layout = self.robot.dof, self._compiled, self.state_layout
        cols = np.swapaxes(self.poses[ks], 1, 2).reshape(len(ks), 16)
        out = np.empty((len(ks), n))
        for m, (T, value, b) in enumerate(zip(cols, self.values[index], rows)):
            (row,) = call(T, np.array([value]), self.objective_params, self.q_ref, self.obstacle_input)
            out[m] = layout.views(row.reshape(-1, layout.size)).q[b]
        return out

    def split_function(self) -> tuple[ca.Function, ca.Function]:
        """:meth:`function` split at its waypoint-only part (CasADi's ``extract_parametric``): ``pre(c) -> s`` once per
        waypoint and ``row(c, s, ψ)`` per grid value, the same outputs, with c = [T column-major (16), objective
        params, q_ref (n), obstacle params]."""
        fn = self._function
        T, psi = ca.SX.sym("T", 16), ca.SX.sym(self.param_name)
        rest = [ca.SX.sym(fn.name_in(i), fn.nnz_in(i)) for i in (2, 3, 4)]
        fixed = ca.vertcat(T, *rest)
        out, symbols, values = ca.extract_parametric(fn(ca.reshape(T, 4, 4), psi, *rest), fixed)
        s = ca.vertcat(*symbols)
        pre = ca.Function(f"{fn.name()}_pre", [fixed], [ca.densify(ca.vertcat(*values))])
        return pre, ca.Function(f"{fn.name()}_row", [fixed, s, psi], [out])

    @cached_property
    def _native(self) -> _NativeLayers | None:
        return _NativeLayers.for_grid(self, *(Compiled(f) for f in self.split_function()))

    def build(self) -> None:
        """Trace and compile now what :meth:`layers` and :meth:`configurations` call (the C layers, or the row map at
        every call size), so that the DP's clock counts evaluations, never a compile."""
        _ = self._compiled
        if self._native is None:
            self._rows.build()

    def layers(self, k0: int, k1: int) -> Layers:
        """The states of waypoints k0 .. k1 - 1 (see :class:`Layers`): only the grid values inside a branch's
        exact feasible set count (in C only the rows with one are evaluated; in numpy every row is)."""
        K, B, G = k1 - k0, self.rows, self.G
        cols = np.ascontiguousarray(np.swapaxes(self.poses[k0:k1], 1, 2)).reshape(K, 16)
        if self._native is not None:
            return self._native(cols, self.inside[k0:k1])
        (out,) = self._rows(np.repeat(cols, G, axis=0), np.tile(self.values, K), self.objective_params, self.q_ref,
                            self.obstacle_input)  # fmt: skip
        state = self.state_layout.views(out.reshape(K, G, B, self.state_layout.size))  # each (K, G, B, ...)
        root, shift = self.clearance_sources
        clear = state.clearance[:, (np.arange(G)[None, :] + shift[:, None]) % G, root[:, None]]  # (K, B, G)
        q = np.ascontiguousarray(state.q.transpose(0, 2, 1, 3))
        f = state.f.transpose(0, 2, 1)
        ok = (state.valid.transpose(0, 2, 1) > 0.5) & self.inside[k0:k1] & (clear >= self.d_safe) & np.isfinite(f)
        return Layers(q, ok, np.where(ok, f, np.inf))


class _NativeLayers:
    """:meth:`Grid.layers`' C path: ``qpik_plan_layers`` (``grid.c``) calling the row function's generated C."""

    def __init__(self, dll: ctypes.CDLL, pre: NativeFunction, row: NativeFunction, grid: Grid):
        self._dll, self._pre, self._row = dll, pre, row  # the C call uses their buffers: they live as long
        self.B, self.G, self.n, self.d_safe = grid.rows, grid.G, grid.robot.dof, grid.d_safe
        self.values = np.ascontiguousarray(grid.values, float)
        self.root, self.shift = (np.ascontiguousarray(x, np.int64) for x in grid.clearance_sources)
        self._clear, self._need = np.zeros((self.B, self.G)), np.zeros(self.G, np.uint8)
        fixed, psi, out = pre.args[0], row.args[2], row.res[0]  # the C call sets the pose per waypoint
        given = Layout(pose=16, objective=grid.objective_params.size, q_ref=grid.robot.dof,
                       obstacles=grid.obstacle_input.size).views(fixed)  # fmt: skip
        given.objective[...], given.q_ref[...], given.obstacles[...] = (grid.objective_params, grid.q_ref,
                                                                         grid.obstacle_input)  # fmt: skip
        self._head = (*pre.addresses, *row.addresses, fixed.ctypes.data, psi.ctypes.data, out.ctypes.data)

    @classmethod
    def for_grid(cls, grid: Grid, pre: Compiled, row: Compiled) -> _NativeLayers | None:
        """The C path for ``grid`` with its split row function (:meth:`Grid.split_function`) compiled, or None
        when that or ``grid.c`` is not native code."""
        dll = _library()
        first = None if dll is None else NativeFunction.of(pre, outputs=(0,))
        if first is None:
            return None
        # the row function reads the fixed inputs and the waypoint's part (the first one's output) from their buffers
        second = NativeFunction.of(row, outputs=(0,), inputs={0: first.args[0], 1: first.res[0]})
        return None if second is None else cls(dll, first, second, grid)

    def __call__(self, cols: np.ndarray, inside: np.ndarray) -> Layers:
        """The states of the waypoints of ``cols`` (K, 16) (poses column-major) with ``inside`` (K, B, G)."""
        K, B, G, n = len(cols), self.B, self.G, self.n
        q, ok, f = np.empty((K, B, G, n)), np.empty((K, B, G), np.uint8), np.empty((K, B, G))
        inside = np.ascontiguousarray(inside, np.uint8)
        status = self._dll.qpik_plan_layers(*self._head, K, B, G, n, cols.ctypes.data, self.values.ctypes.data,
                                            inside.ctypes.data, self.root.ctypes.data, self.shift.ctypes.data,
                                            self.d_safe, self._clear.ctypes.data, self._need.ctypes.data,
                                            q.ctypes.data, ok.ctypes.data, f.ctypes.data)  # fmt: skip
        if status:
            raise SolverError("qpik_plan_layers: the compiled state function failed")
        return Layers(q, ok.view(bool), f)


@cache
def _library() -> ctypes.CDLL | None:
    """``grid.c`` compiled (:func:`qpik.native.sources.load_source`), or None without a compiler."""
    args = [ctypes.c_void_p] * 13 + [ctypes.c_longlong] * 4 + [ctypes.c_void_p] * 5 + [ctypes.c_double]
    args += [ctypes.c_void_p] * 5
    return load_source("qpik_plan_layers", "cdll", ["grid.c"], signatures={"qpik_plan_layers": (ctypes.c_int, args)})
