"""Robot: which capsules no joint moves, against finite differences of the capsules' end points."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEEDS, random_q
from hypothesis import given, settings

import qpik
from qpik.robots import CATALOG


@pytest.mark.parametrize("name", sorted(CATALOG))
@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_fixed_capsules_are_those_no_joint_moves(name, seed):
    """A capsule is fixed iff no joint's small rotation moves either end point (central differences)."""
    robot = qpik.load_robot(name)
    q = random_q(robot, 1, seed, margin=0.01)[0]
    h = 1e-6
    moves = np.zeros(len(robot.capsules), bool)
    for j in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[j] = h
        rate = (robot.capsule_segments(q + dq) - robot.capsule_segments(q - dq)) / (2 * h)  # (C, 2, 3), m/rad
        moves |= np.abs(rate).max(axis=(1, 2)) > 1e-6
    np.testing.assert_array_equal(robot.fixed_capsules, ~moves)


def test_a_first_link_on_the_first_axis_is_fixed():
    """The iiwa's first capsule lies on joint 1's axis, its second is a ball at the shoulder (on joints 1's and
    2's axes): both fixed; the capsules from the upper arm on are not."""
    iiwa = qpik.load_robot("iiwa14")
    a, b = iiwa.capsule_segments(iiwa.q_home)[0]
    assert np.allclose(a[:2], 0) and np.allclose(b[:2], 0)  # on the z axis, joint 1's axis
    assert iiwa.fixed_capsules[:2].all() and not iiwa.fixed_capsules[2:].any()


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_with_home_gives_a_new_robot_with_its_own_cache(seed):
    """with_home changes only the home configuration; the new robot's cache starts empty and its answers agree."""
    robot = qpik.load_robot("panda")
    robot.fk(robot.q_home)
    q = random_q(robot, 1, seed, margin=0.01)[0]
    moved = robot.with_home(q)
    np.testing.assert_array_equal(moved.q_home, q)
    np.testing.assert_array_equal(robot.q_home, qpik.load_robot("panda").q_home)
    assert moved.cache is not robot.cache
    np.testing.assert_allclose(moved.fk(q), robot.fk(q), atol=1e-12)


def test_with_home_refuses_a_bad_configuration():
    robot = qpik.load_robot("iiwa14")
    outside = robot.q_home.copy()
    outside[3] = robot.q_max[3] + 0.1
    for bad, match in (([0.0] * 6, "shape"), ([np.nan] * 7, "q_home"), (outside, "joints 4 outside")):
        with pytest.raises(qpik.InputError, match=match):
            robot.with_home(bad)
