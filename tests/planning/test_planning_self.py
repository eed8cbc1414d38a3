"""qpik.plan_self_motion with self-collision (on by default; ``self_collision=False`` turns it off) on seeded paths of
nammoto7 whose plan without it brings the arm's own capsules closer than d_s (2 paths by default, 8 with
``QPIK_TESTS_LARGE=1``): with it, every waypoint of the plan, and of the DP's plan it was refined from, keeps
the checked capsule pairs ≥ d_s apart, measured by MuJoCo on the arm's twin (:mod:`self_clearance`)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE
from self_clearance import mujoco_self_clearance

import qpik
from qpik.planning.plan import make_plan, measure
from qpik.planning.setup import Setup
from qpik.scene import Scene

PATHS = 8 if LARGE else 2
D_SAFE = 0.02
TOL = 1e-6
"""m: MuJoCo's distance of a waypoint on the boundary d_s may differ from qpik's kernel by rounding."""
OPTIONS = qpik.PlanOptions(mujoco=False)


def _colliding_paths(plain, count, seed, tries=400):
    """Seeded paths (12 waypoints: FK of a straight joint-space segment of up to 0.2 rad per joint from a
    configuration 2 to 10 cm clear of itself) whose plan under ``plain`` is ok but comes closer than d_s − 1 mm
    to itself (MuJoCo), and those plans."""
    robot, safe = plain.robot, plain.replace(self_collision=True)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(tries):
        q0 = rng.uniform(robot.q_min, robot.q_max)
        dq = rng.uniform(-0.2, 0.2, robot.dof)
        if not 0.02 < safe.self_clearance(q0[None])[0] < 0.1:
            continue
        T = robot.fk(q0 + np.linspace(0.0, 1.0, 12)[:, None] * dq)
        plan = qpik.plan_self_motion(plain, T, options=OPTIONS)
        if plan.ok and mujoco_self_clearance(safe, plan.q).min() < D_SAFE - 1e-3:
            out.append((T, plan))
        if len(out) == count:
            return out
    raise AssertionError(f"only {len(out)} colliding plans in {tries} tries")


@pytest.fixture(scope="module")
def colliding():
    """nammoto7's margin without obstacles: the scene and its :data:`PATHS` seeded colliding paths and plans."""
    plain = Scene.of(qpik.load_robot("nammoto7"), d_safe=D_SAFE, objective="margin", self_collision=False)
    return plain, _colliding_paths(plain, PATHS, 7)


def test_every_waypoint_keeps_self_clearance(colliding):
    plain, paths = colliding
    safe = plain.replace(self_collision=True)
    for T, before in paths:
        assert "self_clearance" not in [c.name for c in before.checks]  # without it nothing checks the pairs
        plan = qpik.plan_self_motion(safe, T, options=OPTIONS)
        assert plan.ok and len(plan.q) == len(T), plan.summary()
        assert "self_clearance" in [c.name for c in plan.checks]
        for made in (plan, plan.dp_plan):
            if made is not None and len(made.q):
                assert mujoco_self_clearance(safe, made.q).min() >= D_SAFE - TOL, made.summary()
                np.testing.assert_allclose(made.self_clearance, safe.self_clearance(made.q))


def test_a_plan_coming_too_close_to_itself_fails_its_check(colliding):
    """The plan's check measures the capsule pairs itself: the configurations of a plan made without
    self-collision, measured for the scene with it, fail the check at the first waypoint that comes too close."""
    plain, ((T, before), *_) = colliding
    safe = plain.replace(self_collision=True)
    setup = Setup(safe, T, None, OPTIONS)
    plan = make_plan(setup, before.q, "optimal")
    measure(plan, mujoco=False)
    close = safe.self_clearance(before.q) < D_SAFE
    assert not plan.ok and plan.failure_kind == "check" and plan.failure_waypoint == int(np.argmax(close))
    assert "self_clearance" in plan.failure
