"""qpik.solve_best on the arms whose slots are found per pose (qpik.nlp.best_sampled): Baxter's right arm and the Sawyer
(the 1-D search), the TIAGo Pro's arm (the general 6-R), files from example-robot-data and robosuite.

The reference is independent of the module: every slot of qpik.ik at a dense grid of the locked joint (this file's
own, 2001 values over its limits; 8001 in the large run), the margin or the distance computed here from the
limits, and the answer's configuration checked by MuJoCo's FK of the file.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, model_robot, mujoco_poses, random_q

import qpik
from qpik.analytic.api import closed_form_for
from qpik.core.errors import InputError
from qpik.geometry import Sphere
from qpik.nlp import solve_best
from qpik.nlp.options import BestOptions
from qpik.scene import Scene

DENSE = 8001 if LARGE else 1001
CASES = [("erd_baxter", k) for k in range(20 if LARGE else 1)]
CASES += [("robosuite_sawyer", k) for k in range(6 if LARGE else 0)]
CASES += [("erd_tiago_pro", k) for k in range(10 if LARGE else 1)]
"""The Sawyer (a near member: a search of milliseconds at the suite's -O0, 1,001 of them) in the large run only."""


def margin(robot: qpik.Robot, q: np.ndarray) -> np.ndarray:
    """The smallest distance to a joint limit over the joint's half range, of q (..., n)."""
    half = 0.5 * (robot.q_max - robot.q_min)
    return np.min(np.minimum(q - robot.q_min, robot.q_max - q) / half, axis=-1)


def dense(robot: qpik.Robot, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every slot's configuration at DENSE values of the locked joint over its limits where it is valid inside the
    limits: (K, n)."""
    locked = closed_form_for(robot).locked
    t = np.linspace(robot.q_min[locked], robot.q_max[locked], DENSE)
    sols = qpik.ik(robot, np.broadcast_to(T, (DENSE, 4, 4)), t)
    return sols.q[sols.valid & sols.within_limits]


def check_answer(robot: qpik.Robot, T: np.ndarray, res) -> None:
    """An optimal answer reaches the pose by MuJoCo's FK of the file, inside the limits, and says it is not
    certified."""
    assert res.status == "optimal", res.message
    assert not res.certified and "not certified" in res.summary() and "sampled" in res.message
    np.testing.assert_allclose(mujoco_poses(robot, res.q[None])[0], T, atol=1e-9)
    assert robot.within_limits(res.q)


@pytest.mark.parametrize("key, seed", CASES)
def test_the_best_margin_is_at_least_the_densely_sampled_best(key, seed):
    """The issue's check: the objective is ≤ the dense-sampled best + 1e-8 (a basin that the module's own samples
    miss shows here), and the margin reported is the margin of the answer's q."""
    robot = model_robot(key)
    T = mujoco_poses(robot, random_q(robot, 1, 100 + seed))[0]
    res = solve_best(robot, T)
    check_answer(robot, T, res)
    assert res.reported == pytest.approx(margin(robot, res.q), abs=1e-12)
    assert res.reported >= margin(robot, dense(robot, T)).max() - 1e-8
    assert res.param == res.q[closed_form_for(robot).locked]
    row = next(r for r in res.branches if r.branch == res.branch)
    assert row.objective == res.objective and row.param == res.param


@pytest.mark.skipif(not LARGE, reason="the large run: QPIK_TESTS_LARGE=1")
def test_the_best_distance_to_a_reference_is_at_least_the_densely_sampled_best():
    """A smooth objective whose minimum often lies at the end of a slot's feasible stretch: ½|q − q_ref|²."""
    robot = model_robot("erd_baxter")
    for seed in range(4):
        q, q_ref = random_q(robot, 2, 200 + seed)
        T = mujoco_poses(robot, q[None])[0]
        res = solve_best(robot, T, "distance", q_ref=q_ref)
        check_answer(robot, T, res)
        assert res.objective == pytest.approx(0.5 * np.sum((res.q - q_ref) ** 2), abs=1e-12)
        assert res.objective <= 0.5 * np.sum((dense(robot, T) - q_ref) ** 2, axis=1).min() + 1e-8


def test_an_obstacle_is_kept_at_d_safe_and_can_only_cost_margin():
    """A sphere where the free answer's elbow is: the new answer keeps every capsule d_s from it (measured by the
    scene's capsule distances) and its margin is no larger than the free answer's."""
    robot = model_robot("erd_baxter")
    T = mujoco_poses(robot, random_q(robot, 1, 101))[0]
    free = solve_best(robot, T)
    elbow = mujoco_poses(robot, free.q[None], body="right_lower_elbow")[0][:3, 3]
    scene = Scene.of(robot, [Sphere(elbow, 0.05)], d_safe=0.02)
    assert scene.clearance(free.q[None])[0] < 0.0  # the free answer's elbow is inside the sphere
    res = solve_best(scene, T)
    check_answer(robot, T, res)
    assert scene.clearance(res.q[None])[0] >= 0.02 - 1e-9 and res.clearance >= 0.02 - 1e-9
    assert res.reported <= free.reported + 1e-12


def test_a_pose_out_of_reach_is_not_found_and_proves_nothing():
    """No slot reaches the pose at any sample: ``"not found"`` (never "unreachable": nothing is proved), a finite q,
    an objective of +inf and the distance to the pose as the violation."""
    robot = model_robot("erd_baxter")
    T = robot.fk(robot.q_home)
    T[:3, 3] += (3.0, 0.0, 0.0)
    res = solve_best(robot, T)
    assert res.status == "not found" and "nothing proved" in res.message
    assert np.isfinite(res.q).all() and res.objective == np.inf and res.violation > 2.0
    assert not any(r.feasible for r in res.branches)


def test_the_branches_option_searches_only_those_slots():
    """Asked for one slot, the answer is that slot's (or none), the others are "skipped" in the table; it is no better
    than the answer over every slot."""
    robot = model_robot("erd_baxter")
    T = mujoco_poses(robot, random_q(robot, 1, 102))[0]
    every = solve_best(robot, T)
    slot = next(r.branch for r in every.branches if r.feasible and r.branch != every.branch)
    one = solve_best(robot, T, options=BestOptions(branches=[slot]))
    check_answer(robot, T, one)
    assert one.branch == slot and one.objective >= every.objective
    assert [r.searched for r in one.branches] == [r.branch == slot for r in one.branches]
    assert qpik.redundancy_parameter(robot, one.q)[1] == slot


def test_bad_options_name_what_is_wrong():
    robot = model_robot("erd_baxter")
    T = robot.fk(robot.q_home)
    with pytest.raises(InputError, match="method: 'levelset'"):
        solve_best(robot, T, options=BestOptions(method="levelset"))
    with pytest.raises(InputError, match="branches"):
        solve_best(robot, T, options=BestOptions(branches=[16]))
