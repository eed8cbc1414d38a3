"""Signed distances and witness points between link capsules and obstacles.

A link capsule is a world segment ``x(s) = a + s (b − a)``, ``s ∈ [0, 1]``, with
radius ``r`` (m); a zero-length segment is a sphere. For each (capsule, obstacle)
pair this module returns, all in the world frame:

- ``d``: signed surface-to-surface distance (m), negative when they overlap;
- ``s``: segment parameter of the witness point on the capsule axis;
- ``p_link``: witness point on the capsule surface, ``x(s) − r n``;
- ``p_obs``: witness point on the obstacle surface;
- ``normal``: unit ``n`` pointing from the obstacle toward the capsule, with
  ``p_link − p_obs = d n`` (so ``d = |p_link − p_obs|`` when apart, ``−|…|`` when
  overlapping).

All obstacles are convex, so ``d`` is a convex function of a translation of
the capsule and ``n`` is its gradient (a subgradient where the witness is not
unique, e.g. parallel segments or a capsule axis through a sphere centre):
``d(t + δ) ≥ d(t) + nᵀδ``. One exception: when the capsule *axis* enters a box,
``d`` is the depth of the deepest axis point minus ``r`` and ``n`` that point's
nearest face; ``d`` does not decrease along ``n`` but may grow slower than
``nᵀδ`` (not at all for a segment crossing a slab, whose deepest point slides
along it). A controller keeps ``d ≥ d_s > 0``, far from that case.

Contract with the controller: capsule ``i`` is ``robot.capsules[i]`` (the order
of ``robot.capsule_segments(q)``). For a static obstacle,

    ḋ = nᵀ J_p(p_link) q̇,

where ``J_p(p)`` (3 × n) is the translational Jacobian of the point ``p`` attached
to link ``robot.capsules[i].link``: ``J_p = J_v − [p − o_link]_× J_ω`` built from
``Robot.frames``/the link Jacobian. (``p_link`` and the axis point ``x(s)`` give
the same ``nᵀ J_p`` because they differ by ``−r n`` and ``nᵀ (ω × n) = 0``.)
The velocity-damper row is then ``nᵀ J_p v ≥ −ξ (d − d_s)/(d_i − d_s)``.

The kernels (:mod:`qpik.geometry.segment`) are written once in the scalar
algebra of :mod:`qpik.algebra.symbolic` and run two ways. A list of shapes (or a batch
of configurations) goes through numpy, vectorised over capsules × obstacles of
each kernel family (a sphere is the segment–segment kernel with a point). An
:class:`ObstacleSet` packed once and called with one (C, 2, 3) set of segments
goes through a CasADi function traced from the same kernels and evaluated via
:class:`qpik.native.compiled.Compiled` — the 1 kHz path.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from qpik.algebra.symbolic import CASADI, NUMPY, Ops, Scalar, Vec, matvec, transpose, vadd, vscale, vsub
from qpik.core.errors import InputError
from qpik.core.layout import Layout
from qpik.core.validate import bounded, finite_array
from qpik.geometry.segment import segment_box, segment_capsule, segment_halfspace
from qpik.geometry.shapes import Box, Capsule, HalfSpace, Shape, Sphere
from qpik.native.compiled import Compiled

Kernel = tuple[Scalar, Scalar, Vec, Vec]


def _params(shape: Shape) -> tuple[str, np.ndarray]:
    """The kernel family of a shape and its flat parameter vector (world frame)."""
    if isinstance(shape, Sphere):
        return "sphere", _record("sphere", centre=shape.center, radius=shape.radius)
    if isinstance(shape, Capsule):
        if not np.any(shape.p1 != shape.p0):  # a zero-length capsule is a sphere
            return "sphere", _record("sphere", centre=shape.p0, radius=shape.radius)
        return "capsule", _record("capsule", start=shape.p0, axis=shape.p1 - shape.p0, radius=shape.radius)
    if isinstance(shape, Box):
        return "box", _record("box", centre=shape.center, rotation=shape.rotation, half_extents=shape.half_extents)
    if isinstance(shape, HalfSpace):
        return "halfspace", _record("halfspace", normal=shape.normal, offset=shape.offset)
    raise InputError(f"obstacle: expected a Sphere, Capsule, Box or HalfSpace, got {type(shape).__name__}")


RECORDS = {
    "sphere": Layout(centre=3, radius=()),
    "capsule": Layout(start=3, axis=3, radius=()),
    "box": Layout(centre=3, rotation=(3, 3), half_extents=3),
    "halfspace": Layout(normal=3, offset=()),
}
"""The parameter record of each kernel family (:func:`_params`; world frame, m): a capsule's axis runs from
``start`` to ``start + axis``, a box's ``rotation`` maps box coordinates to the world (row-major), a half-space is
``normal · x <= offset``."""
PARAMS = {kind: record.size for kind, record in RECORDS.items()}
"""Length of the parameter record of each kernel family."""
REFERENCE = {"sphere": "centre", "capsule": "start", "box": "centre", "halfspace": None}
"""The block of each family's record that is a point of the obstacle (what moves it), None for a half-space."""


def set_layout(kinds: Sequence[str]) -> Layout:
    """The packed parameters of obstacles of families ``kinds`` (:attr:`ObstacleSet.params`): block ``o{i}`` is
    obstacle i's record (:data:`RECORDS`)."""
    return Layout(**{f"o{i}": RECORDS[kind] for i, kind in enumerate(kinds)})


SMOOTH = frozenset({"sphere"})
"""Kernel families whose witness point on a link capsule is unique and moves continuously with the
capsule (the closest point of a segment to a point): the distance is C¹ in the configuration. For
the others (a capsule axis parallel to a box face, a half-space or another capsule) the witness can
jump along the capsule from one step to the next; see :class:`qpik.control.limits.obstacle.ObstacleLimit`."""


def _record(kind: str, **parts: object) -> np.ndarray:
    """A new parameter record (:data:`RECORDS`) of family ``kind`` from its blocks by name."""
    return RECORDS[kind].packer()(parts).copy()


def _pair(kind: str, a: Vec, u: Vec, prm: Sequence[Scalar], ops: Ops) -> Kernel:
    """``(s, sd, p, n)`` of the segment ``a + s u`` to one obstacle given by its parameter record (:data:`RECORDS`,
    world frame)."""
    r = RECORDS[kind].split(prm)
    if kind == "sphere":
        return segment_capsule(a, u, r.centre, (0.0, 0.0, 0.0), r.radius, ops)
    if kind == "capsule":
        return segment_capsule(a, u, r.start, r.axis, r.radius, ops)
    if kind == "halfspace":
        return segment_halfspace(a, u, r.normal, r.offset, ops)
    c, R = r.centre, r.rotation
    Rt = transpose(R)
    s, sd, p, n = segment_box(matvec(Rt, vsub(a, c)), matvec(Rt, u), r.half_extents, ops)
    return s, sd, vadd(c, matvec(R, p)), matvec(R, n)


def pair_expr(
    a: Vec, b: Vec, radius: Scalar, kind: str, params: Sequence[Scalar], ops: Ops
) -> tuple[Scalar, Vec, Vec, Vec, Scalar]:
    """``(d, p_link, p_obs, normal, s)`` (fields of :class:`Distances`) of the capsule ``a``–``b``, ``radius``
    to one obstacle of family ``kind`` with parameters ``params`` (:data:`PARAMS`), in :mod:`qpik.algebra.symbolic`.

    Scalars broadcast (the numpy path evaluates all capsules × obstacles of a family at once).
    """
    u = vsub(b, a)
    s, sd, p, n = _pair(kind, a, u, params, ops)
    return sd - radius, vsub(vadd(a, vscale(s, u)), vscale(radius, n)), p, n, s


def axis_distance(a: Vec, u: Vec, radius: Scalar, kind: str, params: Sequence[Scalar], ops: Ops) -> Scalar:
    """The signed distance (m) of the capsule with axis ``a + s u`` (s ∈ [0, 1]) and ``radius`` to one obstacle of
    family ``kind`` (:data:`PARAMS`): :func:`pair_expr`'s ``d`` from the axis's start and direction."""
    return _pair(kind, a, u, params, ops)[1] - radius


def set_expr(
    segments: Sequence[tuple[Vec, Vec]],
    radii: Sequence[Scalar],
    kinds: Sequence[str],
    params: Sequence[Scalar],
    ops: Ops,
) -> list[list[tuple[Scalar, Vec, Vec, Vec, Scalar]]]:
    """:func:`pair_expr` of every capsule (rows) against every obstacle (columns) of a packed set.

    ``params``: the concatenated parameters of the obstacles (:attr:`ObstacleSet.params`), families ``kinds``.
    """
    records = list(set_layout(kinds).split(params).values())
    return [
        [pair_expr(a, b, r, kind, rec, ops) for kind, rec in zip(kinds, records)] for (a, b), r in zip(segments, radii)
    ]


class ObstacleSet:
    """Obstacles packed into parameter arrays, built once and reused every control step.

    Column ``o`` of :class:`Distances` is ``shapes[o]`` (the caller's order).
    """

    def __init__(self, shapes: Sequence[Shape]):
        try:
            self.shapes: tuple[Shape, ...] = tuple(shapes)
        except TypeError:
            raise InputError(f"obstacles: expected a sequence of shapes, got {type(shapes).__name__}") from None
        packed = []
        for i, sh in enumerate(self.shapes):
            try:
                packed.append(_params(sh))
            except InputError as exc:
                raise InputError(f"obstacles[{i}]: {exc}") from None
        names = [sh.name for sh in self.shapes if sh.name]
        twice = sorted({x for x in names if names.count(x) > 1})
        if twice:
            raise InputError(f"obstacles: names must be unique, {twice} given more than once")
        self.kinds: tuple[str, ...] = tuple(k for k, _ in packed)
        self.params: np.ndarray = np.concatenate([p for _, p in packed]) if packed else np.zeros(0)
        """All parameters in shape order (the compiled path's input)."""
        self.groups: dict[str, tuple[np.ndarray, np.ndarray]] = {
            kind: (np.flatnonzero(np.array(self.kinds) == kind), np.array([p for k, p in packed if k == kind]))
            for kind in dict.fromkeys(self.kinds)
        }
        """Per kernel family: (columns, parameters (O_kind, n_params)) for the numpy path."""

    def __len__(self) -> int:
        return len(self.shapes)


PAIR = Layout(d=(), p_link=3, p_obs=3, normal=3, s=())
"""One pair's record in a flat buffer: the fields of :class:`Distances` (:func:`pair_expr`'s order)."""


def pair_record(pair: tuple[Scalar, Vec, Vec, Vec, Scalar]) -> list:
    """The scalars of one :func:`pair_expr` result in :data:`PAIR`'s order."""
    return PAIR.flatten(**dict(zip(PAIR.names, pair)))


@dataclass(frozen=True)
class Distances:
    """Every (capsule, obstacle) pair: C capsules (rows) × O obstacles (columns), world frame.

    Arrays have a leading batch axis ``N`` when the segments were batched.

    Attributes:
        d: (C, O) signed distance, m (negative = overlap).
        p_link: (C, O, 3) witness point on the capsule surface, m.
        p_obs: (C, O, 3) witness point on the obstacle surface, m.
        normal: (C, O, 3) unit normal from the obstacle toward the capsule; ``p_link − p_obs = d n``.
        s: (C, O) segment parameter in [0, 1] of the witness point's axis point ``a + s (b − a)``.
    """

    d: np.ndarray
    p_link: np.ndarray
    p_obs: np.ndarray
    normal: np.ndarray
    s: np.ndarray


@dataclass(frozen=True)
class PairDistance:
    """One capsule–obstacle pair; fields as in :class:`Distances` (``d``, ``s`` floats, points (3,))."""

    d: float
    p_link: np.ndarray
    p_obs: np.ndarray
    normal: np.ndarray
    s: float


def distances(segments: np.ndarray, radii: np.ndarray, obstacles: Sequence[Shape] | ObstacleSet) -> Distances:
    """Signed distances and witness points of every capsule to every obstacle.

    Args:
        segments: (C, 2, 3) capsule axis end points ``a, b`` in the world frame, m
            (e.g. ``robot.capsule_segments(q)``); or a batch (N, C, 2, 3).
        radii: (C,) capsule radii, m, ≥ 0.
        obstacles: shapes, or an :class:`ObstacleSet` packed once. An
            ObstacleSet with unbatched segments takes the compiled fast path.

    Returns:
        :class:`Distances` with C rows and ``len(obstacles)`` columns.
    """
    seg = bounded(finite_array(segments, "segments"), "segments")
    if seg.ndim not in (3, 4) or seg.shape[-2:] != (2, 3):
        raise InputError(f"segments: expected shape (C, 2, 3) or (N, C, 2, 3), got {seg.shape}")
    r = bounded(finite_array(radii, "radii", (seg.shape[-3],)), "radii")
    if np.any(r < 0.0):
        raise InputError("radii: must be >= 0")
    packed = isinstance(obstacles, ObstacleSet)
    obs = obstacles if packed else ObstacleSet(obstacles)
    if packed and seg.ndim == 3 and len(obs):
        out = _compiled(seg.shape[0], obs.kinds)(seg.reshape(-1), r, obs.params)[0]
        return Distances(**PAIR.views(out.reshape(seg.shape[0], len(obs), PAIR.size).copy()))
    return _numpy(seg, r, obs)


def distance(a: np.ndarray, b: np.ndarray, radius: float, shape: Shape) -> PairDistance:
    """One capsule (axis ``a``–``b`` (3,), world, m; ``radius`` m) against one shape; see :func:`distances`."""
    seg = np.stack([finite_array(a, "a", (3,)), finite_array(b, "b", (3,))])[None]
    out = distances(seg, [radius], [shape])
    return PairDistance(
        d=float(out.d[0, 0]),
        p_link=out.p_link[0, 0],
        p_obs=out.p_obs[0, 0],
        normal=out.normal[0, 0],
        s=float(out.s[0, 0]),
    )


def _numpy(seg: np.ndarray, r: np.ndarray, obs: ObstacleSet) -> Distances:
    """The kernels on numpy arrays: scalars of shape (..., C, O_kind), one pass per kernel family."""
    shape = (*seg.shape[:-2], len(obs))
    d, s = np.empty(shape), np.empty(shape)
    p_link, p_obs, normal = np.empty((*shape, 3)), np.empty((*shape, 3)), np.empty((*shape, 3))
    a = tuple(seg[..., None, 0, i] for i in range(3))  # each (..., C, 1)
    b = tuple(seg[..., None, 1, i] for i in range(3))
    rr = r[:, None]
    for kind, (cols, prm) in obs.groups.items():
        dk, lk, pk, nk, sk = pair_expr(a, b, rr, kind, tuple(prm.T), NUMPY)
        d[..., cols], s[..., cols] = dk, sk
        for out, vec in ((p_link, lk), (p_obs, pk), (normal, nk)):
            out[..., cols, :] = np.stack(np.broadcast_arrays(*vec), -1)
    return Distances(d=d, p_link=p_link, p_obs=p_obs, normal=normal, s=s)


@lru_cache(maxsize=32)
def _compiled(n_capsules: int, kinds: tuple[str, ...]) -> Compiled:
    """CasADi function ``(segments (6C,), radii (C,), params) -> (C·O records of PAIR,)``, traced from the
    same kernels; the pairs row-major over (capsule, obstacle), each a :data:`PAIR` record."""
    seg = ca.SX.sym("segments", 6 * n_capsules)
    rad = ca.SX.sym("radii", n_capsules)
    prm = ca.SX.sym("params", sum(PARAMS[k] for k in kinds))
    ends = [
        (tuple(seg[6 * c + i] for i in range(3)), tuple(seg[6 * c + 3 + i] for i in range(3)))
        for c in range(n_capsules)
    ]
    pairs = set_expr(ends, [rad[c] for c in range(n_capsules)], kinds, [prm[i] for i in range(prm.numel())], CASADI)
    out = [x for row in pairs for pair in row for x in pair_record(pair)]
    return Compiled(ca.Function("capsule_distances", [seg, rad, prm], [ca.vertcat(*out)]))
