"""The built-in arms against sources qpik did not write: ssik's models, datasheets, Table 4 of Nammoto & Kosuge 2012."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ARMS, SEEDS, random_q
from hypothesis import given, settings

import qpik
from qpik.core.errors import UnknownRobotError
from qpik.core.validate import project_to_so3
from qpik.problems import load, problems_folder

ssik_kuka = pytest.importorskip("ssik.prebuilt.kuka.iiwa14_ik")
ssik_franka = pytest.importorskip("ssik.prebuilt.franka.panda_ik")
SSIK = {"iiwa14": ssik_kuka, "panda": ssik_franka}


def test_load_robot_returns_one_object_per_name():
    assert qpik.load_robot("iiwa14") is qpik.load_robot("iiwa14")
    assert set(qpik.CATALOG) == set(ARMS)


def test_unknown_robot_names_the_known_ones():
    with pytest.raises(UnknownRobotError, match="known: nammoto7, iiwa14, zheng7, panda"):
        qpik.load_robot("ur5")
    with pytest.raises(KeyError):
        qpik.load_robot("ur5")


def test_limits_home_and_capsules_are_consistent(robot):
    assert robot.dof == 7
    for name in ("q_min", "q_max", "v_max", "q_home"):
        assert getattr(robot, name).shape == (7,), name
    assert np.all(robot.q_min < robot.q_max)
    assert np.all(robot.v_max > 0)
    assert robot.within_limits(robot.q_home)
    assert len(robot.capsules) == 7 and np.all(robot.capsule_radii > 0)


@settings(max_examples=3, deadline=None)
@given(seed=SEEDS)
def test_capsules_form_a_chain_from_base_to_ee(robot, seed):
    """Each capsule ends where the next begins (on the next joint's axis), the last one at the ee."""
    q = random_q(robot, 500, seed)
    seg = robot.capsule_segments(q)  # (N, 7, 2, 3)
    np.testing.assert_allclose(seg[:, 1:, 0], seg[:, :-1, 1], atol=1e-12)
    np.testing.assert_allclose(seg[:, -1, 1], robot.fk(q)[:, :3, 3], atol=1e-12)


def test_within_limits_batched_and_tolerance(robot):
    q = np.stack([robot.q_home, robot.q_max + 1e-3, robot.q_min - 1e-3])
    np.testing.assert_array_equal(robot.within_limits(q), [True, False, False])
    np.testing.assert_array_equal(robot.within_limits(q, tol=2e-3), [True, True, True])


@pytest.mark.parametrize("name", sorted(SSIK))
def test_limits_match_ssik(name):
    robot = qpik.load_robot(name)
    lo, hi = np.array(SSIK[name]._JOINT_LIMITS).T
    np.testing.assert_allclose(robot.q_min, lo, atol=1e-4)
    np.testing.assert_allclose(robot.q_max, hi, atol=1e-4)


@pytest.mark.parametrize("name", sorted(SSIK))
@settings(max_examples=2, deadline=None)
@given(seed=SEEDS)
def test_fk_matches_ssik(name, seed):
    """ssik builds its FK from the URDF (product of exponentials), not from a DH table."""
    robot = qpik.load_robot(name)
    q = random_q(robot, 300, seed)
    ref = np.array([SSIK[name].fk(qi) for qi in q])
    np.testing.assert_allclose(robot.fk(q), ref, atol=1e-12, rtol=0)


def test_zero_configurations_match_datasheets():
    # iiwa 14 R820 stands straight up at q = 0: 0.36 + 0.42 + 0.40 + 0.126 m
    np.testing.assert_allclose(qpik.load_robot("iiwa14").fk(np.zeros(7)), _pose(np.eye(3), (0, 0, 1.306)), atol=1e-12)
    # Panda flange at q = 0: x = a7 = 0.088, z = 0.333 + 0.316 + 0.384 - 0.107, pointing down
    np.testing.assert_allclose(
        qpik.load_robot("panda").fk(np.zeros(7)), _pose(np.diag([1.0, -1, -1]), (0.088, 0, 0.926)), atol=1e-12
    )


def test_nammoto7_reproduces_table_4_of_seed_000():
    """Every row of Table 4 (2 decimals) reaches the pose of eqs. (33)-(36) within its rounding."""
    problem = load(problems_folder() / "nammoto2012_table4.toml")
    rounded_R = np.array([[0.18, 0.63, 0.76], [-0.16, 0.78, -0.61], [-0.97, -0.01, 0.25]])  # columns n, t, b
    p = np.array([-0.18, 0.41, 0.41])
    R = project_to_so3(rounded_R)
    T = problem.robot.fk(problem.expected["q"])
    assert T.shape == (16, 4, 4)
    assert np.all(np.linalg.norm(T[:, :3, 3] - p, axis=1) < 0.01)
    cos = (np.trace(np.swapaxes(T[:, :3, :3], 1, 2) @ R, axis1=1, axis2=2) - 1) / 2
    assert np.all(np.arccos(np.clip(cos, -1, 1)) < 0.02)
    # the rounded rotation is not far from its projection either: the paper is self-consistent
    assert np.abs(rounded_R - R).max() < 0.01


def _pose(R: np.ndarray, p: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


@pytest.mark.parametrize("tol", [np.nan, -1e-3, np.inf, "0.1", None])
def test_within_limits_tolerance_must_be_a_finite_number_at_least_zero(tol):
    robot = qpik.load_robot("iiwa14")
    with pytest.raises(qpik.InputError, match=r"^tol"):
        robot.within_limits(robot.q_home, tol=tol)
