"""Arms loaded from MJCF and URDF files written by others, checked against MuJoCo's own reading of them.

FK against ``mj_kinematics`` of the same model, Jacobians against finite differences and
against MuJoCo's ``mj_jacSite`` on the robot's model, capsules against MuJoCo's placement of
every collision vertex, limits against the catalog Panda (the Franka documentation), and the
errors of bad models.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import MODEL_DIR, fd, fd_geometric_jacobian, model_robot, mujoco_poses, random_q

import qpik
from qpik.analytic.intervals import wrap
from qpik.core.errors import InputError, UnknownRobotError
from qpik.robots.model_files import MeshOptions
from qpik.robots.mujoco_backend import MjKinematics


def mujoco_tip_poses(robot: qpik.Robot, Q: np.ndarray) -> np.ndarray:
    """World poses (N, 4, 4) of the tip body by MuJoCo on the model file (other joints at their reference)."""
    return mujoco_poses(robot, Q, robot.model.spec().compile(), robot.model.tip_body)


def test_fk_equals_mujoco_and_derivatives_are_fd(loaded):
    Q = random_q(loaded, 300, 0)
    T = loaded.fk(Q)
    np.testing.assert_allclose(T, mujoco_tip_poses(loaded, Q), atol=1e-10, rtol=0)
    J = loaded.jacobian(Q)
    np.testing.assert_allclose(J, fd_geometric_jacobian(loaded.fk, Q), atol=1e-6, rtol=0)
    H_fd = np.moveaxis(fd(loaded.jacobian, Q[:50]), -1, 1)  # (N, 6, j, k) -> (N, k, 6, j)
    np.testing.assert_allclose(loaded.hessian(Q[:50]), H_fd, atol=1e-6, rtol=0)
    for q, Tq, Jq in zip(Q[:20], T, J):  # the compiled single-q path
        T1, J1 = loaded.fk_jacobian(q)
        np.testing.assert_allclose(T1, Tq, atol=1e-12, rtol=0)
        np.testing.assert_allclose(J1, Jq, atol=1e-12, rtol=0)


def test_model_site_and_jacobian_equal_the_chain(loaded):
    """The robot's MuJoCo model (capsules and end-effector site added) through MuJoCo's own Jacobian."""
    kin = MjKinematics(loaded.mj_model(), loaded.site, loaded.joint_names)
    Q = random_q(loaded, 50, 1)
    T, J = kin.fk_jacobian(Q)
    np.testing.assert_allclose(T, loaded.fk(Q), atol=1e-10, rtol=0)
    np.testing.assert_allclose(J, loaded.jacobian(Q), atol=1e-10, rtol=0)


def test_capsules_contain_the_collision_geometry(loaded):
    """Every collision vertex (or primitive's points), placed by MuJoCo at random q, is inside its link's capsule."""
    model = loaded.mj_model()
    kin = MjKinematics(model, loaded.site, loaded.joint_names)
    body_link = _body_links(model, loaded)
    caps = {c.link: i for i, c in enumerate(loaded.capsules)}
    colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    for q in random_q(loaded, 3, 2):
        kin.update(q)
        seg = loaded.capsule_segments(q)
        for g in range(model.ngeom):
            link = body_link.get(int(model.geom_bodyid[g]), 0)
            drawn = model.geom(g).name.startswith("qpik_capsule")
            own = [h for h in range(model.ngeom) if body_link.get(int(model.geom_bodyid[h]), 0) == link]
            if link == 0 or drawn or (not colliding[g] and any(colliding[h] for h in own)):
                continue
            pts, r = _geom_points(model, kin.data, g)
            c = caps[link]
            d = _segment_distance(seg[c, 0], seg[c, 1], pts) + r
            assert d.max() <= loaded.capsules[c].radius + 1e-9, (loaded.name, link, model.geom(g).name)


def test_capsules_are_drawn_where_the_chain_puts_them(loaded):
    model = loaded.mj_model()
    kin = MjKinematics(model, loaded.site, loaded.joint_names)
    q = random_q(loaded, 1, 3)[0]
    kin.update(q)
    seg = loaded.capsule_segments(q)
    for c, cap in enumerate(loaded.capsules):
        g = model.geom(f"qpik_capsule{c}").id
        assert model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0
        z = kin.data.geom_xmat[g].reshape(3, 3)[:, 2]
        ends = kin.data.geom_xpos[g] + np.outer((-1, 1), z) * model.geom_size[g, 1]
        err = min(np.abs(ends - seg[c]).max(), np.abs(ends[::-1] - seg[c]).max())
        assert err < 1e-9
        assert model.geom_size[g, 0] == pytest.approx(cap.radius, abs=1e-12)


def test_limits_home_and_velocities(loaded):
    assert np.all(loaded.q_min < loaded.q_max)
    assert loaded.within_limits(loaded.q_home)
    assert np.all(loaded.v_max > 0)


@pytest.mark.parametrize("key", ["erd_panda", "pybullet_panda"])
def test_panda_files_carry_the_franka_limits(key):
    """Two Panda URDFs against the catalog Panda (Franka documentation); pybullet's ranges are wider."""
    robot, franka = model_robot(key), qpik.load_robot("panda")
    np.testing.assert_allclose(robot.v_max, franka.v_max, atol=1e-9)
    if key == "pybullet_panda":
        assert np.all(robot.q_min < franka.q_min) and np.all(robot.q_max > franka.q_max)
    else:
        np.testing.assert_allclose(robot.q_min, franka.q_min, atol=1e-9)
        np.testing.assert_allclose(robot.q_max, franka.q_max, atol=1e-9)


def test_panda_urdf_flange_is_the_catalog_panda():
    """example-robot-data's panda_link8 against the catalog Panda's flange (modified DH), one base offset apart."""
    robot = qpik.load_robot(model_robot("erd_panda").model.path, tip="panda_link8")
    franka = qpik.load_robot("panda")
    Q = random_q(franka, 200, 4)
    np.testing.assert_allclose(robot.fk(Q), franka.fk(Q), atol=1e-12)


def test_which_joints_are_the_arm():
    """Named joints: the others on the path stay at their reference (MuJoCo agrees), the order is checked."""
    path = MODEL_DIR / "gymnasium_pusher/pusher_v5.xml"
    arm = model_robot("pusher")
    names = list(arm.joint_names)
    part = qpik.load_robot(path, joints=names[:3] + names[4:], tip="tips_arm")
    assert part.dof == 6
    Q = random_q(part, 50, 5)
    np.testing.assert_allclose(part.fk(Q), mujoco_tip_poses(part, Q), atol=1e-10)
    full = np.insert(Q, 3, 0.0, axis=1)  # pusher's qpos0 is 0
    np.testing.assert_allclose(part.fk(Q), arm.fk(full), atol=1e-12)
    with pytest.raises(InputError, match="chain order"):
        qpik.load_robot(path, joints=names[::-1], tip="tips_arm")
    with pytest.raises(InputError, match="not on the chain"):
        qpik.load_robot(path, joints=[*names, "obj_slidex"], tip="tips_arm")
    with pytest.raises(InputError, match="no joint 'elbow'"):
        qpik.load_robot(path, joints=["elbow"], tip="tips_arm")


def test_site_tip_and_ee_offset():
    path = MODEL_DIR / "robosuite_iiwa/robot.xml"
    ee = np.eye(4)
    ee[:3, 3] = (0.0, 0.0, 0.1)
    robot = qpik.load_robot(path, tip="right_center", meshes=MeshOptions(collision_only=True))  # a site on link_1
    assert robot.dof == 1
    longer = qpik.load_robot(path, meshes=MeshOptions(collision_only=True), ee=ee)
    plain = model_robot("robosuite_iiwa")
    Q = random_q(plain, 20, 6)
    np.testing.assert_allclose(longer.fk(Q), plain.fk(Q) @ ee, atol=1e-12)


def test_package_paths_resolve_against_a_package_map(tmp_path):
    erd = model_robot("erd_panda").model.path
    share = erd.parents[4]  # .../share, holding example-robot-data/
    robot = qpik.load_robot(erd, meshes=MeshOptions(package_map={"example-robot-data": share / "example-robot-data"}))
    np.testing.assert_allclose(robot.fk(robot.q_home), model_robot("erd_panda").fk(robot.q_home), atol=1e-15)
    bad = tmp_path / "arm.urdf"
    bad.write_text(_URDF.format(geom='<mesh filename="package://nowhere/link.stl"/>'))
    with pytest.raises(InputError, match=r"mesh 'package://nowhere/link.stl' not found.*package_map=\{'nowhere'"):
        qpik.load_robot(bad)


_URDF = """<robot name="two">
  <link name="base"/>
  <link name="l1"><collision><geometry>{geom}</geometry></collision></link>
  <link name="l2"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="0.7"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 -1 0"/></joint>
</robot>
"""


def test_urdf_velocity_and_continuous_joints(tmp_path):
    from qpik.robots.limits import CONTINUOUS_LIMIT, DEFAULT_VELOCITY

    path = tmp_path / "two.urdf"
    path.write_text(_URDF.format(geom='<box size="0.1 0.1 0.3"/>'))
    robot = qpik.load_robot(path)
    np.testing.assert_allclose(robot.v_max, [0.7, DEFAULT_VELOCITY])
    np.testing.assert_allclose(robot.q_max, [1.0, CONTINUOUS_LIMIT])
    Q = random_q(robot, 50, 7)
    np.testing.assert_allclose(robot.fk(Q), mujoco_tip_poses(robot, Q), atol=1e-12)


@pytest.mark.parametrize(
    ("text", "options", "match"),
    [
        ("<mujoco><worldbody><body><geom size='.1'/></body></worldbody></mujoco>", {}, "no joints"),
        (
            "<mujoco><worldbody><body><joint type='ball'/><geom size='.1'/><body><joint/><geom size='.1'/>"
            "</body></body></worldbody></mujoco>",
            {},
            "unsupported joint: 'qpik_joint0' is a ball joint",
        ),
        (
            "<mujoco><worldbody><body name='a'><joint/><geom size='.1'/></body>"
            "<body name='b'><joint/><geom size='.1'/></body></worldbody></mujoco>",
            {},
            "branched chain: 'world' carries 2 moving branches",
        ),
        (
            "<mujoco><worldbody><body name='a'><joint/><geom size='.1'/></body>"
            "<body name='b'><joint/><geom size='.1'/></body></worldbody></mujoco>",
            {"base": "a", "tip": "b"},
            "branched chain: tip 'b' is not below base 'a'",
        ),
        ("<mujoco><worldbody><body><joint/><geom size='.1'/></body></worldbody></mujoco>", {"tip": "x"}, "tip: no"),
        ("<mujoco><worldbody><body><joint/><geom size='.1'></body></worldbody></mujoco>", {}, "not well-formed XML"),
        ("not a model at all", {}, "not well-formed XML"),
    ],
)
def test_bad_models_raise_clear_errors(tmp_path, text, options, match):
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(InputError, match=match):
        qpik.load_robot(path, **options)


def test_missing_meshes_and_unknown_names():
    with pytest.raises(InputError, match=r"mesh 'meshes/link_0_vis.stl' not found.*collision_only=True"):
        qpik.load_robot(MODEL_DIR / "robosuite_iiwa/robot.xml")
    with pytest.raises(UnknownRobotError, match=r"unknown robot 'ur5'; known: .*, or the path of an MJCF or URDF file"):
        qpik.load_robot("ur5")
    with pytest.raises(InputError, match="catalog arm"):
        qpik.load_robot("iiwa14", tip="x")
    with pytest.raises(InputError, match="branched chain"):
        qpik.load_robot(MODEL_DIR / "gymnasium_pusher/pusher_v5.xml")


# ---- helpers ----------------------------------------------------------------


def _body_links(model: mujoco.MjModel, robot: qpik.Robot) -> dict[int, int]:
    """body id -> link k (1..n) of the last arm joint above it (0 above joint 1)."""
    jb = [int(model.joint(n).bodyid[0]) for n in robot.joint_names]
    out = {0: 0}
    for b in range(1, model.nbody):
        p = int(model.body_parentid[b])
        out[b] = max([k + 1 for k, x in enumerate(jb) if x == b], default=out[p])
    return out


def _geom_points(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> tuple[np.ndarray, float]:
    R, p = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g]
    size = model.geom_size[g]
    kind = model.geom_type[g]
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        m = model.geom_dataid[g]
        local, r = model.mesh_vert[model.mesh_vertadr[m] : model.mesh_vertadr[m] + model.mesh_vertnum[m]], 0.0
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        local, r = np.zeros((1, 3)), size[0]
    elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        local, r = np.array([[0, 0, -size[1]], [0, 0, size[1]]]), size[0]
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        t = np.linspace(0, 2 * np.pi, 200)
        local = np.concatenate([np.c_[size[0] * np.cos(t), size[0] * np.sin(t), np.full(200, z)] for z in (-1, 1)])
        local[:, 2] *= size[1]
        r = 0.0
    else:
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        local, r = corners * size, 0.0
    return local @ R.T + p, r


def _segment_distance(a: np.ndarray, b: np.ndarray, pts: np.ndarray) -> np.ndarray:
    ab = b - a
    L2 = ab @ ab
    t = np.zeros(len(pts)) if L2 == 0 else np.clip((pts - a) @ ab / L2, 0, 1)
    return np.linalg.norm(pts - a - t[:, None] * ab, axis=1)


def test_the_catalog_zheng7_asked_for_q7_gives_the_answers_of_its_mjcf_twin(tmp_path):
    """The catalog's zheng7 keeps no family (the arm of no closed form of the suite and the problem files); asked for
    q7 it is of the family its MJCF twin (the arm written by ``to_mjcf`` and loaded as a file) gets by default, the
    1-D search over q4 with q7 locked, with the same slots to 1e-9 rad at the same poses and parameters, each holding
    the configuration; asked for q1 it is of the general 6-R family with q1 locked; ψ is refused."""
    plain = qpik.load_robot("zheng7")
    assert plain.closed_form is None
    robot = qpik.load_robot("zheng7", redundancy="q7")
    assert robot.closed_form == "locked_search" and qpik.load_robot("zheng7", redundancy="q7") is robot
    path = tmp_path / "zheng7.xml"
    path.write_text(plain.to_mjcf())
    twin = qpik.load_robot(path, tip="ee")
    assert twin.closed_form == "locked_search"
    q = np.random.default_rng(12).uniform(robot.q_min, robot.q_max, (20, robot.dof))
    np.testing.assert_allclose(twin.fk(q), robot.fk(q), atol=1e-12)
    for qk, T in zip(q, robot.fk(q)):
        mine, theirs = qpik.ik(robot, T, float(qk[6])), qpik.ik(twin, T, float(qk[6]))
        assert np.array_equal(mine.valid, theirs.valid)
        assert np.abs(wrap(mine.q[mine.valid] - theirs.q[theirs.valid])).max() < 1e-9
        assert np.abs(wrap(mine.q[mine.valid] - qk)).max(axis=1).min() < 1e-9
    other = qpik.load_robot("zheng7", redundancy="q1")  # the general 6-R with q1 locked
    assert other.closed_form == "locked_general" and other.notes.startswith("served with q1 locked")
    sol = qpik.ik(other, other.fk(q[0]), float(q[0, 0]))
    assert np.abs(wrap(sol.q[sol.valid] - q[0])).max(axis=1).min() < 1e-9
    with pytest.raises(qpik.InputError, match="redundancy: 'zheng7' has no closed form in psi"):
        qpik.load_robot("zheng7", redundancy="psi")
