"""plan_self_motion on the Panda runs the DP over its locked-q7 closed form (then the path NLP), and the plan
follows the path by FK to 1e-9, inside the limits."""

from __future__ import annotations

import numpy as np

import qpik


def test_the_panda_plans_with_the_dp_in_q7():
    robot = qpik.load_robot("panda")
    q0 = np.array([0.2, -0.5, 0.1, -2.0, 0.2, 1.7, 0.4])
    path = robot.fk(q0 + np.linspace(0.0, 1.0, 12)[:, None] * np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.2, 0.3]))
    plan = qpik.plan_self_motion(robot, path, "margin", options=qpik.PlanOptions(mujoco=False))
    assert plan.status in ("optimal", "dp") and plan.ok, plan.summary()
    assert plan.param_name == "q7" and "dp" in plan.timings
    assert np.abs(robot.fk(plan.q) - path).max() < 1e-9
    assert robot.within_limits(plan.q).all()
    np.testing.assert_array_equal(plan.param, plan.q[:, 6])
