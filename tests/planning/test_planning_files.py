"""plan_self_motion on third-party model files of the locked-joint family (a Panda, the Jaco read from the flange, and
the xArm7, a near member): the DP runs over the closed form's branches along the locked joint, and the plan follows
the path by MuJoCo's FK of the file to 1e-9, inside the limits, its parameter the locked joint itself."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import model_robot, mujoco_poses, random_q

import qpik


@pytest.mark.parametrize("key", ["erd_panda", "robosuite_jaco", "erd_xarm7"])
def test_a_file_plans_with_the_dp_along_its_locked_joint(key: str):
    robot = model_robot(key)
    start = random_q(robot, 1, 11, margin=0.3)[0]
    step = np.random.default_rng(5).uniform(-0.25, 0.25, robot.dof)
    path = mujoco_poses(robot, start + np.linspace(0.0, 1.0, 12)[:, None] * step)
    scene = qpik.Scene.of(robot, objective="margin", self_collision=False)
    plan = qpik.plan_self_motion(scene, path, options=qpik.PlanOptions(mujoco=False))
    assert robot.closed_form == "locked_joint" and "dp" in plan.timings
    assert plan.status in ("optimal", "dp") and plan.ok, plan.summary()
    assert np.abs(mujoco_poses(robot, plan.q) - path).max() < 1e-9
    assert robot.within_limits(plan.q).all()
    locked = int(plan.param_name[1:]) - 1
    np.testing.assert_allclose(np.cos(plan.param), np.cos(plan.q[:, locked]), atol=1e-12)
    np.testing.assert_allclose(np.sin(plan.param), np.sin(plan.q[:, locked]), atol=1e-12)
