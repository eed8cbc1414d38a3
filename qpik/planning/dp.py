r"""Dynamic programming over the parameter grid (:mod:`qpik.planning.grid`): the best sequence of states.

A plan picks one feasible state :math:`s_k = (b_k, i_k)` per waypoint (branch row, grid index) and
costs

.. math:: J = \sum_{k} \frac{\lVert q(s_{k+1}) - q(s_k) \rVert^2}{\Delta_k} + \sum_k w_k\, f(q(s_k)),

with :math:`\Delta_k` the progress (or time, s) between waypoints k and k+1 and :math:`w_k` the
trapezoid weights of the same progress, so that J approximates
:math:`\int \lVert dq/ds \rVert^2 ds + \int f\, ds`. A transition is *continuous* when every joint
moves by at most its bound, :math:`|q_j(s_{k+1}) - q_j(s_k)| \le \ell_{k,j}` (the L∞ bound of the
largest joint step and, with times, :math:`v_{max,j} \Delta t_k`; with ``a_max``, also the
acceleration from the velocity of the state's best predecessor, as Ferrentino et al. check it).

Continuous transitions are searched on the same branch between grid values at most ``window``
indices apart (cyclically): a parameter change of Δ moves the shoulder by Δ about the
shoulder–wrist line (S-R-S: :math:`\sum_{j \le 3} |\Delta q_j| \ge |\Delta\psi|`; offset shoulder:
:math:`\Delta q_1 = \Delta\delta` plus the wrist's azimuth change), so a larger change is a large
joint step. Where the banded search loses every state, every pair of the two waypoints is
checked before giving up.

``reconfigure="forbid"``: continuous transitions only; the first waypoint that no continuous
transition reaches is reported. ``"fewest"``: a transition that is not continuous is a
*reconfiguration* (the arm stops and changes configuration); the plan has the fewest of them
and, among those, the least J (lexicographic order, exact on the grid).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from functools import cache

import numpy as np

from qpik.analytic.api import symbol
from qpik.core.progress import Progress
from qpik.native.sources import load_source
from qpik.planning.grid import Grid, Layers

CHUNK = 32
"""Waypoints whose states are evaluated per call of :meth:`Grid.layers`."""


@dataclass
class Transitions:
    """What bounds a transition from waypoint k to k + 1 (k = 0..N-2).

    Attributes:
        step: (N-1, n) the largest move of each joint, rad.
        motion: (N-1,) 1/Δ_k, the weight of ‖Δq‖².
        point: (N,) w_k, the weight of f at each waypoint.
        dt: (N-1,) seconds between waypoints (None without times).
        a_max: (n,) acceleration limits, rad/s² (None: not checked).
    """

    step: np.ndarray
    motion: np.ndarray
    point: np.ndarray
    dt: np.ndarray | None = None
    a_max: np.ndarray | None = None


@dataclass
class Failure:
    """Why the DP found no plan: the first waypoint that cannot be reached and why (words).

    ``kind``: ``"infeasible"`` when the exact feasible set of that waypoint is empty (no branch reaches the
    pose inside the joint limits at any parameter: a proof), ``"grid"`` otherwise (only the grid failed)."""

    waypoint: int
    reason: str
    kind: str = "grid"


@dataclass
class DPResult:
    """The DP's plan.

    Attributes:
        rows, index: (N,) the grid row and index of each waypoint's state (-1 past a failure).
        q: (K, n) configurations, rad, of the waypoints before a failure (K = N without one).
        cost: J of the plan (its prefix up to the failure).
        reconfigurations: the waypoints k whose transition to k + 1 is a reconfiguration.
        failure: why the plan stops early ("forbid" only), or None.
        ok: (N, B, G) which states are feasible (for the self-motion map).
        evaluated: states evaluated (feasible or not).
    """

    rows: np.ndarray
    index: np.ndarray
    q: np.ndarray
    cost: float
    reconfigurations: list[int] = field(default_factory=list)
    failure: Failure | None = None
    ok: np.ndarray | None = None
    evaluated: int = 0


class _Layers:
    """:meth:`Grid.layers` in chunks of :data:`CHUNK` waypoints, kept while used."""

    def __init__(self, grid: Grid):
        self.grid, self.k0, self.data = grid, -1, None
        self.evaluated = 0
        N = len(grid.poses)
        self.ok = np.zeros((N, grid.rows, grid.G), bool)

    def __call__(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q (B, G, n), ok (B, G), f (B, G) of waypoint k."""
        if self.data is None or not self.k0 <= k < self.k0 + len(self.data.ok):
            self.k0 = k
            self.data: Layers = self.grid.layers(k, min(k + CHUNK, len(self.grid.poses)))
            self.ok[k : k + len(self.data.ok)] = self.data.ok
            self.evaluated += int(self.grid.inside[k : k + len(self.data.ok)].sum())
        j = k - self.k0
        return self.data.q[j], self.data.ok[j], self.data.f[j]


def build(grid: Grid) -> None:
    """Trace and compile what :func:`solve` calls on ``grid`` (:meth:`Grid.build` and ``dp.c``), so that a clock
    started after it counts the DP's work only."""
    grid.build()
    _library()


def solve(grid: Grid, tr: Transitions, window: int, fewest: bool, progress: bool = True) -> DPResult:
    """The DP of the module docstring on ``grid``; ``window``: grid indices searched each way (≥ 1). A DP that runs
    longer than a moment says how far it is on stderr (:class:`qpik.core.progress.Progress`; ``progress``)."""
    N, B, G = len(grid.poses), grid.rows, grid.G
    said = Progress(f"the DP over {N} waypoints × {B} branches × {G} values, waypoint", N, progress)
    layers = _Layers(grid)
    w = int(min(max(window, 1), G // 2))
    offsets = np.arange(-w, w + 1) if 2 * w + 1 <= G else np.arange(G)
    src = np.full((N, B, G), -1, np.int64)  # flat source state b*G + i of each state's best predecessor
    jumped = np.zeros((N, B, G), bool)
    q0, ok0, f0 = layers(0)
    V = np.where(ok0, tr.point[0] * f0, np.inf)
    J = np.zeros((B, G), np.int64)
    vel = np.zeros((B, G, q0.shape[-1])) if tr.a_max is not None else None
    failure = None if ok0.any() else _empty_failure(grid, layers, 0)
    last = N - 1 if failure is None else -1
    for k in range(N - 1 if failure is None else 0):
        said(k)
        qa, _, _ = layers(k)
        qb, okb, fb = layers(k + 1)
        step = _Step(qa, qb, okb, fb, tr, k, vel)
        Vn, Jn, s = step.banded(V, J, offsets)
        if not np.isfinite(Vn).any() and okb.any():
            Vn, Jn, s = step.full(V, J)  # the band lost every state: every pair
        elif okb.any():  # across branches too: they meet at the singular positions
            Vn, Jn, s = _merge((Vn, Jn, s), step.full(V, J, cross=True))
        jump = np.zeros((B, G), bool)
        if fewest:
            Vn, Jn, s, jump = _jumps(V, J, Vn, Jn, s, okb, tr.point[k + 1] * fb)
        if not np.isfinite(Vn).any():
            failure = _failure(grid, layers, step, k, V)
            last = k
            break
        if vel is not None:
            has = s >= 0
            prev = qa.reshape(B * G, -1)[np.where(has, s, 0)]
            vel = np.where((has & ~jump)[..., None], (qb - prev) / tr.dt[k], 0.0)
        V, J, src[k + 1], jumped[k + 1] = Vn, Jn, s, jump
    said.finish(N if failure is None else max(last + 1, 0))
    rows, index, q = _backtrack(layers, src, jumped, V, J, last, grid)
    recon = [k for k in range(last) if jumped[k + 1, rows[k + 1], index[k + 1]]]
    cost = float(V.reshape(-1)[rows[last] * G + index[last]]) if last >= 0 else np.inf
    return DPResult(rows, index, q, cost, recon, failure, layers.ok, layers.evaluated)


class _Step:
    """The transitions from waypoint k (states qa) to k + 1 (qb, okb, fb)."""

    def __init__(self, qa, qb, okb, fb, tr: Transitions, k: int, vel):
        self.qa, self.qb, self.okb, self.fb = qa, qb, okb, fb
        self.lim = tr.step[k]
        self.wm, self.wp = tr.motion[k], tr.point[k + 1]
        self.vel = vel
        if tr.a_max is not None:
            self.dt = tr.dt[k]
            self.dv = tr.a_max * 0.5 * (tr.dt[k] + (tr.dt[k - 1] if k > 0 else tr.dt[k]))
        self.B, self.G = okb.shape

    def _cost(self, V, D, src_flat):
        """Candidate values for moves D (..., n) from the flat source states ``src_flat``; inf where not allowed."""
        fits = (np.abs(D) <= self.lim).all(axis=-1)
        if self.vel is not None:
            v = self.vel.reshape(self.B * self.G, -1)[src_flat]
            fits &= (np.abs(D / self.dt - v) <= self.dv).all(axis=-1)
        c = V.reshape(-1)[src_flat] + self.wm * np.einsum("...j,...j->...", D, D)
        return np.where(fits, c, np.inf)

    def banded(self, V, J, offsets):
        """Same branch, sources at j - o for every offset o: the best per destination (b, j).

        Through ``dp.c`` (compiled at first use) when a C compiler works, else the same in numpy."""
        lib = _library()
        if lib is not None:
            return self._native(lib, V, J, offsets)
        B, G = self.B, self.G
        j = np.arange(G)
        i = (j[None, :] - offsets[:, None]) % G  # (O, G) source index of destination j at offset o
        flat = np.arange(B)[:, None, None] * G + i[None]  # (B, O, G)
        D = self.qb[:, None, :, :] - self.qa[:, i]  # (B, O, G, n)
        c = self._cost(V, D, flat)
        return self._pick(c, J.reshape(-1)[flat], flat, 1)

    def _native(self, lib, V, J, offsets):
        B, G, n = self.B, self.G, self.qa.shape[-1]
        Vn, Jn, s = np.empty((B, G)), np.empty((B, G), np.int64), np.empty((B, G), np.int64)
        args = [np.ascontiguousarray(x, dtype) for x, dtype in (
            (offsets, np.int64), (self.qa, float), (self.qb, float), (self.okb, np.uint8), (self.fb, float),
            (V, float), (J, np.int64), (self.lim, float))]  # fmt: skip
        vel = None if self.vel is None else np.ascontiguousarray(self.vel, float)
        dv = None if self.vel is None else np.ascontiguousarray(self.dv, float)
        ptr = [a.ctypes.data for a in args]
        vel_ptr, dv_ptr = (None, None) if vel is None else (vel.ctypes.data, dv.ctypes.data)
        inv_dt = 0.0 if vel is None else 1.0 / self.dt
        lib.qpik_dp_banded(B, G, n, len(offsets), *ptr, self.wm, self.wp, vel_ptr, inv_dt, dv_ptr, Vn.ctypes.data,
                           Jn.ctypes.data, s.ctypes.data)  # fmt: skip
        return Vn, Jn, s

    def full(self, V, J, cross: bool = False):
        """Every reachable source state against every feasible destination (any branch; ``cross``: of another
        branch only): the pairs within the joint-step bounds are found by k-d trees (scipy's ``cKDTree``, L∞
        metric on the moves scaled by their bounds; one tree per branch with ``cross``, so that branches far
        apart are pruned at once), so the cost grows with the pairs that fit, not with all pairs. Also keeps
        what :attr:`closest` needs."""
        from scipy.spatial import cKDTree

        B, G = self.B, self.G
        n = self.qa.shape[-1]
        best = (np.full((B, G), np.inf), np.zeros((B, G), np.int64), np.full((B, G), -1))
        live = np.flatnonzero(np.isfinite(V.reshape(-1)))
        dest = np.flatnonzero(self.okb.reshape(-1))
        self._closest = None
        if not len(live) or not len(dest):
            return best
        qa = self.qa.reshape(B * G, n)[live] / self.lim
        tree = cKDTree(self.qb.reshape(B * G, n)[dest] / self.lim)
        self._closest = (tree, qa, live, dest)
        if cross:
            src, dst = self._cross(live, dest)
        else:
            pairs = cKDTree(qa).sparse_distance_matrix(tree, 1.0 + 1e-12, p=np.inf, output_type="ndarray")
            src, dst = live[pairs["i"]], dest[pairs["j"]]
        if not len(src):
            return best
        D = self.qb.reshape(B * G, n)[dst] - self.qa.reshape(B * G, n)[src]
        c = self._cost(V, D, src) + self.wp * self.fb.reshape(-1)[dst]
        jumps = J.reshape(-1)[src]
        keep = np.isfinite(c)
        src, dst, c, jumps = src[keep], dst[keep], c[keep], jumps[keep]
        order = np.lexsort((c, jumps, dst))  # per destination: fewest jumps, then least value
        first = np.ones(len(order), bool)
        first[1:] = dst[order][1:] != dst[order][:-1]
        pick = order[first]
        Vn, Jn, s = (x.reshape(-1).copy() for x in best)
        Vn[dst[pick]], Jn[dst[pick]], s[dst[pick]] = c[pick], jumps[pick], src[pick]
        return Vn.reshape(B, G), Jn.reshape(B, G), s.reshape(B, G)

    def _cross(self, live: np.ndarray, dest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flat (source, destination) pairs within the bounds whose branches differ."""
        from scipy.spatial import cKDTree

        n = self.qa.shape[-1]
        rows_a, rows_b = live // self.G, dest // self.G
        trees_a = {b: (live[rows_a == b], cKDTree(self.qa.reshape(-1, n)[live[rows_a == b]] / self.lim))
                   for b in np.unique(rows_a)}  # fmt: skip
        trees_b = {b: (dest[rows_b == b], cKDTree(self.qb.reshape(-1, n)[dest[rows_b == b]] / self.lim))
                   for b in np.unique(rows_b)}  # fmt: skip
        src, dst = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
        for a, (ia, ta) in trees_a.items():
            for b, (ib, tb) in trees_b.items():
                if a != b:
                    pairs = ta.sparse_distance_matrix(tb, 1.0 + 1e-12, p=np.inf, output_type="ndarray")
                    src.append(ia[pairs["i"]]), dst.append(ib[pairs["j"]])
        return np.concatenate(src), np.concatenate(dst)

    @property
    def closest(self) -> tuple[float, int, int]:
        """After :meth:`full`: the pair that comes closest to the bounds, ``(largest step over its bound, source
        flat index, destination flat index)``."""
        if self._closest is None:
            return (np.inf, -1, -1)
        tree, qa, live, dest = self._closest
        ratio, m = tree.query(qa, k=1, p=np.inf)
        a = int(np.argmin(ratio))
        return (float(ratio[a]), int(live[a]), int(dest[m[a]]))

    def _pick(self, c, Jc, flat, axis: int):
        """Per destination (b, j), the candidate along ``axis`` of fewest jumps, then least value."""
        ok = np.expand_dims(self.okb, axis)
        c = np.where(ok, c + self.wp * np.expand_dims(np.where(self.okb, self.fb, 0.0), axis), np.inf)
        Jc = np.where(np.isfinite(c), Jc, np.iinfo(np.int64).max)
        Jmin = Jc.min(axis=axis, keepdims=True)
        c = np.where(Jc == Jmin, c, np.inf)
        best = np.expand_dims(c.argmin(axis=axis), axis)
        V = np.take_along_axis(c, best, axis).squeeze(axis)
        s = np.take_along_axis(np.broadcast_to(flat, c.shape), best, axis).squeeze(axis)
        live = np.isfinite(V)
        return V, np.where(live, Jmin.squeeze(axis), 0), np.where(live, s, -1)


def _merge(a, b):
    """Per destination, the better of two (V, J, source) candidates: fewest jumps, then least value."""
    better = np.isfinite(b[0]) & (~np.isfinite(a[0]) | (b[1] < a[1]) | ((b[1] == a[1]) & (b[0] < a[0])))
    return tuple(np.where(better, y, x) for x, y in zip(a, b))


def _jumps(V, J, Vn, Jn, s, okb, fb):
    """With reconfigurations: every feasible state is reachable from the best (fewest jumps, least value) state
    of the waypoint before, with one jump more; kept where it beats the continuous transitions."""
    Vf, Jf = V.reshape(-1), J.reshape(-1)
    live = np.isfinite(Vf)
    if not live.any():
        return Vn, Jn, s, np.zeros(okb.shape, bool)
    jmin = Jf[live].min()
    best = int(np.flatnonzero(live & (Jf == jmin))[np.argmin(Vf[live & (Jf == jmin)])])
    Vj = np.where(okb, Vf[best] + np.where(okb, fb, 0.0), np.inf)
    Jj = jmin + 1
    better = okb & (~np.isfinite(Vn) | (Jj < Jn) | ((Jj == Jn) & (Vj < Vn)))
    return (np.where(better, Vj, Vn), np.where(better, Jj, Jn), np.where(better, best, s), better)


def _backtrack(layers: _Layers, src, jumped, V, J, last: int, grid: Grid):
    """The best final state (fewest jumps, least value) and its predecessors back to waypoint 0."""
    N, _, G = src.shape
    n = grid.robot.dof
    Vf, Jf = V.reshape(-1), J.reshape(-1)
    live = np.isfinite(Vf)
    rows, index = np.full(N, -1), np.full(N, -1)
    if last < 0 or not live.any():
        return rows, index, np.zeros((0, n))
    jmin = Jf[live].min()
    cand = live & (Jf == jmin)
    s = int(np.flatnonzero(cand)[np.argmin(Vf[cand])])
    for k in range(last, -1, -1):
        rows[k], index[k] = divmod(s, G)
        s = int(src[k, rows[k], index[k]]) if k else -1
    q = grid.configurations(np.arange(last + 1), rows[: last + 1], index[: last + 1])
    return rows, index, q


def _empty(grid: Grid, layers: _Layers, k: int) -> str:
    """Why waypoint k has no feasible state (words)."""
    sym = symbol(grid.param_name)
    if not grid.inside[k].any():
        if _proved_empty(grid, k):
            return f"no branch reaches this pose with every joint inside its limits at any {sym}"
        if grid.intervals is None:
            return (f"the search finds no branch inside the joint limits at the {grid.G} grid values of {sym} (no "
                    "feasible sets for this arm: a narrower one may exist between them)")  # fmt: skip
        return f"its feasible {sym} intervals hold no grid value (narrower than the grid step {grid.spacing:.3g} rad)"
    what = "an obstacle or, for a checked capsule pair, to itself" if grid.self_pairs else "an obstacle"
    return (f"every configuration inside the joint limits is closer than d_s = {grid.d_safe:g} m to {what}"
            f" (at the {grid.G} grid values of {sym})")  # fmt: skip


def _proved_empty(grid: Grid, k: int) -> bool:
    """Whether the exact feasible intervals of waypoint k (every branch) are empty, and proved so (never without
    sets)."""
    if grid.intervals is None:
        return False
    fi = grid.intervals[k]
    return fi.proved and not any(fi.intervals[b] for b in range(grid.rows))


def _empty_failure(grid: Grid, layers: _Layers, k: int) -> Failure:
    """Waypoint k has no feasible grid state: a proof when its exact feasible set is empty."""
    kind = "infeasible" if _proved_empty(grid, k) else "grid"
    return Failure(k, _empty(grid, layers, k), kind)


def _failure(grid: Grid, layers: _Layers, step: _Step, k: int, V: np.ndarray) -> Failure:
    """Why waypoint k + 1 cannot be reached from the states reachable at waypoint k (after :meth:`_Step.full`)."""
    if not step.okb.any():
        return _empty_failure(grid, layers, k + 1)
    _, a, b = step.closest
    n = step.qa.shape[-1]
    d = np.abs(step.qb.reshape(-1, n)[b] - step.qa.reshape(-1, n)[a])
    j = int(np.argmax(d / step.lim))
    return Failure(k + 1, f"the grid ({grid.G} values per branch) holds no state within the joint-step bounds of"
                          f" one reachable at waypoint {k} (the grid failed; a motion between its values may exist):"
                          f" the smallest move on the grid needs joint {j + 1} to move {d[j]:.3g} rad"
                          f" (bound {step.lim[j]:.3g} rad)")  # fmt: skip


@cache
def _library() -> ctypes.CDLL | None:
    """``dp.c`` compiled (:func:`qpik.native.sources.load_source`), or None without a compiler."""
    args = [ctypes.c_longlong] * 4 + [ctypes.c_void_p] * 8 + [ctypes.c_double] * 2
    args += [ctypes.c_void_p, ctypes.c_double] + [ctypes.c_void_p] * 4
    return load_source("qpik_dp", "cdll", ["dp.c"], signatures={"qpik_dp_banded": (None, args)})
