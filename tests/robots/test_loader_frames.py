"""Frames of loaded arms: with ``base=`` every pose is relative to the base link, as in pinocchio, KDL and MoveIt.

Checked against pinocchio on the same URDF (TALOS and TIAGo Pro of example-robot-data), with the
joints that are not arm joints at their reference (pinocchio's neutral configuration, 0 for these files).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MODEL_DIR, packaged, random_q

import qpik
from qpik.robots.model_files import MeshOptions
from qpik.robots.mujoco_backend import MjKinematics

pin = pytest.importorskip("pinocchio")

CASES = {  # key: (packaged model, base link, tip link)
    "talos": ("erd/talos", "torso_2_link", "arm_left_7_link"),
    "tiago_pro": ("erd/tiago_pro", "torso_lift_link", "arm_left_tool_link"),
}
_robots: dict[str, tuple[qpik.Robot, object]] = {}


def arm(key: str) -> tuple[qpik.Robot, object, str, str]:
    """The loaded arm, pinocchio's model of the same file, its base and tip link (loaded once)."""
    model, base, tip = CASES[key]
    if key not in _robots:
        path = packaged(model)
        _robots[key] = (
            qpik.load_robot(path, base=base, tip=tip, meshes=MeshOptions(collision_only=True)),
            pin.buildModelFromUrdf(str(path)),
        )
    robot, pmodel = _robots[key]
    return robot, pmodel, base, tip


def pinocchio_poses(robot: qpik.Robot, pmodel, frame: str, Q: np.ndarray) -> np.ndarray:
    """World poses (N, 4, 4) of ``frame`` by pinocchio, the arm's joints at Q, the others neutral."""
    data = pmodel.createData()
    fid = pmodel.getFrameId(frame)
    out = []
    for q in Q:
        full = pin.neutral(pmodel)
        for name, x in zip(robot.joint_names, q):
            full[pmodel.joints[pmodel.getJointId(name)].idx_q] = x
        pin.framesForwardKinematics(pmodel, data, full)
        out.append(data.oMf[fid].homogeneous.copy())
    return np.array(out)


@pytest.mark.parametrize("key", list(CASES))
def test_base_frame_fk_equals_pinocchio(key):
    """FK relative to the base link equals pinocchio's base⁻¹·tip to 1e-12; the placement is pinocchio's base."""
    robot, pmodel, base, tip = arm(key)
    Q = random_q(robot, 200, 1)
    world_base = pinocchio_poses(robot, pmodel, base, Q[:1])[0]
    world_tip = pinocchio_poses(robot, pmodel, tip, Q)
    np.testing.assert_allclose(robot.fk(Q), np.linalg.inv(world_base) @ world_tip, atol=1e-12, rtol=0)
    np.testing.assert_allclose(robot.model.placement, world_base, atol=1e-12, rtol=0)
    np.testing.assert_allclose(robot.model.placement @ robot.fk(Q), world_tip, atol=1e-12, rtol=0)
    assert np.linalg.norm(world_base[:3, 3]) > 0.05  # the test can fail: the base is away from the world origin


@pytest.mark.parametrize("key", list(CASES))
def test_base_frame_jacobian_equals_pinocchio(key):
    """The geometric Jacobian [v; ω] of the tip, base frame, against pinocchio's (world-aligned, rotated)."""
    robot, pmodel, _, tip = arm(key)
    data = pmodel.createData()
    R = robot.model.placement[:3, :3]
    for q in random_q(robot, 20, 2):
        full = pin.neutral(pmodel)
        cols = [pmodel.joints[pmodel.getJointId(name)] for name in robot.joint_names]
        for j, x in zip(cols, q):
            full[j.idx_q] = x
        J = pin.computeFrameJacobian(pmodel, data, full, pmodel.getFrameId(tip), pin.LOCAL_WORLD_ALIGNED)
        J = J[:, [j.idx_v for j in cols]]
        np.testing.assert_allclose(robot.jacobian(q), np.vstack((R.T @ J[:3], R.T @ J[3:])), atol=1e-12, rtol=0)


@pytest.mark.parametrize("key", list(CASES))
def test_mujoco_model_world_is_the_base_frame(key):
    """The robot's MuJoCo model (the one the sim runs) is moved: its end-effector site equals ``robot.fk``."""
    robot, *_ = arm(key)
    kin = MjKinematics.from_robot(robot)
    Q = random_q(robot, 30, 3)
    np.testing.assert_allclose(kin.fk(Q), robot.fk(Q), atol=1e-10, rtol=0)
    np.testing.assert_allclose(kin.jacobian(Q), robot.jacobian(Q), atol=1e-10, rtol=0)


def test_solve_ik_reaches_base_frame_poses():
    """Poses given in the base frame (what a pinocchio or MoveIt user has) are reached."""
    robot, pmodel, base, tip = arm("tiago_pro")
    Q = random_q(robot, 8, 4, margin=0.2)
    targets = np.linalg.inv(pinocchio_poses(robot, pmodel, base, Q[:1])[0]) @ pinocchio_poses(robot, pmodel, tip, Q)
    for T in targets:
        q = qpik.solve_ik(robot, T, robot.q_home)
        np.testing.assert_allclose(robot.fk(q), T, atol=1e-6)


def test_base_below_a_joint_and_no_base():
    """An MJCF base body below the first joint: poses relative to it (that joint at its reference); without base
    the placement is the identity and poses are the world's."""
    path = MODEL_DIR / "gymnasium_pusher/pusher_v5.xml"
    plain = qpik.load_robot(path, tip="tips_arm")
    np.testing.assert_array_equal(plain.model.placement, np.eye(4))
    on_link = qpik.load_robot(path, base="r_shoulder_pan_link", tip="tips_arm")
    assert on_link.dof == plain.dof - 1
    Q = random_q(on_link, 20, 5)
    full = np.insert(Q, 0, 0.0, axis=1)  # pusher's qpos0 is 0
    np.testing.assert_allclose(on_link.model.placement @ on_link.fk(Q), plain.fk(full), atol=1e-12)
    np.testing.assert_allclose(on_link.model.placement[:3, 3], (0.0, -0.6, 0.0), atol=1e-12)
    np.testing.assert_allclose(MjKinematics.from_robot(on_link).fk(Q), on_link.fk(Q), atol=1e-10)


_FRAMED = """<mujoco model="framed">
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <light pos="0 0 3"/>
    <frame pos="0.3 0.1 0.2" euler="0 0 30">
      <body name="stand" pos="0 0 0.1" euler="10 0 0">
        <geom type="box" size="0.1 0.1 0.1"/>
        <site name="mount" pos="0.01 0.02 0.2" euler="0 5 15"/>
        <body name="l1" pos="0 0 0.2"><joint name="a" axis="0 0 1" range="-2 2"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
          <body name="l2" pos="0.3 0 0"><joint name="b" axis="0 1 0" range="-2 2"/>
            <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
            <site name="tip" pos="0.3 0 0"/>
          </body>
        </body>
      </body>
    </frame>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("base", ["stand", "mount"])
def test_base_body_or_site_under_a_world_frame(tmp_path, base):
    """A base body (or a site on it) placed through an MJCF ``<frame>``: FK relative to it, the placement its world
    pose (MuJoCo's), and the moved model agrees."""
    import mujoco

    path = tmp_path / "framed.xml"
    path.write_text(_FRAMED)
    world = qpik.load_robot(path, tip="tip")
    robot = qpik.load_robot(path, base=base, tip="tip")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    kind = mujoco.mjtObj.mjOBJ_SITE if base == "mount" else mujoco.mjtObj.mjOBJ_BODY
    i = mujoco.mj_name2id(model, kind, base)
    xmat, xpos = (data.site_xmat, data.site_xpos) if base == "mount" else (data.xmat, data.xpos)
    placement = np.eye(4)
    placement[:3, :3], placement[:3, 3] = xmat[i].reshape(3, 3), xpos[i]
    np.testing.assert_allclose(robot.model.placement, placement, atol=1e-12)
    Q = random_q(robot, 30, 6)
    np.testing.assert_allclose(placement @ robot.fk(Q), world.fk(Q), atol=1e-12)
    np.testing.assert_allclose(MjKinematics.from_robot(robot).fk(Q), robot.fk(Q), atol=1e-10)
    np.testing.assert_allclose(robot.capsule_segments(Q), np.einsum("ij,...j->...i", np.linalg.inv(placement)[:3, :3],
                               world.capsule_segments(Q)) + np.linalg.inv(placement)[:3, 3], atol=1e-12)  # fmt: skip
