"""Triangle meshes of what the viewer draws: the arm's geoms, its link capsules and the obstacles.

The arm is drawn from its MuJoCo model (:meth:`qpik.Robot.mj_model`: the twin of a catalog arm, the
model file of a loaded one): every geom except planes and the capsules qpik adds to a loaded model
(those are drawn from :attr:`qpik.Robot.capsules`, as a layer of their own). A mesh geom is its
``mesh_vert``/``mesh_face``; spheres, capsules, cylinders, ellipsoids and boxes are tessellated by
:mod:`trimesh.creation`. Every part is stored in the frame of its MuJoCo body, so that one pose per
body places it: ``world = (xpos, xquat) ∘ part`` after ``mj_kinematics``.

Units: metres. Quaternions are (w, x, y, z), MuJoCo's order and viser's.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh

from qpik.geometry.shapes import PLANE_EXTENT, Box, Capsule, HalfSpace, Shape, Sphere
from qpik.robots.mujoco_backend import MjKinematics
from qpik.robots.robot import LinkCapsule, Robot

CAPSULE_GEOM = "qpik_capsule"
"""Name prefix of the capsules :meth:`qpik.robots.model_source.ModelSource.spec_with` adds to a loaded model."""
SUBDIVISIONS = 2  # icosphere subdivisions of spheres and ellipsoids (162 vertices)
SECTIONS = 20  # segments around a capsule or cylinder


@dataclass(frozen=True)
class Part:
    """One drawable piece: ``vertices`` (V, 3) float32 in its frame, ``faces`` (F, 3) uint32, ``rgb`` 0-255,
    ``opacity``, and the MuJoCo geom it is drawn from (-1: none)."""

    vertices: np.ndarray
    faces: np.ndarray
    rgb: tuple[int, int, int]
    opacity: float = 1.0
    geom: int = -1


@dataclass(frozen=True)
class BodyParts:
    """The parts rigidly attached to MuJoCo body ``body``, in its frame; ``moving``: some arm joint moves it."""

    body: int
    name: str
    parts: tuple[Part, ...]
    moving: bool


class ArmGeometry:
    """The arm's geoms grouped by body, and the body poses of a configuration.

    Args:
        robot: any arm :func:`qpik.load_robot` takes.

    Attributes:
        bodies: the :class:`BodyParts` of every body that has a drawable geom.
        kin: the :class:`~qpik.robots.mujoco_backend.MjKinematics` of the model (its joints the arm's).
    """

    def __init__(self, robot: Robot):
        self.kin = MjKinematics.from_robot(robot)
        model = self.kin.model
        moving = model.body_weldid != 0
        by_body: dict[int, list[Part]] = {}
        for g in range(model.ngeom):
            if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE or model.geom(g).name.startswith(CAPSULE_GEOM):
                continue
            part = _geom_part(model, g)
            if part is not None:
                by_body.setdefault(int(model.geom_bodyid[g]), []).append(part)
        self.bodies: tuple[BodyParts, ...] = tuple(
            BodyParts(b, model.body(b).name or f"body{b}", tuple(parts), bool(moving[b]))
            for b, parts in sorted(by_body.items())
        )

    def poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World positions (K, 3) and quaternions (K, 4) of :attr:`bodies` at configuration q (n,), rad."""
        self.kin.update(q)
        ids = [b.body for b in self.bodies]
        return self.kin.data.xpos[ids].copy(), self.kin.data.xquat[ids].copy()


def _geom_part(model: mujoco.MjModel, g: int) -> Part | None:
    """Geom ``g`` as a mesh in its body's frame (None for a type the viewer does not draw)."""
    kind, size = int(model.geom_type[g]), model.geom_size[g]
    G = mujoco.mjtGeom
    if kind == G.mjGEOM_MESH:
        m = int(model.geom_dataid[g])
        v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
        f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
        vertices, faces = model.mesh_vert[v0 : v0 + nv], model.mesh_face[f0 : f0 + nf]
    elif kind in (G.mjGEOM_SPHERE, G.mjGEOM_ELLIPSOID):
        ball = trimesh.creation.icosphere(subdivisions=SUBDIVISIONS, radius=1.0)
        scale = size[0] if kind == G.mjGEOM_SPHERE else size
        vertices, faces = ball.vertices * scale, ball.faces
    elif kind == G.mjGEOM_CAPSULE:
        vertices, faces = _capsule(2.0 * size[1], size[0])
    elif kind == G.mjGEOM_CYLINDER:
        cyl = trimesh.creation.cylinder(radius=size[0], height=2.0 * size[1], sections=SECTIONS)
        vertices, faces = cyl.vertices, cyl.faces
    elif kind == G.mjGEOM_BOX:
        box = trimesh.creation.box(extents=2.0 * size)
        vertices, faces = box.vertices, box.faces
    else:
        return None
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, model.geom_quat[g])
    body_frame = np.asarray(vertices) @ R.reshape(3, 3).T + model.geom_pos[g]
    m = int(model.geom_matid[g])
    rgba = model.mat_rgba[m] if m >= 0 else model.geom_rgba[g]
    return Part(_f32(body_frame), _u32(faces), _rgb(rgba[:3]), float(rgba[3]), g)


def _capsule(length: float, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """A capsule mesh along z, centred at the origin: axis length ``length`` (m, ≥ 0), ``radius`` (m)."""
    if length < 1e-9:
        ball = trimesh.creation.icosphere(subdivisions=SUBDIVISIONS, radius=radius)
        return ball.vertices, ball.faces
    mesh = trimesh.creation.capsule(height=length, radius=radius, count=[SECTIONS, SECTIONS])
    return mesh.vertices, mesh.faces


def segment_frame(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """A pose (4, 4) at the midpoint of ``p0``–``p1`` (3,) with its z axis along the segment (any z for a point)."""
    T = np.eye(4)
    T[:3, 3] = 0.5 * (p0 + p1)
    d = p1 - p0
    length = float(np.linalg.norm(d))
    if length > 1e-12:
        quat = np.empty(4)
        mujoco.mju_quatZ2Vec(quat, d / length)
        R = np.empty(9)
        mujoco.mju_quat2Mat(R, quat)
        T[:3, :3] = R.reshape(3, 3)
    return T


def capsule_part(capsule: LinkCapsule, rgb: tuple[int, int, int], opacity: float) -> tuple[Part, np.ndarray]:
    """A link capsule as a part in its own frame, and that frame (4, 4) in the link frame."""
    vertices, faces = _capsule(float(np.linalg.norm(capsule.p1 - capsule.p0)), capsule.radius)
    return Part(_f32(vertices), _u32(faces), rgb, opacity), segment_frame(capsule.p0, capsule.p1)


def shape_part(shape: Shape, rgb: tuple[int, int, int], opacity: float) -> tuple[Part, np.ndarray]:
    """An obstacle as a part in its own frame, and that frame's world pose (4, 4).

    A :class:`~qpik.geometry.HalfSpace` is drawn as its boundary plane, a square of half side
    :data:`~qpik.geometry.shapes.PLANE_EXTENT` around the point of the plane nearest the origin.
    """
    T = np.eye(4)
    if isinstance(shape, Sphere):
        ball = trimesh.creation.icosphere(subdivisions=3, radius=shape.radius)
        vertices, faces = ball.vertices, ball.faces
        T[:3, 3] = shape.center
    elif isinstance(shape, Capsule):
        vertices, faces = _capsule(float(np.linalg.norm(shape.p1 - shape.p0)), shape.radius)
        T = segment_frame(shape.p0, shape.p1)
    elif isinstance(shape, Box):
        box = trimesh.creation.box(extents=2.0 * shape.half_extents)
        vertices, faces = box.vertices, box.faces
        T[:3, :3], T[:3, 3] = shape.rotation, shape.center
    elif isinstance(shape, HalfSpace):
        e = PLANE_EXTENT
        vertices = np.array([[-e, -e, 0.0], [e, -e, 0.0], [e, e, 0.0], [-e, e, 0.0]])
        faces = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]])  # both sides
        T = segment_frame(np.zeros(3), shape.normal)
        T[:3, 3] = shape.normal * shape.offset
    else:  # pragma: no cover - every Shape of qpik.geometry is handled above
        raise TypeError(f"no mesh for {type(shape).__name__}")
    return Part(_f32(vertices), _u32(faces), rgb, opacity), T


def wxyz(R: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a rotation matrix (3, 3)."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(R, dtype=float).ravel())
    return quat


def rotation(quat: np.ndarray) -> np.ndarray:
    """The rotation matrix (3, 3) of a quaternion (w, x, y, z) (normalised first)."""
    q = np.asarray(quat, dtype=float)
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, q / np.linalg.norm(q))
    return R.reshape(3, 3)


def _f32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _u32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.uint32)


def _rgb(c: np.ndarray) -> tuple[int, int, int]:
    r, g, b = (round(255 * float(min(max(x, 0.0), 1.0))) for x in c)
    return r, g, b
