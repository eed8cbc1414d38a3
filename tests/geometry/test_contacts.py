"""qpik.geometry.contacts: a base on its table is no failure anywhere (plan checks, controller, sim log), and is
reported."""

from __future__ import annotations

import numpy as np

import qpik
from qpik.geometry.contacts import capsule_facts, capsule_pairs
from qpik.geometry.distance import ObstacleSet, distances
from qpik.geometry.shapes import HalfSpace, Sphere
from qpik.sim import simulate

TABLE = HalfSpace(np.array([0.0, 0.0, 1.0]), 0.05, name="table")  # z <= 0.05: through the base column


def _line(robot, q0, dq, n):
    return robot.fk(q0 + np.linspace(0.0, 1.0, n)[:, None] * dq)


def test_a_pair_is_checked_unless_its_distance_is_constant():
    robot = qpik.load_robot("iiwa14")
    ball = Sphere(np.array([0.5, 0.0, 0.6]), 0.1, name="ball")
    mask = capsule_pairs(robot, [TABLE, ball])
    # dense sampling: a pair left out has the same distance everywhere, a checked pair does not
    g = np.random.default_rng(3)
    q = robot.q_min + (robot.q_max - robot.q_min) * g.random((400, robot.dof))
    d = distances(robot.capsule_segments(q), robot.capsule_radii, ObstacleSet([TABLE, ball])).d
    spread = np.ptp(d, axis=0)
    assert np.all(spread[~mask] < 1e-9) and np.all(spread[mask] > 1e-6)
    assert not mask[0, 0] and not mask[:2].any()  # the base column on the table; the two capsules no joint moves
    assert mask[~robot.fixed_capsules].all()  # every capsule a joint moves, against either


def test_iiwa_on_a_table_through_its_base_column_plans_and_reports_the_fact():
    robot = qpik.load_robot("iiwa14")
    q0 = np.array([0.3, 0.5, 0.2, -1.2, 0.1, 0.8, 0.0])
    T = _line(robot, q0, np.full(7, 0.15), 12)
    plan = qpik.plan_self_motion(
        robot, T, obstacles=[TABLE], options=qpik.PlanOptions(refine=False)
    )  # MuJoCo check included
    assert plan.ok and plan.status == "dp", plan.summary()
    names = {c.name for c in plan.checks}
    assert {"clearance", "clearance_mujoco"} <= names
    facts = " ".join(plan.facts)
    assert "touches table: -130 mm, constant, not checked" in facts, plan.facts
    assert [str(f) for f in capsule_facts(robot, [TABLE])] == plan.facts


def test_nammoto7_on_a_table_the_controller_does_not_say_penetrating():
    robot = qpik.load_robot("nammoto7")
    assert not robot.fixed_capsules[0]  # its base column turns with joint 1
    assert not capsule_pairs(robot, [TABLE])[0, 0]
    q0 = robot.q_home
    target = robot.fk(q0 + np.array([0.3, 0.1, -0.1, 0.1, 0.2, 0.1, 0.0]))
    ctrl = qpik.Controller.for_robot(robot, target=target, obstacles=[TABLE], dt=0.005)
    log = simulate(robot, ctrl, q0, 0.5, 0.005, obstacles=[TABLE], target=target)
    statuses = set(log.status.tolist())
    assert "penetrating" not in statuses and "failed" not in statuses, statuses
    assert np.isfinite(ctrl.last.min_clearance) and ctrl.last.min_clearance > 0
    # the sim log leaves out the same kind of pair (MuJoCo geoms) and says so
    assert log.checked is not None and not log.checked.all()
    assert log.facts and all("not checked" in f for f in log.facts)
    assert np.all(log.summary().min_clearance > 0)


def test_nammoto7_on_a_table_plans_its_turning_base_column_is_a_fact():
    robot = qpik.load_robot("nammoto7")
    T = _line(robot, robot.q_home, np.full(7, 0.1), 8)
    plan = qpik.plan_self_motion(
        robot, T, obstacles=[TABLE], options=qpik.PlanOptions(refine=False)
    )  # MuJoCo check included
    assert plan.ok, plan.summary()
    assert any("touches table" in f for f in plan.facts)


def test_nammoto7_on_a_table_the_path_nlp_refines_its_plan():
    """The path NLP leaves the constant pairs out too. With the base column's constant -0.11 m to the table among
    its constraints, IPOPT starts infeasible and stops near the DP's plan (4e-5 better); without it, it climbs
    the margin (4e-4 better)."""
    robot = qpik.load_robot("nammoto7")
    T = _line(robot, robot.q_home, np.full(7, 0.1), 8)
    plan = qpik.plan_self_motion(robot, T, "smooth-margin", [TABLE], options=qpik.PlanOptions(mujoco=False))
    assert plan.ok and plan.label == "NLP" and plan.cost < plan.dp_cost - 1e-4, plan.summary()
