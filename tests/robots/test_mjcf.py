"""The MJCF twin: MuJoCo's own kinematics of the twin against the DH chain."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import SEEDS, mujoco_poses, random_robot
from hypothesis import given, settings

from qpik.robots.catalog import CATALOG
from qpik.robots.loader import load_robot
from qpik.robots.robot import Robot

ARMS = sorted(CATALOG)
BATCH = 300


def _robots(seed: int) -> list[Robot]:
    return [load_robot(name) for name in ARMS] + [random_robot(seed, c) for c in ("standard", "modified")]


@settings(max_examples=4, deadline=None)
@given(seed=SEEDS)
def test_ee_site_equals_fk(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for robot in _robots(seed):
        qs = rng.uniform(-np.pi, np.pi, (BATCH, robot.dof))
        got = mujoco_poses(robot, qs)
        np.testing.assert_allclose(got, robot.fk(qs), atol=1e-9, err_msg=robot.name)


@settings(max_examples=3, deadline=None)
@given(seed=SEEDS)
def test_capsule_geoms_equal_capsule_segments(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for robot in _robots(seed):
        model = robot.mj_model()
        data = mujoco.MjData(model)
        qs = rng.uniform(-np.pi, np.pi, (50, robot.dof))
        want = robot.capsule_segments(qs)  # (N, C, 2, 3)
        ids = [model.geom(f"link{c.link}_capsule").id for c in robot.capsules]
        for q, segs in zip(qs, want):
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            for g, cap, (p0, p1) in zip(ids, robot.capsules, segs):
                centre, z = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)[:, 2]
                half = model.geom_size[g, 1] if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0
                np.testing.assert_allclose(centre - half * z, p0, atol=1e-9)
                np.testing.assert_allclose(centre + half * z, p1, atol=1e-9)
                assert model.geom_size[g, 0] == pytest.approx(cap.radius)


@pytest.mark.parametrize("name", ARMS)
def test_joints_bodies_and_limits(name: str) -> None:
    robot = load_robot(name)
    model = robot.mj_model()
    assert model.nq == model.nv == robot.dof
    for k in range(1, robot.dof + 1):
        joint = model.joint(f"joint{k}")
        assert joint.type[0] == mujoco.mjtJoint.mjJNT_HINGE
        assert joint.limited[0] == 1
        np.testing.assert_array_equal(joint.range, [robot.q_min[k - 1], robot.q_max[k - 1]])
        assert model.body(f"link{k}").id == joint.bodyid[0]
    assert np.all(model.body_mass[1:] > 0)


@pytest.mark.parametrize("name", ARMS)
def test_collision_geoms_are_the_capsules(name: str) -> None:
    """Capsules collide (group 0); every other geom is visual only (group 2, no contacts)."""
    robot = load_robot(name)
    model = robot.mj_model()
    capsule_names = {f"link{c.link}_capsule" for c in robot.capsules}
    seen = set()
    for g in range(model.ngeom):
        geom = model.geom(g)
        if geom.name in capsule_names:
            seen.add(geom.name)
            assert geom.group[0] == 0 and geom.contype[0] != 0
        else:
            assert geom.group[0] == 2 and geom.contype[0] == 0 and geom.conaffinity[0] == 0, geom.name
    assert seen == capsule_names
    assert {model.geom(g).name for g in range(model.ngeom)} >= {"floor", "base"}


def test_extra_worldbody_is_inserted() -> None:
    from qpik.robots.mjcf import to_mjcf

    xml = to_mjcf(load_robot("iiwa14"), ['<geom name="obstacle" type="sphere" size="0.1" pos="0.5 0 0.5"/>'])
    model = mujoco.MjModel.from_xml_string(xml)
    np.testing.assert_array_equal(model.geom("obstacle").pos, [0.5, 0, 0.5])
    assert model.geom("obstacle").bodyid[0] == 0
