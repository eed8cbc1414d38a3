"""bounds: see :mod:`qpik.objectives`."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache, cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.enclosure import taylor_function
from qpik.core.errors import InputError
from qpik.geometry.distance import PARAMS, ObstacleSet, axis_distance, set_layout
from qpik.native.build import concurrently
from qpik.native.compiled import RowMap

if TYPE_CHECKING:
    from qpik.robots.robot import Robot
from qpik.objectives.context import Context, pair_count
from qpik.objectives.objective import Objective
from qpik.robots.self_pairs import Pair


class BoundFunction:
    r"""Taylor models of an objective's split and of the capsule–obstacle distances, for the certificate.

    For a range of configurations given as Taylor models :math:`q(t) = c + s\,t \pm r` in one
    variable :math:`t \in [-1, 1]` (within [lo, hi]; :func:`qpik.algebra.enclosure.taylor_function`, e.g. the
    closed form over a δ/ψ range), :meth:`rows` gives the models of the values

    .. math:: v = [\,s(q);\ w_1 \dots w_K;\ h_1 (m_1);\ \dots;\ h_K (m_K);\ d\ (C \cdot O);\ e\ (P)\,]

    — the split's smooth part, its weights (parameters: single values), the pieces of each maximum
    (:class:`Split`), the capsule–obstacle distances and the distances of the capsule pairs ``self_pairs`` (m):
    the last :attr:`n_clear` values are the clearances (:attr:`~qpik.objectives.context.Context.clearances`).
    Each value lies, for the same t, within ``centre + slope·t ± radius`` and within [lo, hi], so for every t, with
    :math:`\ell(t) = \max(lo,\ c + s\,t - r)` of each value (lower lines),

    .. math:: f(q(t)) \ge \ell_s(t) + \sum_k w_k \max_i \ell_{k,i}(t),

    a convex piecewise-linear function of t whose minimum over [−1, 1] is a lower bound of f over the
    range (:func:`qpik.nlp.certificate.lower_bound`); a clearance whose upper bound is below d_s on the
    whole range proves the clearance constraint violated there.

    The models are composed from three kinds of Taylor function, each compiled once and evaluated over
    rows: the end points of the moving capsules from q (per robot), the distance of one capsule to one
    obstacle from its end points (per obstacle family, shared by every robot, objective and pair), and
    the split from q and the distances (per objective form); a capsule pair's distance is the capsule kernel
    with both axes models (:func:`_self_pair_model`). Models compose because they share t: the
    outputs of one Taylor function are model inputs of the next.

    Raises:
        InputError: an operation of the objective's expression has no Taylor-model rule (a user
            expression): then no bound exists, and no certificate.
    """

    def __init__(self, robot: Robot, objective: Objective, obstacles: ObstacleSet, self_pairs: tuple[Pair, ...] = ()):
        n = robot.dof
        self.params = objective.params(robot)
        q, q_ref = ca.SX.sym("q", n), ca.SX.sym("q_ref", n)
        p = ca.SX.sym("p", len(self.params))
        prm = ca.SX.sym("obstacles", len(obstacles.params))
        self.n_pairs = pair_count(robot, obstacles)
        d = ca.SX.sym("d", self.n_pairs)
        split = objective.split(Context(robot, q, q_ref, obstacles, prm, distances=d), p)
        self.sizes = tuple(int(h.numel()) for _, h in split.maxima)
        """m_k: the number of pieces of each maximum."""
        values = ca.vertcat(split.smooth, *[w for w, _ in split.maxima], *[h for _, h in split.maxima], d)
        name = robot.identifier
        self._split = RowMap(
            taylor_function(ca.Function(f"bound_{name}", [q, p, q_ref, prm, d], [ca.densify(values)]), [0, 4]),
            shared=(1, 3),
            chunks=(16, 16),
        )
        self._form = (robot, objective, obstacles)
        self.self_pairs = self_pairs
        self.n_clear = self.n_pairs + len(self_pairs)
        """The number of clearances, the last values of v: capsule–obstacle pairs, then capsule pairs."""
        self._segments = _segment_models(robot) if self.n_clear else None
        moving = np.flatnonzero(~robot.fixed_capsules)
        self._rank = np.cumsum(~robot.fixed_capsules) - 1
        """Capsule index -> its rank among the moving capsules (the blocks of :func:`_segment_models`)."""
        self._pairs = [(c, o, kind) for c in range(len(moving)) for o, kind in enumerate(obstacles.kinds)]
        self._radii = robot.capsule_radii[moving]
        self._records = set_layout(obstacles.kinds)

    @cached_property
    def values(self) -> ca.Function:
        """v itself at one configuration, ``(q, p, q_ref, obstacle params) -> v`` (L,), written directly (the
        distances from q, not through models): what the models enclose."""
        robot, objective, obstacles = self._form
        q, q_ref = ca.SX.sym("q", robot.dof), ca.SX.sym("q_ref", robot.dof)
        p, prm = ca.SX.sym("p", len(self.params)), ca.SX.sym("obstacles", len(obstacles.params))
        ctx = Context(robot, q, q_ref, obstacles, prm, self_pairs=self.self_pairs)
        split = objective.split(ctx, p)
        v = ca.vertcat(split.smooth, *[w for w, _ in split.maxima], *[h for _, h in split.maxima], ctx.clearances)
        return ca.Function(f"bound_values_{robot.identifier}", [q, p, q_ref, prm], [ca.densify(v)])

    def rows(self, c: np.ndarray, params: np.ndarray, q_ref: np.ndarray, obstacle_params: np.ndarray,
             s: np.ndarray, r: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:  # fmt: skip
        """``[centre, slope, radius, lo, hi]`` of v (each (M, L)) for the q models of M rows: centres ``c``,
        slopes ``s``, radii ``r`` and bounds ``lo``, ``hi`` (each (M, n), rad), with the objective's
        ``params``, ``q_ref`` (M, n) and the packed ``obstacle_params`` (:attr:`ObstacleSet.params`)."""
        M = len(c)
        d = [np.zeros((M, 0))] * 5
        seg = None if self._segments is None else self._segments(c, s, r, lo, hi)  # 5 × (M, 6 C')
        if self.n_pairs:
            d = [np.empty((M, self.n_pairs)) for _ in range(5)]
            for kind, at in _by_kind(self._pairs):
                cap = np.array([self._pairs[k][0] for k in at])
                obs = np.array([self._pairs[k][1] for k in at])
                pick = (6 * cap[:, None] + np.arange(6)).ravel()
                parts = [x[:, pick].reshape(M * len(at), 6) for x in seg]
                radius = np.tile(self._radii[cap], M)[:, None]
                records = self._records.views(np.asarray(obstacle_params, float))
                prm = np.tile(np.stack([records[f"o{o}"] for o in obs]), (M, 1))
                out = _pair_models(kind)(parts[0], radius, prm, *parts[1:])
                for whole, part in zip(d, out):
                    whole[:, at] = part.reshape(M, len(at))
        models = self._split(c, params, q_ref, obstacle_params, d[0], s, r, lo, hi, *d[1:])
        if not self.self_pairs:
            return models
        return [np.hstack([v, e]) for v, e in zip(models, self._self_rows(seg, M))]

    def _self_rows(self, seg: list[np.ndarray], M: int) -> list[np.ndarray]:
        """The models ``[centre, slope, radius, lo, hi]`` (each (M, P)) of the capsule pairs' distances from the
        moving capsules' axis models ``seg``; a fixed capsule's axis is a constant (slope and radius 0, lo = hi)."""
        robot, P = self._form[0], len(self.self_pairs)
        fixed = robot.fixed_capsules
        ends = robot.capsule_segments(robot.q_home[None])[0]
        axes = []
        for c in (c for pair in self.self_pairs for c in pair):
            if fixed[c]:
                a, b = ends[c]
                value = np.tile(np.concatenate([a, b - a]), (M, 1))
                zero = np.zeros((M, 6))
                axes.append([value, zero, zero, value, value])
            else:
                pick = 6 * self._rank[c] + np.arange(6)
                axes.append([x[:, pick] for x in seg])
        first, second = ([np.concatenate([axes[2 * k + j][m] for k in range(P)]) for m in range(5)] for j in (0, 1))
        radii = robot.capsule_radii[np.array(self.self_pairs)]
        radius = [np.repeat(radii[:, j], M)[:, None] for j in (0, 1)]
        out = _self_pair_model()(first[0], second[0], *radius, *first[1:], *second[1:])
        return [x.reshape(P, M).T for x in out]

    def builds(self) -> list[Callable[[], None]]:
        """The compiles of every function :meth:`rows` calls (:meth:`~qpik.native.compiled.RowMap.build`), to run
        now."""
        maps = [self._split, *([] if self._segments is None else [self._segments])]
        maps += [_self_pair_model()] if self.self_pairs else []
        return [m.build for m in maps + [_pair_models(kind) for kind, _ in _by_kind(self._pairs)]]

    def build(self) -> None:
        """Compile every function :meth:`rows` calls now, concurrently (:func:`qpik.native.build.concurrently`)."""
        concurrently(*self.builds())


def _by_kind(pairs: list[tuple[int, int, str]]) -> list[tuple[str, np.ndarray]]:
    """The pair indices of each obstacle family, in first-seen order."""
    kinds = list(dict.fromkeys(kind for _, _, kind in pairs))
    return [(kind, np.array([k for k, (_, _, x) in enumerate(pairs) if x == kind])) for kind in kinds]


def _segment_models(robot: Robot) -> RowMap:
    """The Taylor models of the moving capsules' axes ``[a, u]`` (6 C', world frame, m) from q's model:
    ``(c, s, r, lo, hi) -> 5 × (6 C')``, compiled once per robot. A capsule of link k with end points
    :math:`p_0, p_1` (link frame) has :math:`a = R_k p_0 + t_k` and :math:`u = R_k (p_1 - p_0)`: u written
    without the link's position, so its model carries none of t_k's remainder."""
    return robot.cache.get("capsule axis models", _build_segment_models, robot)


def _build_segment_models(robot: Robot) -> RowMap:
    q = ca.SX.sym("q", robot.dof)
    frames = robot.chain.frames_expr([q[i] for i in range(robot.dof)], sy.CASADI)
    axes = []
    for c in np.flatnonzero(~robot.fixed_capsules):
        capsule = robot.capsules[c]
        R, t = frames[capsule.link]
        p0, p1 = (tuple(map(sy.snap, p)) for p in (capsule.p0, capsule.p1))
        axes += [*sy.vadd(sy.matvec(R, p0), t), *sy.matvec(R, sy.vsub(p1, p0))]
    fn = ca.Function(f"axes_{robot.identifier}", [q], [ca.densify(ca.vertcat(*axes))])
    return RowMap(taylor_function(fn, [0]), chunks=(16, 16))


@cache
def _pair_models(kind: str) -> RowMap:
    """The Taylor model of one capsule–obstacle distance (m) of family ``kind`` from its axis's models
    (:func:`_segment_models`): ``(axis [a, u] (6,), radius, obstacle params, slope, radius, lo, hi of the axis)
    -> 5 × (1,)``, compiled once."""
    axis, radius, prm = ca.SX.sym("axis", 6), ca.SX.sym("radius"), ca.SX.sym("obstacle", PARAMS[kind])
    a, u = tuple(axis[i] for i in range(3)), tuple(axis[i] for i in range(3, 6))
    d = axis_distance(a, u, radius, kind, [prm[i] for i in range(PARAMS[kind])], sy.CASADI)
    return RowMap(taylor_function(ca.Function(f"pair_{kind}", [axis, radius, prm], [d]), [0]), chunks=(64, 16))


@cache
def _self_pair_model() -> RowMap:
    """The Taylor model of one capsule–capsule distance (m) from both axes' models (:func:`_segment_models`):
    ``(axis [a, u] (6,), other axis [a', u'] (6,), radius, other radius, slope, radius, lo, hi of each axis)
    -> 5 × (1,)`` (:func:`~qpik.robots.self_pairs.pair_distance_expr`'s kernel), compiled once."""
    axis, other, radii = ca.SX.sym("axis", 6), ca.SX.sym("other", 6), ca.SX.sym("radii", 2)
    a, u = tuple(axis[i] for i in range(3)), tuple(axis[i] for i in range(3, 6))
    d = axis_distance(a, u, radii[0], "capsule", [*(other[i] for i in range(6)), radii[1]], sy.CASADI)
    fn = ca.Function("self_pair", [axis, other, radii[0], radii[1]], [d])
    return RowMap(taylor_function(fn, [0, 1]), chunks=(64, 16))


def bound_function(robot: Robot, objective: Objective, obstacles: ObstacleSet,
                   self_pairs: tuple[Pair, ...] = ()) -> BoundFunction | None:  # fmt: skip
    """The cached :class:`BoundFunction` of the objective's form, the obstacle families and the capsule pairs,
    or None when the objective is not :attr:`~Objective.bounded` or its expression has an operation without a
    Taylor-model rule."""
    if not objective.bounded:
        return None
    key = ("bound function", objective.key(), obstacles.kinds, len(objective.params(robot)), self_pairs)
    return robot.cache.get(key, _bounds, robot, objective, obstacles, self_pairs)


def _bounds(robot: Robot, objective: Objective, obstacles: ObstacleSet,
            self_pairs: tuple[Pair, ...]) -> BoundFunction | None:  # fmt: skip
    try:
        return BoundFunction(robot, objective, obstacles, self_pairs)
    except InputError:
        return None
