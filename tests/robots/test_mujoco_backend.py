"""MjKinematics: FK/Jacobians against the DH chain, finite differences and mink; geom distances
against brute force."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import SEEDS, fd, fd_geometric_jacobian, random_q
from hypothesis import given, settings

from qpik.core.errors import InputError
from qpik.robots.catalog import CATALOG
from qpik.robots.loader import load_robot
from qpik.robots.mujoco_backend import MjKinematics

ARMS = sorted(CATALOG)
KIN = {name: MjKinematics.from_robot(load_robot(name)) for name in ARMS}


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_jacobian_matches_finite_differences_and_dh(seed: int) -> None:
    for name, kin in KIN.items():
        robot = load_robot(name)
        qs = random_q(robot, 20, seed)
        T, J = kin.fk_jacobian(qs)
        np.testing.assert_allclose(T, robot.fk(qs), atol=1e-9)
        np.testing.assert_allclose(J, robot.jacobian(qs), atol=1e-9)
        np.testing.assert_allclose(kin.jacobian(qs), J, atol=0)
        np.testing.assert_allclose(kin.jacobian(qs[:3]), fd_geometric_jacobian(kin.fk, qs[:3]), atol=1e-6)


def test_jacobian_is_minks_body_jacobian_in_world_axes() -> None:
    """mink returns the body Jacobian ₍B₎J_WB; rotating both rows blocks by R_WB gives ours."""
    rng = np.random.default_rng(0)
    for name, kin in KIN.items():
        robot = load_robot(name)
        config = mink.Configuration(robot.mj_model())
        for q in rng.uniform(robot.q_min, robot.q_max, (10, robot.dof)):
            config.update(q)
            R = config.get_transform_frame_to_world("ee", "site").rotation().as_matrix()
            Jb = config.get_frame_jacobian("ee", "site")
            world = np.vstack((R @ Jb[:3], R @ Jb[3:]))
            np.testing.assert_allclose(kin.jacobian(q), world, atol=1e-12, err_msg=name)


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_point_jacobian_matches_finite_differences(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for name, kin in KIN.items():
        robot = load_robot(name)
        q = rng.uniform(robot.q_min, robot.q_max)
        k = int(rng.integers(1, robot.dof + 1))
        body = kin.model.body(f"link{k}").id
        # a point fixed in body k: its body coordinates c, world p(q) = x_b(q) + R_b(q) c
        kin.update(q)
        p = kin.data.xpos[body] + rng.uniform(-0.2, 0.2, 3)
        c = kin.data.xmat[body].reshape(3, 3).T @ (p - kin.data.xpos[body])

        def world(qq: np.ndarray, kin: MjKinematics = kin, body: int = body, c: np.ndarray = c) -> np.ndarray:
            kin.update(qq)
            return kin.data.xpos[body] + kin.data.xmat[body].reshape(3, 3) @ c

        want = fd(world, q)
        np.testing.assert_allclose(kin.point_jacobian(q, f"link{k}", p), want, atol=1e-6, err_msg=f"{name} link{k}")


def _segment_points(p0: np.ndarray, p1: np.ndarray, n: int = 800) -> np.ndarray:
    return p0 + np.linspace(0, 1, n)[:, None] * (p1 - p0)


def _brute_distance(a: np.ndarray, b: np.ndarray) -> float:
    """min over sampled point pairs of two point sets (M, 3), (K, 3)."""
    return float(np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)).min())


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_geom_distance_matches_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    name = ARMS[seed % len(ARMS)]
    robot = load_robot(name)
    centre = rng.uniform(-0.6, 0.6, 3) + np.array([0, 0, 0.5])
    ball = f'<geom name="ball" type="sphere" size="0.1" pos="{" ".join(map(str, centre))}"/>'
    kin = MjKinematics.from_robot(robot, [ball])
    q = rng.uniform(robot.q_min, robot.q_max)
    segs = robot.capsule_segments(q)
    i = int(rng.integers(0, robot.dof - 2))
    j = int(rng.integers(i + 2, robot.dof))  # adjacent links touch by construction
    ci, cj = robot.capsules[i], robot.capsules[j]
    pairs = [
        (f"link{ci.link}_capsule", f"link{cj.link}_capsule", segs[i], segs[j], ci.radius, cj.radius),
        (f"link{cj.link}_capsule", "ball", segs[j], np.stack([centre, centre]), cj.radius, 0.1),
    ]
    for ga, gb, sa, sb, ra, rb in pairs:
        dist, fromto = kin.geom_distance(q, ga, gb, distmax=10.0)
        brute = _brute_distance(_segment_points(*sa), _segment_points(*sb)) - ra - rb
        assert dist == pytest.approx(brute, abs=1e-3), (name, ga, gb)
        # the witness points lie on the two surfaces, and are dist apart when the geoms are apart
        assert _brute_distance(fromto[:1], _segment_points(*sa, 4000)) == pytest.approx(ra, abs=1e-3)
        assert _brute_distance(fromto[1:], _segment_points(*sb, 4000)) == pytest.approx(rb, abs=1e-3)
        if dist > 0:
            assert np.linalg.norm(fromto[1] - fromto[0]) == pytest.approx(dist, abs=1e-9)


def test_geom_distance_beyond_distmax() -> None:
    kin = KIN["iiwa14"]
    dist, fromto = kin.geom_distance(load_robot("iiwa14").q_home, "link1_capsule", "link6_capsule", distmax=0.01)
    assert dist == 0.01 and np.all(np.isnan(fromto))


def test_limits_and_dof_from_joint_ranges() -> None:
    for name, kin in KIN.items():
        robot = load_robot(name)
        assert kin.dof == robot.dof
        np.testing.assert_array_equal(kin.q_min, robot.q_min)
        np.testing.assert_array_equal(kin.q_max, robot.q_max)


def test_arm_that_is_part_of_the_model() -> None:
    """Extra non-arm joints (a sliding obstacle) stay at qpos0 and out of the Jacobian."""
    robot = load_robot("panda")
    slider = (
        '<body name="cart" pos="0.6 0 0.3"><joint name="slide" type="slide" axis="1 0 0"/><geom size="0.05"/></body>'
    )
    kin = MjKinematics.from_robot(robot, [slider])
    assert kin.model.nq == 8 and kin.dof == 7
    q = np.random.default_rng(1).uniform(robot.q_min, robot.q_max, (5, 7))
    T, J = kin.fk_jacobian(q)
    np.testing.assert_allclose(T, robot.fk(q), atol=1e-9)
    np.testing.assert_allclose(J, robot.jacobian(q), atol=1e-9)


def test_from_xml_path_and_a_hand_written_arm(tmp_path) -> None:
    robot = load_robot("zheng7")
    path = tmp_path / "zheng7.xml"
    path.write_text(robot.to_mjcf())
    q = robot.q_home
    np.testing.assert_allclose(MjKinematics.from_xml(path).fk(q), robot.fk(q), atol=1e-12)
    # a planar 2R arm with no DH table: x = l1 cos q1 + l2 cos(q1 + q2), y likewise
    xml = """<mujoco><compiler angle="radian"/><worldbody>
      <body name="a"><joint name="j1" axis="0 0 1" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02"/>
        <body name="b" pos="0.5 0 0"><joint name="j2" axis="0 0 1"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/><site name="tip" pos="0.3 0 0"/>
        </body></body></worldbody></mujoco>"""
    arm = MjKinematics.from_xml(xml, site="tip")
    assert arm.dof == 2
    np.testing.assert_array_equal(arm.q_min, [-1, -np.inf])
    q1, q2 = 0.3, -0.7
    p = arm.fk(np.array([q1, q2]))[:3, 3]
    np.testing.assert_allclose(
        p, [0.5 * np.cos(q1) + 0.3 * np.cos(q1 + q2), 0.5 * np.sin(q1) + 0.3 * np.sin(q1 + q2), 0]
    )


def test_bad_inputs_raise_input_error() -> None:
    kin = KIN["iiwa14"]
    with pytest.raises(InputError, match="q"):
        kin.fk(np.full(7, np.nan))
    with pytest.raises(InputError, match="q"):
        kin.jacobian(np.zeros(6))
    with pytest.raises(InputError, match="site"):
        kin.site_pose(np.zeros(7), "nope")
    with pytest.raises(InputError, match="geom"):
        kin.geom_distance(np.zeros(7), "link1_capsule", "nope")
    with pytest.raises(InputError, match="point"):
        kin.point_jacobian(np.zeros(7), "link3", np.zeros(2))
    with pytest.raises(InputError, match="joint"):
        MjKinematics(kin.model, joint_names=["joint1", "nope"])
