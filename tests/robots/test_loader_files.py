"""Real ROS files: COLLADA meshes, inertias the kinematics does not need, mimic joints, limits, model names."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import MODEL_DIR, fd, fd_geometric_jacobian, packaged, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.core.errors import InputError
from qpik.robots.collada import as_stl
from qpik.robots.limits import CONTINUOUS_LIMIT, DEFAULT_VELOCITY
from qpik.robots.mujoco_backend import MjKinematics
from qpik.sim import SimOptions, simulate

MIMIC = MODEL_DIR / "mimic_arm/mimic_arm.urdf"
COLLADA_ARMS = {  # key: (packaged model, options)
    "baxter": ("erd/baxter", {"base": "torso", "tip": "left_hand_link"}),
    "tiago": ("erd/tiago", {"base": "torso_lift_link", "tip": "arm_tool_link"}),
}


# ---- COLLADA ----------------------------------------------------------------


@pytest.mark.parametrize("key", list(COLLADA_ARMS))
def test_collada_arms_load_and_run_the_controller(key):
    """Baxter and TIAGo (COLLADA meshes, visual ones too) load, and the controller reaches a pose in MuJoCo."""
    model, options = COLLADA_ARMS[key]
    robot = qpik.load_robot(packaged(model), **options)
    assert robot.dof == 7
    spec = robot.model.spec()
    files = [Path(m.file) for m in spec.meshes]
    assert any(f.parent.name == "meshes" and f.suffix == ".stl" and len(f.stem) == 40 for f in files)
    assert not any(f.suffix.lower() == ".dae" for f in files)
    mid, span = (robot.q_min + robot.q_max) / 2, robot.q_max - robot.q_min
    q0 = mid + 0.15 * span * np.random.default_rng(0).uniform(-1, 1, robot.dof)
    target = robot.fk(q0 + 0.15)
    # the loading is under test, not the self pairs of the fitted capsules (their default list is #24's open work)
    options = qpik.ControllerOptions(self_collision=False)
    ctrl = qpik.Controller.for_robot(robot, target=target, dt=0.01, options=options)
    log = simulate(robot, ctrl, q0, 2.0, 0.01, target=target, options=SimOptions(record_every=10))
    assert np.linalg.norm(log.ee[0, :3, 3] - target[:3, 3]) > 0.1
    assert np.linalg.norm(log.ee[-1, :3, 3] - target[:3, 3]) < 1e-3  # the posture task's pull stays ~1e-4
    np.testing.assert_allclose(log.ee, robot.fk(log.q), atol=1e-10)  # MuJoCo's site, base frame, equals FK
    assert np.all(robot.within_limits(log.q))


def _erd(path: str) -> Path:
    return packaged("erd/baxter").parents[2] / path


@pytest.mark.parametrize(
    "mesh",
    [
        "baxter_description/meshes/torso/base_link_collision.DAE",
        "baxter_description/meshes/lower_shoulder/S1.DAE",
        "tiago_description/meshes/arm/arm_1_collision.dae",
    ],
)
def test_collada_conversion_matches_coal(mesh):
    """The cached STL has the vertices coal's (assimp) loader reads from the same COLLADA file (float32 STL)."""
    coal = pytest.importorskip("coal")
    import trimesh

    path = _erd(mesh)
    if not path.is_file():
        pytest.skip(f"{mesh} is not in this example-robot-data")
    stl = as_stl(path)
    assert as_stl(path) == stl and stl.stat().st_mtime_ns == as_stl(path).stat().st_mtime_ns  # cached
    ours = np.unique(np.round(trimesh.load(stl).vertices, 6), axis=0)
    theirs = np.unique(np.round(np.asarray(coal.MeshLoader().load(str(path), np.ones(3)).vertices()), 6), axis=0)
    assert len(ours) > 20
    np.testing.assert_allclose(ours.min(0), theirs.min(0), atol=2e-6)
    np.testing.assert_allclose(ours.max(0), theirs.max(0), atol=2e-6)
    assert abs(len(ours) - len(theirs)) <= 0.01 * len(theirs)


def test_collada_unit_is_applied(tmp_path):
    """``<unit meter="0.01">`` (centimetres) scales the mesh to metres, as RViz reads it."""
    import trimesh

    source = _erd("baxter_description/meshes/lower_shoulder/S1.DAE")
    text = source.read_text()
    assert 'meter="1"' in text
    cm = tmp_path / "S1_cm.dae"
    cm.write_text(text.replace('meter="1"', 'meter="0.01"'))
    np.testing.assert_allclose(trimesh.load(as_stl(cm)).bounds, 0.01 * trimesh.load(as_stl(source)).bounds, atol=1e-9)
    bad = tmp_path / "bad.dae"
    bad.write_text("<COLLADA>not a mesh</COLLADA>")
    with pytest.raises(InputError, match=r"bad\.dae"):
        as_stl(bad)


def test_pr2_loads_with_its_inertias_replaced():
    """PR2's inertias break the triangle inequality: replaced, said in the notes; FK is MuJoCo's."""
    robot = qpik.load_robot(packaged("erd/pr2"), base="torso_lift_link", tip="l_wrist_roll_link")
    assert robot.dof == 7
    assert "invalid inertias replaced" in robot.notes and "sensor_mount_link" in robot.notes
    Q = random_q(robot, 20, 1)
    np.testing.assert_allclose(MjKinematics.from_robot(robot).fk(Q), robot.fk(Q), atol=1e-10)


@pytest.mark.parametrize(
    "inertial",
    [
        '<mass value="nan"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/>',
        '<mass value="-1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/>',
        '<mass value="1"/><inertia ixx="1" iyy="nan" izz="1" ixy="0" ixz="0" iyz="0"/>',
        '<mass value="1"/><inertia ixx="-1" iyy="-1" izz="-1" ixy="0" ixz="0" iyz="0"/>',
        '<mass value="1"/><inertia ixx="1" iyy="1" izz="5" ixy="0" ixz="0" iyz="0"/>',
        '<mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="2" ixz="0" iyz="0"/>',
        '<origin xyz="nan 0 0"/><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/>',
    ],
)
def test_bad_inertials_never_block_loading(tmp_path, inertial):
    """Mass, centre and tensor the kinematics does not use: replaced, said in the notes; the model compiles."""
    path = tmp_path / "arm.urdf"
    path.write_text(
        _TWO.format(limit='<limit lower="-1" upper="1" velocity="1"/>').replace(
            '<link name="l1">', f'<link name="l1"><inertial>{inertial}</inertial>'
        )
    )
    robot = qpik.load_robot(path)
    assert "invalid inertias replaced (the kinematics does not use them): l1" in robot.notes
    model = robot.mj_model()
    assert np.all(np.isfinite(model.body_inertia)) and np.all(model.body_mass >= 0)


# ---- mimic joints -------------------------------------------------------------


def test_mimic_joint_is_coupled_as_pinocchio_says():
    """j3 = -0.5 j2 + 0.2: three independent joints; FK equals pinocchio's mimic model to 1e-12."""
    pin = pytest.importorskip("pinocchio")
    robot = qpik.load_robot(MIMIC)
    assert robot.dof == 3 and robot.joint_names == ("j1", "j2", "j4")
    assert robot.model.mimic == (("j3", "j2", -0.5, 0.2),)
    assert "j3 = -0.5·j2 + 0.2" in robot.notes
    model = pin.buildModelFromUrdf(str(MIMIC), mimic=True)
    data = model.createData()
    Q = random_q(robot, 100, 2)
    poses = []
    for q in Q:
        full = pin.neutral(model)
        for name, x in zip(robot.joint_names, q):
            full[model.joints[model.getJointId(name)].idx_q] = x
        pin.framesForwardKinematics(model, data, full)
        poses.append(data.oMf[model.getFrameId("tool")].homogeneous.copy())
    np.testing.assert_allclose(robot.fk(Q), np.array(poses), atol=1e-12, rtol=0)


def test_pr2_finger_chain_with_a_mimic_joint_is_pinocchios():
    """PR2's arm down to a fingertip: the tip joint mimics the finger joint; base-frame FK equals pinocchio's."""
    pin = pytest.importorskip("pinocchio")
    path = packaged("erd/pr2")
    robot = qpik.load_robot(path, base="torso_lift_link", tip="l_gripper_l_finger_tip_link")
    assert robot.dof == 8 and robot.model.mimic == (
        ("l_gripper_l_finger_tip_joint", "l_gripper_l_finger_joint", 1.0, 0.0),
    )
    model = pin.buildModelFromUrdf(str(path), mimic=True)
    data = model.createData()
    base, tip = model.getFrameId("torso_lift_link"), model.getFrameId("l_gripper_l_finger_tip_link")
    Q = random_q(robot, 50, 8)
    for q in Q:
        full = pin.neutral(model)
        for name, x in zip(robot.joint_names, q):
            joint = model.joints[model.getJointId(name)]
            full[joint.idx_q : joint.idx_q + joint.nq] = (np.cos(x), np.sin(x)) if joint.nq == 2 else x  # continuous
        pin.framesForwardKinematics(model, data, full)
        np.testing.assert_allclose(robot.fk(q), (data.oMf[base].inverse() * data.oMf[tip]).homogeneous, atol=1e-12)
    np.testing.assert_allclose(robot.jacobian(Q[:10]), fd_geometric_jacobian(robot.fk, Q[:10]), atol=1e-6)


def test_mimic_jacobian_and_hessian_are_the_chain_rule():
    robot = qpik.load_robot(MIMIC)
    Q = random_q(robot, 40, 3)
    np.testing.assert_allclose(robot.jacobian(Q), fd_geometric_jacobian(robot.fk, Q), atol=1e-6, rtol=0)
    H_fd = np.moveaxis(fd(robot.jacobian, Q[:10]), -1, 1)
    np.testing.assert_allclose(robot.hessian(Q[:10]), H_fd, atol=1e-6, rtol=0)
    for q in Q[:5]:  # the compiled single-q path
        np.testing.assert_allclose(robot.jacobian(q), robot.jacobian(q[None])[0], atol=1e-13)
        np.testing.assert_allclose(robot.hessian(q), robot.hessian(q[None])[0], atol=1e-13)
    g = robot.manipulability_gradient(Q[0], translational=True)
    np.testing.assert_allclose(g, fd(lambda q: robot.manipulability(q, translational=True), Q[0]), atol=1e-6)


def test_mimic_point_jacobians_of_every_link():
    """The controller's capsule rows: each link's point Jacobian (its columns up to its last driving joint) is FD's."""
    from qpik.algebra import symbolic as sy

    robot = qpik.load_robot(MIMIC)
    assert [c.link for c in robot.capsules] == [1, 2, 3, 4]  # link 3 is moved by the mimic joint
    for q in random_q(robot, 5, 6):
        frames = robot.chain.frames_expr([np.array([x]) for x in q], sy.NUMPY)
        for c, cap in enumerate(robot.capsules):
            point = robot.capsule_segments(q)[c, 1]
            cols = robot.chain.point_jacobian_expr(frames, tuple(point), cap.link)
            J = np.zeros((3, robot.dof))
            for i, col in enumerate(cols):
                J[:, i] = [float(np.squeeze(x)) for x in col]
            np.testing.assert_allclose(J, fd(lambda q, c=c: robot.capsule_segments(q)[c, 1], q), atol=1e-6)


def test_mimic_joint_in_mujoco():
    """The MuJoCo model couples the joint (MuJoCo's equality constraint; the kinematics and the sim write it)."""
    robot = qpik.load_robot(MIMIC)
    model = robot.mj_model()
    assert model.neq == 1 and model.eq_type[0] == mujoco.mjtEq.mjEQ_JOINT
    np.testing.assert_allclose(model.eq_data[0, :2], (0.2, -0.5))
    kin = MjKinematics.from_robot(robot)
    with pytest.raises(InputError, match="mimic joint 'ghost' is not in the model"):
        MjKinematics(model, robot.site, robot.joint_names, [("ghost", "j2", 1.0, 0.0)])
    with pytest.raises(InputError, match=r"mimic: leaders \['j3'\] are not arm joints"):
        MjKinematics(model, robot.site, robot.joint_names, [("j1", "j3", 1.0, 0.0)])
    Q = random_q(robot, 30, 4)
    np.testing.assert_allclose(kin.fk(Q), robot.fk(Q), atol=1e-12)
    np.testing.assert_allclose(kin.jacobian(Q), robot.jacobian(Q), atol=1e-12)
    log = simulate(robot, lambda t, q: np.array([0.3, -0.4, 0.5]), Q[0] * 0.5, 1.0, 0.01)
    np.testing.assert_allclose(log.ee, robot.fk(log.q), atol=1e-12)
    with pytest.raises(InputError, match="mimic joints"):
        robot.to_urdf()  # its writer has one axis per joint


@pytest.mark.parametrize(
    ("mimic", "match"),
    [
        ('<mimic joint="j4"/>', "mimics 'j4', which is not an independent arm joint before it"),
        ('<mimic joint="nowhere"/>', "joint 'j3' mimics 'nowhere', which is not a joint of the file"),
        ("<mimic/>", "required attribute missing: 'joint'"),
        ('<mimic joint="j2" multiplier="nan"/>', "joint 'j3': mimic multiplier and offset must be finite"),
        ('<mimic joint="j2" offset="x"/>', "bad format in attribute 'offset'"),
    ],
)
def test_bad_mimic_joints_are_clear_errors(tmp_path, mimic, match):
    path = tmp_path / "arm.urdf"
    path.write_text(MIMIC.read_text().replace('<mimic joint="j2" multiplier="-0.5" offset="0.2"/>', mimic))
    with pytest.raises(InputError, match=match):
        qpik.load_robot(path)


# ---- limits -------------------------------------------------------------------

_TWO = """<robot name="two">
  <link name="base"/>
  <link name="l1"><collision><geometry><box size="0.1 0.1 0.3"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0 0 0.1"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    {limit}</joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 -1 0"/><limit lower="-1" upper="1" effort="1" velocity="0.5"/></joint>
</robot>
"""


def _two(tmp_path: Path, limit: str) -> Path:
    path = tmp_path / "two.urdf"
    path.write_text(_TWO.format(limit=limit))
    return path


@pytest.mark.parametrize(
    ("limit", "match"),
    [
        ('<limit lower="nan" upper="1" velocity="1"/>', "joint 'j1': limit lower is NaN"),
        ('<limit lower="-1" upper="nan" velocity="1"/>', "joint 'j1': limit upper is NaN"),
        ('<limit lower="2" upper="1" velocity="1"/>', "joint 'j1': limit lower 2.0 > upper 1.0"),
        ('<limit lower="0.5" upper="0.5" velocity="1"/>', "joint 'j1' is locked in the file"),
        ('<limit lower="-inf" upper="1" velocity="1"/>', "joint 'j1': limit lower is infinite"),
        ('<limit lower="-1" upper="inf" velocity="1"/>', "joint 'j1': limit upper is infinite"),
        ('<limit lower="-1" upper="1" velocity="0"/>', "joint 'j1': limit velocity 0.0"),
        ('<limit lower="-1" upper="1" velocity="-1"/>', "joint 'j1': limit velocity -1.0"),
        ('<limit lower="-1" upper="1" velocity="nan"/>', "joint 'j1': limit velocity nan"),
        ('<limit lower="-1" upper="1" velocity="inf"/>', "joint 'j1': limit velocity inf"),
        ('<limit lower="one" upper="1" velocity="1"/>', "joint 'j1': limit lower='one' is not a number"),
    ],
)
def test_invalid_limits_name_the_joint_and_attribute(tmp_path, limit, match):
    with pytest.raises(InputError, match=match):
        qpik.load_robot(_two(tmp_path, limit))


def test_missing_limits_get_documented_defaults(tmp_path):
    robot = qpik.load_robot(_two(tmp_path, '<limit effort="1"/>'))
    np.testing.assert_array_equal(robot.q_min, [-CONTINUOUS_LIMIT, -1.0])
    np.testing.assert_array_equal(robot.v_max, [DEFAULT_VELOCITY, 0.5])
    assert f"no position limit in the file for j1: ±{CONTINUOUS_LIMIT:.4f} used" in robot.notes
    assert f"no velocity limit in the file for j1: {DEFAULT_VELOCITY} used" in robot.notes
    assert np.all(np.isfinite(robot.q_home))
    lower_only = qpik.load_robot(_two(tmp_path, '<limit lower="-0.5" velocity="2"/>'))  # URDF: upper defaults to 0
    np.testing.assert_array_equal((lower_only.q_min[0], lower_only.q_max[0], lower_only.v_max[0]), (-0.5, 0.0, 2.0))


_NUMBERS = st.one_of(
    st.floats(min_value=-4.0, max_value=4.0),
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.sampled_from([0.0, -0.0, 1.0, -1.0, 1e-300, 1e300]),
)


@settings(max_examples=60, deadline=None)
@given(lower=_NUMBERS, upper=_NUMBERS, velocity=_NUMBERS)
def test_limits_are_used_as_given_or_refused(tmp_path_factory, lower, upper, velocity):
    """A mutated URDF limit: loaded exactly as written, or one InputError naming j1 (never rewritten)."""
    path = _two(
        tmp_path_factory.mktemp("limits"), f'<limit lower="{lower!r}" upper="{upper!r}" velocity="{velocity!r}"/>'
    )
    valid = np.isfinite([lower, upper, velocity]).all() and lower < upper and velocity > 0
    if not valid:
        with pytest.raises(InputError, match="joint 'j1'"):
            qpik.load_robot(path)
        return
    robot = qpik.load_robot(path)
    assert np.all(np.isfinite(robot.q_home)) and robot.within_limits(robot.q_home)
    assert (robot.q_min[0], robot.q_max[0], robot.v_max[0]) == (lower, upper, velocity)


# ---- model names --------------------------------------------------------------


@pytest.mark.parametrize("name", [None, 'my arm "v2" <test>', "7-dof/arm", "class"])
def test_any_model_name_works(tmp_path, name):
    """An MJCF without a model name (MuJoCo's "MuJoCo Model") or with any text: IK and control run."""
    text = (MODEL_DIR / "gymnasium_pusher/pusher_v5.xml").read_text()
    head, rest = text.split("<mujoco", 1)
    rest = rest.split(">", 1)[1]
    model = "" if name is None else f' model="{name.replace(chr(34), "&quot;").replace("<", "&lt;")}"'
    path = tmp_path / "pusher.xml"
    path.write_text(f"{head}<mujoco{model}>{rest}")
    robot = qpik.load_robot(path, tip="tips_arm")
    assert robot.name == ("MuJoCo Model" if name is None else name)
    assert robot.identifier.isidentifier() and robot.identifier.isascii()
    q = random_q(robot, 1, 5, margin=0.3)[0]
    np.testing.assert_allclose(robot.fk(qpik.solve_ik(robot, robot.fk(q), robot.q_home)), robot.fk(q), atol=1e-6)
    ctrl = qpik.Controller.for_robot(robot, target=robot.fk(q), dt=0.01)
    assert ctrl.step(robot.q_home).shape == (robot.dof,)
    assert robot.mj_model().nbody > robot.dof


def test_one_joint_urdf(tmp_path):
    """A 1-joint arm: manipulability 0 (fewer joints than rows), shapes (6, 1), control runs."""
    path = tmp_path / "one.urdf"
    path.write_text(
        '<robot name="one"><link name="b"/><link name="l"><collision><geometry><box size="0.1 0.1 0.1"/>'
        '</geometry></collision></link><joint name="j" type="revolute"><parent link="b"/><child link="l"/>'
        '<origin xyz="0.2 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
        "</joint></robot>"
    )
    robot = qpik.load_robot(path)
    q = np.array([0.3])
    assert robot.jacobian(q).shape == (6, 1) and robot.fk_jacobian(q)[1].shape == (6, 1)
    assert robot.manipulability(q) == 0.0 and robot.manipulability(q, translational=True) == 0.0
    np.testing.assert_array_equal(robot.manipulability(np.zeros((3, 1))), np.zeros(3))
    ctrl = qpik.Controller.for_robot(robot, target=robot.fk(q), dt=0.01)
    assert ctrl.step(np.zeros(1))[0] > 0
