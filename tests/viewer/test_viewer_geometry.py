"""qpik.viewer.geometry: the meshes the viewer draws lie where MuJoCo and qpik.geometry put the geoms and shapes.

Every part's vertices, placed by its body's pose, are checked against MuJoCo's own placement of the geom
(``geom_xpos``/``geom_xmat`` of a separate ``MjData``) and against the geom's surface equation; the link
capsules against :meth:`qpik.Robot.capsule_segments`; the obstacles against :func:`qpik.geometry.distance`.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import model_robot, random_q

pytest.importorskip("viser", reason="viser is not installed (pip install 'qpik[view]')")

import qpik
from qpik.geometry import Box, Capsule, HalfSpace, Sphere, distance
from qpik.viewer.geometry import ArmGeometry, capsule_part, shape_part

G = mujoco.mjtGeom


def _world_parts(geometry: ArmGeometry, q: np.ndarray):
    """(geom id, world vertices (V, 3)) of every arm part at q, placed by the body poses of ArmGeometry.poses."""
    pos, quat = geometry.poses(q)
    out = []
    for body, p, w in zip(geometry.bodies, pos, quat):
        R = np.empty(9)
        mujoco.mju_quat2Mat(R, w)
        for part in body.parts:
            out.append((part.geom, part.vertices.astype(float) @ R.reshape(3, 3).T + p))
    return out


def _mujoco_geoms(robot: qpik.Robot, q: np.ndarray) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """MuJoCo's own kinematics of the robot's model at q (a fresh MjData, the arm's joints set by name)."""
    model = robot.mj_model()
    data = mujoco.MjData(model)
    for name, value in zip(robot.joint_names, q):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_kinematics(model, data)
    return model, data


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7", "panda"])
def test_primitive_parts_lie_on_their_geoms_surface(name):
    """Catalog twins (capsules, cylinders, boxes, spheres): each vertex, in the geom's frame as MuJoCo places it,
    satisfies the surface equation of its type and size."""
    robot = qpik.load_robot(name)
    geometry = ArmGeometry(robot)
    for q in random_q(robot, 3, seed=7):
        model, data = _mujoco_geoms(robot, q)
        parts = _world_parts(geometry, q)
        assert {g for g, _ in parts} == {g for g in range(model.ngeom) if model.geom_type[g] != G.mjGEOM_PLANE}
        for g, v in parts:
            local = (v - data.geom_xpos[g]) @ data.geom_xmat[g].reshape(3, 3)  # into the geom's frame
            r, h = model.geom_size[g, 0], model.geom_size[g, 1]
            kind = model.geom_type[g]
            if kind == G.mjGEOM_CAPSULE:  # distance to the axis segment z in [-h, h] is the radius
                axis = np.clip(local[:, 2], -h, h)
                np.testing.assert_allclose(np.linalg.norm(local - np.outer(axis, [0, 0, 1]), axis=1), r, atol=1e-6)
            elif kind == G.mjGEOM_CYLINDER:  # every vertex on a cap, inside the rim
                np.testing.assert_allclose(np.abs(local[:, 2]), h, atol=1e-6)
                assert np.all(np.linalg.norm(local[:, :2], axis=1) <= r + 1e-6)
            elif kind == G.mjGEOM_SPHERE:
                np.testing.assert_allclose(np.linalg.norm(local, axis=1), r, atol=1e-6)
            elif kind == G.mjGEOM_BOX:
                half = np.broadcast_to(model.geom_size[g], local.shape)
                np.testing.assert_allclose(np.abs(local), half, atol=1e-6)
            else:
                pytest.fail(f"unexpected geom type {kind} in the twin of {name}")


def test_mesh_parts_are_the_model_meshes_where_mujoco_puts_them():
    """A model with meshes (robosuite's iiwa): the drawn vertices are MuJoCo's mesh vertices at the geom's pose."""
    robot = model_robot("robosuite_iiwa")
    geometry = ArmGeometry(robot)
    meshes = 0
    for q in random_q(robot, 2, seed=3):
        model, data = _mujoco_geoms(robot, q)
        for g, v in _world_parts(geometry, q):
            if model.geom_type[g] != G.mjGEOM_MESH:
                continue
            m = model.geom_dataid[g]
            vert = model.mesh_vert[model.mesh_vertadr[m] : model.mesh_vertadr[m] + model.mesh_vertnum[m]]
            want = vert @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
            np.testing.assert_allclose(v, want, atol=1e-5)  # float32 vertices
            meshes += 1
    assert meshes > 0


def test_link_capsule_parts_surround_the_capsule_segments():
    """Every vertex of a link capsule, placed in its link frame, is one radius from qpik's capsule segment."""
    robot = qpik.load_robot("iiwa14")
    for q in random_q(robot, 3, seed=11):
        F, seg = robot.frames(q), robot.capsule_segments(q)
        for c, cap in enumerate(robot.capsules):
            part, local = capsule_part(cap, (0, 0, 255), 0.3)
            T = F[cap.link] @ local
            v = part.vertices.astype(float) @ T[:3, :3].T + T[:3, 3]
            a, b = seg[c]
            s = np.clip((v - a) @ (b - a) / max((b - a) @ (b - a), 1e-300), 0.0, 1.0)
            np.testing.assert_allclose(np.linalg.norm(v - (a + np.outer(s, b - a)), axis=1), cap.radius, atol=1e-6)


@pytest.mark.parametrize(
    "shape",
    [
        Sphere((0.3, -0.2, 0.5), 0.07),
        Capsule((0.1, 0.2, 0.3), (0.4, -0.1, 0.6), 0.05),
        Capsule((0.1, 0.2, 0.3), (0.1, 0.2, 0.3), 0.05),
        Box((0.4, 0.5, 0.1), (0.2, 0.1, 0.05), [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        HalfSpace((0.0, 0.3, 1.0), 0.12),
    ],
    ids=["sphere", "capsule", "point capsule", "box", "halfspace"],
)
def test_obstacle_parts_lie_on_the_shapes_surface(shape):
    """Every vertex of an obstacle's mesh, placed by its pose, is at distance 0 from the shape (qpik.geometry)."""
    part, T = shape_part(shape, (255, 0, 0), 0.4)
    v = part.vertices.astype(float) @ T[:3, :3].T + T[:3, 3]
    d = [distance(p, p, 0.0, shape).d for p in v]
    np.testing.assert_allclose(d, 0.0, atol=1e-6)
