"""The planning problem files (kind ``plan``) and their runner, checked by code of this file.

Every file: FK of the plan reaches every waypoint to 1e-9 (FK here), no joint outside its limits, every link
capsule at least d_s from every obstacle (capsule distances and MuJoCo's ``mj_geomDistance`` on the twin),
every continuous joint step within its bound, and the NLP's objective, recomputed here from the plan's
configurations, at most the DP's. The joint-limit sweep of Nammoto & Kosuge 2012 (Figs. 15-16): the plan stays
inside the limits where δ = 0 leaves them, and its joint path is no longer than either constant-δ path.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import qpik
from qpik.planning.baselines import constant_parameter
from qpik.problems import find_problem, list_problems, load, run_problem
from qpik.problems.plan import plan_problem, waypoints
from qpik.sim import build_scene

# --dist loadgroup: one worker runs the whole module, so its module- and session-scoped fixtures are built once
pytestmark = pytest.mark.xdist_group("problems_plan")

PLANS = [p for p in list_problems() if p.kind == "plan"]


@pytest.fixture(scope="module")
def plans():
    return {p.name: (p, plan_problem(p)) for p in PLANS}


def _objective(problem, q: np.ndarray) -> np.ndarray:
    """The point objective of the problem's [solver] at q (N, n), written here: 0, or the weighted margin."""
    s = problem.solver
    if s["objective"] == "none":
        return np.zeros(len(q))
    assert s["objective"] == "margin"
    lo, hi = problem.robot.q_min, problem.robot.q_max
    half = (hi - lo) / 2
    return -s["objective_weight"] * np.minimum((q - lo) / half, (hi - q) / half).min(axis=1)


def _J(problem, q: np.ndarray, reconfigurations) -> float:
    """Σ ‖Δq‖²/Δ over the continuous transitions + Σ w_k f(q_k) (trapezoid weights of the progress)."""
    poses, times = waypoints(problem)
    s = times if times is not None else np.linspace(0.0, 1.0, len(poses))
    d = np.diff(s)
    w = np.r_[d / 2, 0.0] + np.r_[0.0, d / 2]
    D = np.diff(q, axis=0)
    keep = np.ones(len(D), bool)
    keep[list(reconfigurations)] = False
    return float(np.sum(keep * (D * D).sum(axis=1) / d) + np.sum(w * _objective(problem, q)))


def _mujoco_clearance(problem, q: np.ndarray) -> float:
    scene = build_scene(problem.robot, problem.obstacles)
    m, data = scene.kin.model, scene.kin.data
    out = np.inf
    for qk in q:
        scene.kin.update(qk)
        for g in scene.link_geoms:
            for o in scene.obstacle_geoms:
                out = min(out, mujoco.mj_geomDistance(m, data, int(g), int(o), 10.0, None))
    return out


def test_there_are_the_planning_problems_of_the_issue():
    names = {p.name for p in PLANS}
    assert {"nammoto2012_joint_limits_plan", "nammoto2012_obstacle_plan", "iiwa_wiping_plan",
            "iiwa_reconfiguration_plan", "zheng7_plan"} <= names  # fmt: skip


@pytest.mark.parametrize("name", [p.name for p in PLANS])
def test_every_plan_follows_its_path_inside_the_limits_and_clear(plans, name):
    problem, plan = plans[name]
    poses, _ = waypoints(problem)
    assert plan.status in ("optimal", "dp") and len(plan.q) == len(poses), plan.summary()
    F = problem.robot.fk(plan.q)
    assert np.abs(F[:, :3, 3] - poses[:, :3, 3]).max() <= 1e-9
    cosang = (np.trace(np.swapaxes(poses[:, :3, :3], 1, 2) @ F[:, :3, :3], axis1=1, axis2=2) - 1) / 2
    assert np.arccos(np.clip(cosang, -1, 1)).max() <= 1e-6  # arccos: 1e-9 rad shows as ~1e-8 near 1
    assert np.abs(F[:, :3, :3] - poses[:, :3, :3]).max() <= 1e-9
    assert np.all(plan.q >= problem.robot.q_min) and np.all(plan.q <= problem.robot.q_max)
    d_s = problem.solver["d_safe"]
    if problem.obstacles:
        d = qpik.geometry.distances(problem.robot.capsule_segments(plan.q), problem.robot.capsule_radii,
                                    problem.obstacles).d  # fmt: skip
        assert d.min() >= d_s
        assert _mujoco_clearance(problem, plan.q) >= d_s - 1e-9
    steps = np.abs(np.diff(plan.q, axis=0))
    keep = np.ones(len(steps), bool)
    keep[plan.reconfigurations] = False
    assert np.all(steps[keep] <= plan.step_bound[keep] + 1e-9)
    assert plan.ok, [c.text for c in plan.checks if not c.ok]


@pytest.mark.parametrize("name", [p.name for p in PLANS])
def test_the_nlp_objective_is_at_most_the_dp_objective(plans, name):
    problem, plan = plans[name]
    J = _J(problem, plan.q, plan.reconfigurations)
    assert pytest.approx(plan.cost, rel=1e-9, abs=1e-12) == J
    start = plan.dp_plan  # the DP's plan (closed form) or the QP controller's run (zheng7)
    assert start is not None and plan.status == "optimal"
    J0 = _J(problem, start.q, start.reconfigurations)
    assert pytest.approx(plan.dp_cost if problem.robot.closed_form else start.cost, rel=1e-9) == J0
    assert J <= J0


def test_the_reconfiguration_case_needs_one_stop_and_forbid_says_where_and_why(plans):
    problem, plan = plans["iiwa_reconfiguration_plan"]
    assert len(plan.reconfigurations) == int(problem.expected["reconfigurations"])
    poses, times = waypoints(problem)
    forbid = qpik.plan_self_motion(
        problem.robot,
        poses,
        None,
        problem.obstacles,
        times=times,
        options=qpik.PlanOptions(max_joint_step=0.1, reconfigure="forbid", refine=False, mujoco=False),
    )
    assert forbid.status == "failed" and 0 < forbid.failure_waypoint < len(poses)
    assert "joint" in forbid.failure and len(forbid.q) == forbid.failure_waypoint


def test_joint_limit_sweep_beats_both_constant_delta_baselines(plans):
    """Nammoto & Kosuge 2012, Figs. 15-16, with the limits of the problem file."""
    problem, plan = plans["nammoto2012_joint_limits_plan"]
    robot = problem.robot
    zero, seventy = (constant_parameter(plan, v, 1, mujoco=False) for v in (0.0, 0.70))
    outside = ~robot.within_limits(zero.q)
    assert outside.sum() >= 10  # δ = 0 leaves the limits (θ6 as p_z falls) ...
    assert robot.within_limits(plan.q[outside]).all()  # ... where the plan stays inside
    length = lambda q: np.linalg.norm(np.diff(q, axis=0), axis=1).sum()  # noqa: E731
    assert length(plan.q) <= length(zero.q) and length(plan.q) <= length(seventy.q)


def test_the_runner_reports_the_numbers_and_writes_the_files(tmp_path):
    problem = load(find_problem("nammoto2012_joint_limits_plan"))
    report = run_problem(problem, tmp_path)
    assert "Overall: PASS" in report
    for label in ("| NLP |", "| DP |", "| constant δ = 0 (branch 1) |", "| constant δ = 0.7 (branch 1) |",
                  "| QP controller (online) |"):  # fmt: skip
        assert label in report
    assert "FK reproduces every waypoint" in report and "NLP objective" in report and "≤ DP objective" in report
    row = next(ln for ln in report.splitlines() if ln.startswith("| constant δ = 0 ("))
    assert int(row.split("|")[3].split()[0]) > 0  # its waypoints outside the limits are counted
    for suffix in ("_plan.csv", "_plan.npz", "_joints.png", "_map.png"):
        assert (tmp_path / f"{problem.name}{suffix}").stat().st_size > 0
    data = np.load(tmp_path / f"{problem.name}_plan.npz")
    rows = np.loadtxt(tmp_path / f"{problem.name}_plan.csv", delimiter=",", skiprows=1)
    assert np.array_equal(rows[:, 2:9], data["q"]) and data["q"].shape == (61, 7)
    F = problem.robot.fk(data["q"])
    assert np.abs(F - problem.poses).max() <= 1e-9
