"""The DP's grid of an arm whose branches the 1-D search finds (qpik.planning.search_grid) on robosuite's Sawyer:
every state reaches its pose by MuJoCo's FK of the file at its grid value of q1, its feasibility is the joint limits and
the clearance by qpik.geometry's distances (numpy), its objective the joint-limit margin computed here; the DP on it
equals the minimum found by enumerating every sequence of states; plan_self_motion uses it and follows the path, there
and on example-robot-data's TIAGo Pro arm (the general 6-R's family)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import model_robot, mujoco_poses, random_q

import qpik
from qpik.geometry import Sphere
from qpik.geometry.distance import distances
from qpik.objectives import JointLimitMargin
from qpik.planning import dp
from qpik.planning.search_grid import SearchGrid
from qpik.scene import Scene

SAWYER = "robosuite_sawyer"


def _path(robot: qpik.Robot, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Configurations along a joint-space line inside the limits and their poses by MuJoCo: (n, 7), (n, 4, 4)."""
    q0 = random_q(robot, 1, seed, margin=0.6)[0]
    dq = np.random.default_rng(seed).uniform(-0.3, 0.3, robot.dof)
    Q = q0 + np.linspace(0.0, 1.0, n)[:, None] * dq
    return Q, mujoco_poses(robot, Q)


def test_the_states_are_the_searched_branches_inside_the_limits_and_clear():
    robot = model_robot(SAWYER)
    _, T = _path(robot, 3, 11)
    q_mid = robot.q_min + 0.5 * (robot.q_max - robot.q_min)
    ball = Sphere(tuple(robot.frames(q_mid)[4, :3, 3] + np.array([0.0, 0.0, 0.15])), 0.1)
    grid = SearchGrid(Scene.of(robot, [ball], d_safe=0.03, objective=JointLimitMargin()), T, 16, progress=False)
    layers = grid.layers(0, 3)
    assert grid.intervals is None and grid.param_name == "q1" and grid.rows == 16
    for k in range(3):
        q = layers.q[k][grid.inside[k]]  # (M, 7), every state inside the limits the search found
        assert len(q) and robot.within_limits(q).all()
        np.testing.assert_allclose(mujoco_poses(robot, q), np.broadcast_to(T[k], (len(q), 4, 4)), atol=1e-9)
        values = np.broadcast_to(grid.values, grid.inside[k].shape)[grid.inside[k]]
        np.testing.assert_allclose((q[:, 0] - values + np.pi) % (2 * np.pi) - np.pi, 0.0, atol=1e-12)
        d = distances(robot.capsule_segments(q)[:, ~robot.fixed_capsules], robot.capsule_radii[~robot.fixed_capsules],
                      [ball]).d.min(axis=(1, 2))  # fmt: skip
        own = Scene.of(robot).self_clearance(q)
        clear = np.minimum(d, own) >= 0.03
        assert np.array_equal(layers.ok[k][grid.inside[k]], clear) and clear.sum() > 0
        half = 0.5 * (robot.q_max - robot.q_min)
        margin = np.min(np.minimum(q - robot.q_min, robot.q_max - q) / half, axis=1)
        np.testing.assert_allclose(layers.f[k][grid.inside[k]][clear], -margin[clear], atol=1e-12)


def test_the_dp_on_the_search_grid_equals_the_brute_force_minimum():
    """Three waypoints, 8 values of q1 × 16 slots: the DP's cost is the least Σ ‖Δq‖² over every sequence of states
    within the joint-step bound, found by enumeration."""
    robot = model_robot(SAWYER)
    _, T = _path(robot, 3, 12)
    grid = SearchGrid(Scene.of(robot), T, 8, progress=False)
    layers = grid.layers(0, 3)
    tr = dp.Transitions(np.full((2, 7), 0.4), np.ones(2), np.ones(3))  # no objective: f = 0 where feasible
    res = dp.solve(grid, tr, grid.G // 2, fewest=False, progress=False)
    S = grid.rows * grid.G
    q, ok = layers.q.reshape(3, S, -1), layers.ok.reshape(3, S)
    D01 = q[1][None] - q[0][:, None]
    D12 = q[2][None] - q[1][:, None]
    fit01, fit12 = (np.abs(D01) <= 0.4).all(-1), (np.abs(D12) <= 0.4).all(-1)
    c = (D01 * D01).sum(-1)[:, :, None] + (D12 * D12).sum(-1)[None]
    live = ok[0][:, None, None] & ok[1][None, :, None] & ok[2][None, None] & fit01[:, :, None] & fit12[None]
    assert live.any()
    assert res.failure is None and res.cost == pytest.approx(c[live].min(), abs=1e-12)


@pytest.mark.parametrize("key, locked", [(SAWYER, "q1"), ("erd_tiago_pro", "q7")])
def test_plan_self_motion_runs_the_dp_and_follows_the_path(key, locked):
    """On the Sawyer (the 1-D search) and example-robot-data's TIAGo Pro arm (the general 6-R with q7 locked)."""
    robot = model_robot(key)
    _, path = _path(robot, 8, 13)
    plan = qpik.plan_self_motion(robot, path, "margin", options=qpik.PlanOptions(mujoco=False, resolution=16))
    assert plan.status in ("optimal", "dp") and plan.ok, plan.summary()
    assert plan.param_name == locked and "dp" in plan.timings
    dp_plan = plan if plan.status == "dp" else plan.dp_plan
    assert dp_plan.label == "DP" and plan.cost <= dp_plan.cost
    np.testing.assert_allclose(mujoco_poses(robot, plan.q), path, atol=1e-9)
    assert robot.within_limits(plan.q).all()
    j = int(locked[1:]) - 1
    np.testing.assert_allclose(plan.param, (plan.q[:, j] + np.pi) % (2 * np.pi) - np.pi, atol=1e-15)
    for k in range(len(path)):  # each waypoint's slot holds its configuration
        sols = qpik.ik(robot, path[k], plan.q[k, j])
        assert np.abs((sols.q[plan.branch[k]] - plan.q[k] + np.pi) % (2 * np.pi) - np.pi).max() < 1e-9
    assert (np.abs(np.diff(plan.q, axis=0)) <= 0.1 + 1e-9).all()


def test_a_pose_out_of_reach_is_a_grid_failure_never_a_proof():
    robot = model_robot(SAWYER)
    _, path = _path(robot, 3, 14)
    path[0, :3, 3] += 5.0
    plan = qpik.plan_self_motion(robot, path, options=qpik.PlanOptions(mujoco=False, resolution=8))
    assert plan.status == "failed" and plan.failure_waypoint == 0 and plan.failure_kind == "grid"
    assert "the search finds no branch inside the joint limits at the 8 grid values of q1" in plan.failure
