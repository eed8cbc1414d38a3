"""Obstacle shapes in the world frame, and their construction from problem-file dicts.

The world frame is the robot's base frame (for an arm loaded with ``base="link"``, that link's frame:
:mod:`qpik.robots.loader`).

Every shape is a frozen dataclass whose arrays are validated (finite, right
shape), stored as read-only float64 and given in the world (robot base) frame,
in metres. Shapes are convex, so the distance of a link capsule to a shape is a
convex function of the capsule's position (see :mod:`qpik.geometry.distance`).

Each shape renders as one MJCF ``<geom/>`` in the world frame
(:meth:`Shape.to_mjcf_geom`), so a simulation or a viewer can show it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import InitVar, dataclass
from typing import ClassVar
from xml.sax.saxutils import quoteattr

import numpy as np

from qpik.core import validate
from qpik.core.errors import InputError

OBSTACLE_RGBA = "1 0 0 0.35"
"""Default colour of obstacle geoms: semi-transparent red."""
PLANE_EXTENT = 2.0
"""Half side (m) of the square drawn for a half-space in MJCF (collisions treat it as infinite)."""


def _vec3(x: object, name: str) -> np.ndarray:
    arr = validate.bounded(validate.finite_array(x, name, (3,)).copy(), name)
    arr.flags.writeable = False
    return arr


def _positive(x: object, name: str) -> float:
    val = validate.number(x, name, minimum=None, finite=False)
    if not np.isfinite(val) or val <= 0.0:
        raise InputError(f"{name}: must be finite and > 0, got {val}")
    return float(validate.bounded(np.array(val), name))


def _fmt(values: Sequence[float] | np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))  # shortest exact round trip


class Shape:
    """Common base of obstacle shapes: a name and an MJCF rendering."""

    kind: ClassVar[str]
    name: str | None

    def _geom_attrs(self) -> str:  # pragma: no cover - every subclass overrides
        raise NotImplementedError

    def to_mjcf_geom(self, rgba: str = OBSTACLE_RGBA) -> str:
        """One MJCF ``<geom .../>`` (world frame) for this shape, to place under ``<worldbody>``."""
        name = "" if self.name is None else f"name={quoteattr(self.name)} "
        return f'<geom {name}{self._geom_attrs()} rgba="{rgba}"/>'


@dataclass(frozen=True, eq=False)
class Sphere(Shape):
    """A ball: all points within ``radius`` (m) of ``center`` (3,) (world frame, m)."""

    center: np.ndarray
    radius: float
    name: str | None = None
    kind: ClassVar[str] = "sphere"

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def _geom_attrs(self) -> str:
        return f'type="sphere" pos="{_fmt(self.center)}" size="{self.radius!r}"'


@dataclass(frozen=True, eq=False)
class Capsule(Shape):
    """All points within ``radius`` (m) of the segment ``p0``–``p1`` (3,) (world frame, m).

    A zero-length segment is a sphere.
    """

    p0: np.ndarray
    p1: np.ndarray
    radius: float
    name: str | None = None
    kind: ClassVar[str] = "capsule"

    def __post_init__(self) -> None:
        object.__setattr__(self, "p0", _vec3(self.p0, "p0"))
        object.__setattr__(self, "p1", _vec3(self.p1, "p1"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def _geom_attrs(self) -> str:
        if np.linalg.norm(self.p1 - self.p0) < 1e-9:  # MuJoCo rejects a zero-length fromto
            return f'type="sphere" pos="{_fmt(self.p0)}" size="{self.radius!r}"'
        return f'type="capsule" fromto="{_fmt(self.p0)} {_fmt(self.p1)}" size="{self.radius!r}"'


@dataclass(frozen=True, eq=False)
class Box(Shape):
    """An oriented box: ``{center + rotation @ y : |y_i| <= half_extents_i}``.

    Attributes:
        center: box centre (3,), world frame, m.
        half_extents: half side lengths (3,) along the box axes, m, all > 0.
        rotation: (3, 3) box axes as columns in the world frame (box-to-world
            rotation); must be orthonormal with det +1 within 1e-6 unless the
            constructor gets ``project=True`` (then the nearest rotation is used).
    """

    center: np.ndarray
    half_extents: np.ndarray
    rotation: np.ndarray = None  # type: ignore[assignment]  # identity when omitted
    name: str | None = None
    project: InitVar[bool] = False
    kind: ClassVar[str] = "box"

    def __post_init__(self, project: bool) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        half = _vec3(self.half_extents, "half_extents")
        if np.any(half <= 0.0):
            raise InputError(f"half_extents: must all be > 0, got {half.tolist()}")
        object.__setattr__(self, "half_extents", half)
        R = np.eye(3) if self.rotation is None else validate.finite_array(self.rotation, "rotation", (3, 3))
        T = np.eye(4)
        T[:3, :3] = R
        R = validate.pose(T, "rotation", project=project)[0][:3, :3].copy()
        R.flags.writeable = False
        object.__setattr__(self, "rotation", R)

    def _geom_attrs(self) -> str:
        xyaxes = _fmt(self.rotation[:, :2].T)
        return f'type="box" pos="{_fmt(self.center)}" size="{_fmt(self.half_extents)}" xyaxes="{xyaxes}"'


@dataclass(frozen=True, eq=False)
class HalfSpace(Shape):
    """The solid ``{x : normal · x <= offset}``; the free side is ``normal · x >= offset``.

    The set is the one this inequality describes with ``normal`` as given (it must
    not be zero). It is stored with a unit normal ``n = normal / |normal|`` and
    ``offset / |normal|``, the plane's signed distance from the origin along ``n``
    (metres): ``normal = (0, 0, 2), offset = 0.2`` is the solid ``z <= 0.1``.
    A table top at height h is ``HalfSpace((0, 0, 1), h)``.
    """

    normal: np.ndarray
    offset: float
    name: str | None = None
    kind: ClassVar[str] = "halfspace"

    def __post_init__(self) -> None:
        n = validate.bounded(validate.finite_array(self.normal, "normal", (3,)), "normal")
        norm = float(np.linalg.norm(n))
        if not norm > 1e-12:
            raise InputError("normal: must not be the zero vector")
        object.__setattr__(self, "normal", _vec3(n / norm, "normal"))
        offset = validate.bounded(validate.finite_array(self.offset, "offset", ()), "offset")
        object.__setattr__(self, "offset", float(offset) / norm)

    def _geom_attrs(self) -> str:
        # MuJoCo collides a plane as the half-space below it; size only sets how it is drawn.
        pos = _fmt(self.normal * self.offset)
        return f'type="plane" pos="{pos}" zaxis="{_fmt(self.normal)}" size="{PLANE_EXTENT} {PLANE_EXTENT} 0.01"'


SHAPES: dict[str, type[Shape]] = {cls.kind: cls for cls in (Sphere, Capsule, Box, HalfSpace)}
_FIELDS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {  # (required, optional) keys besides type/name
    "sphere": (("center", "radius"), ()),
    "capsule": (("p0", "p1", "radius"), ()),
    "box": (("center", "half_extents"), ("rotation", "project")),
    "halfspace": (("normal", "offset"), ()),
}


def shape_from_spec(spec: Mapping[str, object]) -> Shape:
    """Build a shape from a problem-file dict.

    Accepted forms (``name`` optional everywhere; lengths in m, world frame)::

        {"type": "sphere", "center": [x, y, z], "radius": r}
        {"type": "capsule", "p0": [...], "p1": [...], "radius": r}
        {"type": "box", "center": [...], "half_extents": [...], "rotation": [[row], [row], [row]],
         "project": false}                       # rotation and project optional
        {"type": "halfspace", "normal": [...], "offset": h}   # the solid normal·x <= offset

    Unknown types, missing keys and unknown keys raise :class:`InputError`. This is the
    one parser of obstacle descriptions: problem files (:func:`qpik.problems.load`) use it too.
    """
    if not isinstance(spec, Mapping):
        raise InputError(f"obstacle: expected a table/dict, got {type(spec).__name__}")
    kind = spec.get("type")
    if not isinstance(kind, str) or kind not in SHAPES:
        raise InputError(f"obstacle type: expected one of {sorted(SHAPES)}, got {kind!r}")
    required, optional = _FIELDS[kind]
    missing = [k for k in required if k not in spec]
    if missing:
        raise InputError(f"{kind} obstacle: missing key(s) {missing}")
    unknown = sorted(set(spec) - set(required) - set(optional) - {"type", "name"})
    if unknown:
        raise InputError(f"{kind} obstacle: unknown key(s) {unknown}")
    name = spec.get("name")
    if name is not None and not isinstance(name, str):
        raise InputError(f"{kind} obstacle name: expected a string, got {name!r}")
    kwargs = {k: spec[k] for k in (*required, *optional) if k in spec}
    return SHAPES[kind](name=name, **kwargs)


def obstacles_from_specs(specs: Sequence[Mapping[str, object]]) -> tuple[Shape, ...]:
    """Build every shape of a problem file's obstacle list (see :func:`shape_from_spec`).

    Errors name the position of the offending entry, e.g. ``obstacles[2]: ...``.
    """
    if isinstance(specs, str | Mapping) or not isinstance(specs, Sequence):
        raise InputError(f"obstacles: expected a list of tables/dicts, got {type(specs).__name__}")
    out = []
    for i, spec in enumerate(specs):
        try:
            out.append(shape_from_spec(spec))
        except InputError as exc:
            raise type(exc)(f"obstacles[{i}]: {exc}") from None
    return tuple(out)
