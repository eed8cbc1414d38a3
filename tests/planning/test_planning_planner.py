"""qpik.plan_self_motion on small paths: bad input is reported (which waypoint and why, the least-violating option),
the retimed plan keeps its limits (toppra), its files hold the plan, a timed path is sampled, and the plan of an
arm without a closed form reaches every waypoint where the QP controller's run only tracks them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import qpik
from qpik.geometry import Sphere
from qpik.geometry.paths import WaypointPath
from qpik.nlp.options import BestOptions

IIWA, NAMMOTO, ZHENG = (qpik.load_robot(n) for n in ("iiwa14", "nammoto7", "zheng7"))


def _line(robot, q0, dq, N):
    """FK of configurations moving in a straight line in joint space: a reachable path (N, 4, 4)."""
    return robot.fk(q0 + np.linspace(0.0, 1.0, N)[:, None] * dq)


def test_an_unreachable_waypoint_is_reported_with_which_and_why():
    T = _line(IIWA, IIWA.q_home, np.full(7, 0.2), 12)
    T[7, :3, 3] = (2.0, 0.0, 0.5)  # 2 m away: beyond the arm's reach
    plan = qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(mujoco=False))
    assert plan.status == "failed" and plan.failure_waypoint == 7 and len(plan.q) == 7
    assert "no branch reaches this pose" in plan.failure and plan.least_violating.startswith("unreachable")
    F = IIWA.fk(plan.q)  # the planned prefix is right
    assert np.abs(F - T[:7]).max() < 1e-9
    assert not plan.ok and "failed at waypoint 7" in plan.summary()


def test_a_waypoint_with_an_empty_feasible_set_gives_the_least_violating_option():
    # the elbow (joint 4) limited to ±0.5 rad: |θ4| is fixed by the shoulder–wrist distance at every ψ, so a
    # waypoint that needs |θ4| = 2 rad has no feasible configuration (but is reachable)
    lo, hi = IIWA.q_min.copy(), IIWA.q_max.copy()
    lo[3], hi[3] = -0.5, 0.5
    tight = dataclasses.replace(IIWA, q_min=lo, q_max=hi)
    q = np.array([0.1, 0.5, 0.1, -0.3, 0.1, 0.6, 0.1])
    T = _line(IIWA, q, np.full(7, 0.05), 10)
    T[4] = IIWA.fk(np.array([0.1, 0.5, 0.1, -2.0, 0.1, 0.6, 0.1]))
    plan = qpik.plan_self_motion(tight, T, options=qpik.PlanOptions(max_joint_step=0.3, mujoco=False))
    assert plan.status == "failed" and plan.failure_waypoint == 4
    assert "inside its limits" in plan.failure
    assert plan.least_violating.startswith("no feasible branch: least violating is branch")
    best = qpik.solve_best(tight, T[4], options=BestOptions(certify=False))
    assert best.status == "no feasible branch" and best.violation > 0


def test_obstacle_blocking_every_configuration_is_named():
    T = _line(IIWA, IIWA.q_home, np.full(7, 0.1), 6)
    hand = T[3, :3, 3]
    plan = qpik.plan_self_motion(IIWA, T, obstacles=[Sphere(hand, 0.05)], options=qpik.PlanOptions(mujoco=False))
    assert plan.status == "failed" and plan.failure_waypoint == 0  # the ball covers the hand everywhere near it
    assert "closer than d_s" in plan.failure
    # solve_best's word on the waypoint, proved by its certificate (every cell's clearance below d_s)
    assert plan.least_violating.startswith("no feasible branch: least violating is branch"), plan.least_violating


@pytest.mark.parametrize("bad, match", [
    (dict(max_joint_step=-1.0), "max_joint_step"), (dict(reconfigure="never"), "reconfigure"),
    (dict(resolution=7), "resolution"), (dict(a_max=5.0), "a_max"), (dict(branches=[99]), "branches"),
    (dict(times=[0.0, 1.0]), "times"), (dict(objective="distance"), "q_ref"), (dict(d_safe=np.nan), "d_safe"),
])  # fmt: skip
def test_bad_arguments_raise_input_errors_naming_them(bad, match):
    T = _line(IIWA, IIWA.q_home, np.full(7, 0.1), 5)
    own = {k: v for k, v in bad.items() if k in ("times", "objective", "d_safe")}
    options = qpik.PlanOptions(**{k: v for k, v in bad.items() if k not in own})
    with pytest.raises(qpik.InputError, match=match):
        qpik.plan_self_motion(IIWA, T, options=options, **own)
    with pytest.raises(qpik.InputError, match="path"):
        qpik.plan_self_motion(IIWA, T[0])
    with pytest.raises(qpik.InputError, match="options"):
        qpik.plan_self_motion(IIWA, T, options={"resolution": 72})


def test_retimed_plan_keeps_the_velocity_and_acceleration_limits_and_its_path():
    T = _line(NAMMOTO, NAMMOTO.q_home, np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.3, 0.4]), 30)
    plan = qpik.plan_self_motion(
        NAMMOTO, T, "smooth-margin", options=qpik.PlanOptions(max_joint_step=0.2, mujoco=False)
    )
    assert plan.ok
    v, a = NAMMOTO.v_max, 3.0 * NAMMOTO.v_max
    traj = plan.retime(v, a, samples=400)
    assert np.all(np.diff(traj.t) >= 0) and traj.duration == pytest.approx(traj.t[-1])
    assert (np.abs(traj.qd) / v).max() <= 1.01 and (np.abs(traj.qdd) / a).max() <= 1.01
    assert np.abs(traj.q[0] - plan.q[0]).max() < 1e-12 and np.abs(traj.q[-1] - plan.q[-1]).max() < 1e-12
    assert np.abs(traj.qd[[0, -1]]).max() < 1e-9  # from rest to rest
    # the samples follow the waypoints' joint path: each lies within one joint step of it
    gap = np.abs(traj.q[:, None, :] - plan.q[None]).max(axis=2).min(axis=1)
    assert gap.max() <= plan.step_bound.max()
    # time-optimal: some joint at its velocity or acceleration limit at almost every sample
    load = np.maximum(np.abs(traj.qd) / v, np.abs(traj.qdd) / a).max(axis=1)
    assert np.mean(load > 0.98) > 0.8


def test_the_plan_files_hold_the_plan(tmp_path):
    T = _line(IIWA, IIWA.q_home, np.full(7, 0.15), 8)
    plan = qpik.plan_self_motion(IIWA, T, obstacles=[Sphere((0.5, 0.5, 0.3), 0.05)])
    text = plan.to_csv(tmp_path / "p.csv")
    rows = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1)
    assert text.splitlines()[0].startswith("waypoint,progress,q1") and rows.shape == (8, 15)
    assert np.array_equal(rows[:, 2:9], plan.q) and np.array_equal(rows[:, 10], plan.branch)
    data = np.load(plan.to_npz(tmp_path / "p.npz"))
    assert np.array_equal(data["q"], plan.q) and np.array_equal(data["poses"], T)
    # the parameter and branch are the configuration's own (qpik.redundancy_parameter)
    psi, branch = qpik.redundancy_parameter(IIWA, plan.q)
    assert np.array_equal(branch, plan.branch) and np.abs(np.angle(np.exp(1j * (psi - plan.param)))).max() < 1e-9


def test_a_timed_path_is_sampled_and_its_times_bound_the_steps():
    T = _line(IIWA, IIWA.q_home, np.full(7, 0.3), 5)
    path = WaypointPath(T, np.array([0.0, 1.0, 2.0, 3.0, 4.0]))
    plan = qpik.plan_self_motion(IIWA, path, options=qpik.PlanOptions(waypoints=41, mujoco=False))
    assert len(plan.q) == 41 and plan.times is not None and plan.ok
    assert np.all(plan.step_bound <= IIWA.v_max * 0.1 + 1e-15)
    assert np.abs(IIWA.fk(plan.q) - path.pose(np.linspace(0, 4, 41))).max() < 1e-9


def test_an_arm_without_a_closed_form_reaches_every_waypoint_after_the_nlp():
    T = _line(ZHENG, ZHENG.q_home, np.array([0.3, -0.2, 0.2, 0.3, -0.2, 0.2, 0.3]), 15)
    times = np.linspace(0.0, 3.0, 15)
    plan = qpik.plan_self_motion(ZHENG, T, times=times)
    assert plan.status == "optimal" and plan.ok and plan.profile is None
    assert np.abs(ZHENG.fk(plan.q) - T).max() < 1e-9
    tracked = plan.dp_plan  # the QP controller's run: it lags behind the path
    assert tracked.label == "QP controller (online)" and max(tracked.fk_error) > 1e-6
    assert plan.cost <= tracked.cost


def test_the_stage_times_count_no_building_of_functions(monkeypatch):
    """A fresh arm builds the grid's, the DP's and the NLP's functions within the call; the plan's stage times count
    none of it (no compiled function is made while a stage's clock runs) and add up to less than the call."""
    import time

    from qpik.core.stopwatch import Stopwatch
    from qpik.native.compiled import Compiled
    from qpik.robots.catalog import CATALOG

    watches, built = [], []
    make_watch, make_compiled = Stopwatch.__init__, Compiled.__init__

    def watch(self):
        make_watch(self)
        watches.append(self)

    def compiled(self, *args, **kwargs):
        built.append(any(w.running for w in watches))
        make_compiled(self, *args, **kwargs)

    monkeypatch.setattr(Stopwatch, "__init__", watch)
    monkeypatch.setattr(Compiled, "__init__", compiled)
    robot = CATALOG["iiwa14"]()  # a new object: none of its functions is built yet
    T = _line(robot, robot.q_home, np.full(7, 0.15), 8)
    start = time.perf_counter()
    plan = qpik.plan_self_motion(
        robot, T, "margin", [Sphere((0.5, 0.4, 0.9), 0.05)], options=qpik.PlanOptions(max_joint_step=0.2, mujoco=False)
    )
    wall = time.perf_counter() - start
    assert plan.status in ("optimal", "dp") and {"dp", "nlp"} <= set(plan.timings)
    assert built and watches and not any(built), "a function was built while a stage's clock ran"
    assert 0 < sum(plan.timings.values()) < wall
