"""The URDF written from the joint axes: TRAC-IK's and MuJoCo's FK of it against qpik's FK."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
from conftest import SEEDS, mujoco_poses, random_q, random_robot
from hypothesis import given, settings

from qpik.robots.catalog import CATALOG
from qpik.robots.loader import load_robot
from qpik.robots.robot import Robot
from qpik.robots.urdf import _align, _origin

ARMS = sorted(CATALOG)


def _mujoco_fk(robot: Robot, qs: np.ndarray) -> np.ndarray:
    """Poses (N, 4, 4) of the link ``ee`` by MuJoCo's URDF compiler (fixed bodies kept apart)."""
    xml = robot.to_urdf().replace(">", '>\n  <mujoco><compiler fusestatic="false"/></mujoco>', 1)
    return mujoco_poses(robot, qs, mujoco.MjModel.from_xml_string(xml), body="ee")


@pytest.mark.parametrize("name", ARMS)
def test_tracik_fk_equals_qpik_fk(name: str) -> None:
    pytracik = pytest.importorskip("pytracik")
    robot = load_robot(name)
    solver = pytracik.TRAC_IK("base", "ee", robot.to_urdf(), 0.005, 1e-6, pytracik.SolveType.Speed)
    assert pytracik.get_num_joints(solver) == robot.dof
    # the URDF parser keeps the limits in single precision: equal to float32 round-off
    np.testing.assert_allclose(pytracik.get_joint_lower_bounds(solver), robot.q_min, atol=3e-7, rtol=0)
    np.testing.assert_allclose(pytracik.get_joint_upper_bounds(solver), robot.q_max, atol=3e-7, rtol=0)
    qs = random_q(robot, 300, seed=5)
    got = np.array([pytracik.fk(solver, q) for q in qs])
    np.testing.assert_allclose(got, robot.fk(qs), atol=1e-10, rtol=0)


@pytest.mark.parametrize("name", ARMS)
def test_mujoco_fk_equals_qpik_fk(name: str) -> None:
    robot = load_robot(name)
    qs = random_q(robot, 300, seed=6)
    np.testing.assert_allclose(_mujoco_fk(robot, qs), robot.fk(qs), atol=1e-10, rtol=0)


@settings(max_examples=5, deadline=None)  # each random arm compiles its kinematics (~0.3 s)
@given(seed=SEEDS)
def test_random_arms_with_base_and_tool(seed: int) -> None:
    """Any twists (antiparallel axes included), offsets, base and tool rotations: the same FK."""
    for convention in ("standard", "modified"):
        robot = random_robot(seed, convention)
        qs = random_q(robot, 50, seed)
        np.testing.assert_allclose(_mujoco_fk(robot, qs), robot.fk(qs), atol=1e-10, rtol=0)


@pytest.mark.parametrize("name", ARMS)
def test_joints_limits_and_chain(name: str) -> None:
    robot = load_robot(name)
    root = ET.fromstring(robot.to_urdf())
    joints = [j for j in root.iter("joint") if j.get("type") == "revolute"]
    assert [j.get("name") for j in joints] == [f"joint{k}" for k in range(1, robot.dof + 1)]
    for k, joint in enumerate(joints):
        limit = joint.find("limit")
        assert float(limit.get("lower")) == robot.q_min[k] and float(limit.get("upper")) == robot.q_max[k]
        assert float(limit.get("velocity")) == robot.v_max[k]
        assert joint.find("axis").get("xyz") == "0 0 1"
        assert joint.find("parent").get("link") == ("base" if k == 0 else f"link{k}")
        assert joint.find("child").get("link") == f"link{k + 1}"
    (tip,) = [j for j in root.iter("joint") if j.get("type") == "fixed"]
    assert (tip.find("parent").get("link"), tip.find("child").get("link")) == (f"link{robot.dof}", "ee")


@settings(max_examples=50, deadline=None)
@given(seed=SEEDS)
def test_align_and_rpy(seed: int) -> None:
    """_align takes a to b (opposite vectors too); the rpy give back R = Rz(y) Ry(p) Rx(r), at gimbal lock too."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=3)
    a /= np.linalg.norm(a)
    for b in (rng.normal(size=3), -a, a):
        b = b / np.linalg.norm(b)
        R = _align(a, b)
        np.testing.assert_allclose(R @ a, b, atol=1e-14)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    for pitch in (rng.uniform(-np.pi / 2, np.pi / 2), np.pi / 2, -np.pi / 2):
        r, y = rng.uniform(-np.pi, np.pi, 2)
        T = np.eye(4)
        T[:3, :3] = _rz(y) @ _ry(pitch) @ _rx(r)
        T[:3, 3] = rng.normal(size=3)
        rpy = ET.fromstring(_origin(T)).get("rpy")
        xyz = ET.fromstring(_origin(T)).get("xyz")
        r2, p2, y2 = map(float, rpy.split())
        np.testing.assert_allclose(_rz(y2) @ _ry(p2) @ _rx(r2), T[:3, :3], atol=1e-14)
        np.testing.assert_allclose(np.array(xyz.split(), dtype=float), T[:3, 3], atol=1e-15)


def _rx(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
