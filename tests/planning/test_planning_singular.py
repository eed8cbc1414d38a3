"""The DP at singular crossings: iiwa14 paths of 1.0 rad joint motion through q2 = 0 and q6 = 0 plan at the
default settings, continuously, inside the limits; "fewest" adds no reconfiguration there, and is fast
(no timing asserted) when no transition fits."""

from __future__ import annotations

import numpy as np
import pytest

import qpik

IIWA = qpik.load_robot("iiwa14")


def _crossing(seed: int, n: int = 50):
    """Waypoints (n, 4, 4) of a straight joint motion of 1.0 rad (L∞) whose q2 and q6 change sign, and its
    configurations (n, 7)."""
    g = np.random.default_rng(seed)
    d = g.uniform(-1.0, 1.0, 7)
    d /= np.abs(d).max()
    d[1], d[5] = np.sign(d[1]), np.sign(d[5])
    q0 = g.uniform(-0.6, 0.6, 7) * np.minimum(IIWA.q_max, 2.0)
    q0[1], q0[5] = -g.uniform(0.3, 0.7) * d[1], -g.uniform(0.3, 0.7) * d[5]
    Q = q0 + np.linspace(0.0, 1.0, n)[:, None] * d
    assert np.all(IIWA.q_min < Q) and np.all(IIWA.q_max > Q)
    assert np.any(np.diff(np.sign(Q[:, 1]))) and np.any(np.diff(np.sign(Q[:, 5])))
    return IIWA.fk(Q), Q


def _continuous(plan) -> bool:
    return not plan.reconfigurations and bool(np.all(np.abs(np.diff(plan.q, axis=0)) <= plan.step_bound + 1e-9))


@pytest.mark.parametrize("seed", range(20))
def test_singular_crossings_plan_at_the_default_settings(seed):
    T, _ = _crossing(seed)
    plan = qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(refine=False, mujoco=False))
    assert plan.ok, plan.summary()
    assert np.abs(IIWA.fk(plan.q) - T).max() < 1e-9
    assert np.all(plan.q >= IIWA.q_min) and np.all(plan.q <= IIWA.q_max)
    assert _continuous(plan)


@pytest.mark.parametrize("seed", [4, 19])
def test_fewest_reports_no_reconfiguration_where_a_continuous_motion_exists(seed):
    T, _ = _crossing(seed)
    plan = qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(reconfigure="fewest", refine=False, mujoco=False))
    assert plan.ok and _continuous(plan), plan.summary()


def test_fewest_when_no_transition_fits_reconfigures_at_every_waypoint():
    g = np.random.default_rng(1)
    lo, hi = np.maximum(IIWA.q_min, -2.5), np.minimum(IIWA.q_max, 2.5)
    Q = lo + (hi - lo) * (0.1 + 0.8 * g.random((30, 7)))
    plan = qpik.plan_self_motion(
        IIWA, IIWA.fk(Q), options=qpik.PlanOptions(reconfigure="fewest", refine=False, mujoco=False)
    )
    assert plan.ok and plan.reconfigurations == list(range(29)), plan.summary()
    assert np.abs(IIWA.fk(plan.q) - IIWA.fk(Q)).max() < 1e-9


def test_a_grid_failure_is_not_called_infeasible():
    T, _ = _crossing(0, n=6)  # 0.2 rad per step against a 0.01 rad bound: the grid fails, nothing is proved
    plan = qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(max_joint_step=0.01, refine=False, mujoco=False))
    assert plan.status == "failed" and plan.failure_kind == "grid"
    assert "the grid failed" in plan.failure and "(grid)" in plan.summary()


def test_an_empty_feasible_set_is_infeasible():
    T, _ = _crossing(0, n=6)
    T[3, :3, 3] = (2.0, 0.0, 0.5)  # 2 m away: beyond reach
    plan = qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(max_joint_step=0.5, refine=False, mujoco=False))
    assert plan.status == "failed" and plan.failure_kind == "infeasible" and plan.failure_waypoint == 3
