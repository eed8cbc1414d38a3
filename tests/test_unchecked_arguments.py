"""Arguments that used to pass unchecked each raise qpik's InputError naming them."""

from __future__ import annotations

import numpy as np
import pytest

import qpik
from qpik.core.errors import InputError
from qpik.geometry.distance import ObstacleSet
from qpik.geometry.shapes import Sphere
from qpik.planning.planner import MAX_RESOLUTION
from qpik.planning.setup import MAX_WAYPOINTS
from qpik.sim import simulate

IIWA = qpik.load_robot("iiwa14")


@pytest.fixture(scope="module")
def plan():
    T = IIWA.fk(IIWA.q_home + np.linspace(0, 1, 6)[:, None] * np.full(7, 0.1))
    return qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(refine=False, mujoco=False))


@pytest.mark.parametrize("samples", [0, 1, -5, 2.5, True, "3"])
def test_retime_samples_must_be_an_integer_of_at_least_two(plan, samples):
    with pytest.raises(InputError, match="samples"):
        plan.retime(samples=samples)


def test_retime_two_samples_is_fine(plan):
    assert len(plan.retime(samples=2).t) == 2


@pytest.mark.parametrize("d_safe", [-0.05, np.nan, np.inf])
def test_controller_d_safe_must_be_at_least_zero(d_safe):
    with pytest.raises(InputError, match="d_safe"):
        qpik.Controller.for_robot(IIWA, d_safe=d_safe)


@pytest.mark.parametrize("duration, dt", [(0.0, 0.01), (0.005, 0.01), (-1.0, 0.01)])
def test_simulate_duration_must_cover_one_step(duration, dt):
    with pytest.raises(InputError, match="duration"):
        simulate(IIWA, lambda t, q: np.zeros(7), IIWA.q_home, duration, dt)


def test_duplicate_obstacle_names_are_rejected():
    a, b = Sphere(np.zeros(3), 0.1, name="x"), Sphere(np.ones(3), 0.1, name="x")
    with pytest.raises(InputError, match=r"obstacles.*'x'"):
        ObstacleSet([a, b])
    with pytest.raises(InputError, match="obstacles"):
        simulate(IIWA, lambda t, q: np.zeros(7), IIWA.q_home, 0.01, 0.005, obstacles=[a, b])


def test_planner_caps_waypoints_and_resolution(plan):
    T = plan.poses
    with pytest.raises(InputError, match="resolution"):
        qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(resolution=MAX_RESOLUTION + 2, mujoco=False))
    with pytest.raises(InputError, match="resolution"):
        qpik.plan_self_motion(IIWA, T, options=qpik.PlanOptions(resolution=1e8, mujoco=False))
    with pytest.raises(InputError, match="path"):
        qpik.plan_self_motion(IIWA, np.repeat(T[:1], MAX_WAYPOINTS + 1, axis=0), options=qpik.PlanOptions(mujoco=False))
    path = qpik.geometry.paths.WaypointPath(T, np.linspace(0.0, 1.0, len(T)))
    with pytest.raises(InputError, match="waypoints"):
        qpik.plan_self_motion(IIWA, path, options=qpik.PlanOptions(waypoints=3_000_000, mujoco=False))
