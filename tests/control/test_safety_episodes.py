"""Closed-loop episodes with self-collision, a moving sphere and the motion limits (tests/safety_episodes.py).

The default run takes :data:`PER_ARM` seeds per arm (the four catalog arms and two loaded arms); with
``QPIK_TESTS_LARGE=1`` the large run takes :data:`EXTRA` more per arm (1,020 episodes in all). The same
episodes with one limit left out must show the violation that limit prevents, so each check can fail.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, model_robot
from safety_episodes import (
    D_SAFE_OBS,
    ESCAPE_MARGIN,
    FAMILIES,
    SPHERE_RADIUS,
    a_max,
    escape,
    j_max,
    make_episode,
    run_episode,
)

import qpik
from qpik.geometry import Sphere
from qpik.geometry.distance import distances
from qpik.robots.catalog import CATALOG

ARMS = ("panda", "iiwa14", "nammoto7", "zheng7", "robosuite_iiwa", "pybullet_panda")
PER_ARM = 6
EXTRA = 170  # 6 arms × 170 = 1,020 episodes


def _robot(name: str) -> qpik.Robot:
    return qpik.load_robot(name) if name in CATALOG else model_robot(name)


def _check(name: str, seeds) -> None:
    robot = _robot(name)
    for seed in seeds:
        ep = make_episode(robot, seed)
        out = run_episode(ep)
        where = f"{name} seed {seed} ({ep.family}): {out}"
        assert out.self_violation == 0.0, where
        assert out.obstacle_violation == 0.0, where
        assert (out.position, out.velocity, out.acceleration, out.jerk, out.nan) == (0, 0, 0, 0, 0), where


@pytest.mark.parametrize("name", ARMS)
def test_episodes_hold_every_limit(name: str) -> None:
    _check(name, range(PER_ARM))


@pytest.mark.skipif(not LARGE, reason="the large run: QPIK_TESTS_LARGE=1")
@pytest.mark.parametrize("name", ARMS)
def test_episodes_hold_every_limit_large(name: str) -> None:
    _check(name, range(PER_ARM, PER_ARM + EXTRA))


@pytest.mark.parametrize(
    "off, family, field",
    [
        ("self", "fold", "self_violation"),
        ("moving", "sphere", "obstacle_violation"),
        ("braking", "limit", "position"),
        ("acceleration", "limit", "acceleration"),
        ("jerk", "limit", "jerk"),
    ],
)
def test_episodes_fail_without_the_limit(off: str, family: str, field: str) -> None:
    robot = qpik.load_robot("panda")
    seen = [getattr(run_episode(make_episode(robot, seed, family), off), field) for seed in range(8)]
    assert max(seen) > 0, f"{off} off: no {field} in {seen}"


def test_families_cover_the_issue() -> None:
    assert set(FAMILIES) == {"fold", "sphere", "limit"}
    robot = qpik.load_robot("panda")
    ep = make_episode(robot, 1, "limit")
    j = int(np.flatnonzero(ep.v0)[0])
    assert abs(ep.v0[j]) == robot.v_max[j]  # full speed toward the limit


@pytest.mark.parametrize("name", ("panda", "nammoto7", "pybullet_panda"))
def test_the_premise_is_an_escape(name: str) -> None:
    """The premise of the sphere episodes (:func:`safety_episodes.escape`, a linear program at the start
    configuration) is a motion: the arm driven at its escape velocity, rescaled to retreat at M times the
    sphere's speed and ramped up from rest at the acceleration limits, keeps every moving capsule at least d_s
    from the moving sphere over its whole path (qpik's capsule distances, densely sampled)."""
    robot = _robot(name)
    for seed in range(1, 24, 3):
        ep = make_episode(robot, seed, "sphere")
        t, v = escape(robot, ep.q0, ep.start, ep.velocity, ep.moving_for)
        assert t >= ESCAPE_MARGIN
        speed = np.linalg.norm(ep.velocity)
        v = v * ESCAPE_MARGIN / t
        start = distances(robot.capsule_segments(ep.q0), robot.capsule_radii, [Sphere(ep.start, SPHERE_RADIUS)])
        ramp = 2.0 * (start.d.min() - D_SAFE_OBS) / (ESCAPE_MARGIN * speed)
        assert np.all(np.abs(v) <= a_max(robot) * (ramp - a_max(robot) / j_max(robot)) + 1e-12)
        for clock in np.linspace(0.0, ep.moving_for, 300):
            travelled = clock * clock / (2.0 * ramp) if clock < ramp else clock - ramp / 2.0  # ∫ min(1, τ/ramp) dτ
            q = ep.q0 + v * travelled
            assert np.all((q >= robot.q_min) & (q <= robot.q_max))
            centre = ep.start + ep.velocity * min(clock, ep.moving_for)
            d = distances(robot.capsule_segments(q), robot.capsule_radii, [Sphere(centre, SPHERE_RADIUS)]).d
            assert d.ravel()[~robot.fixed_capsules].min() >= D_SAFE_OBS, f"{name} seed {seed} at {clock:.3f} s"


def test_a_sphere_at_the_base_column_is_outside_the_premise() -> None:
    """The Panda's base column is a capsule no joint moves: a sphere aimed at it cannot be escaped (t = 0)."""
    robot = qpik.load_robot("panda")
    assert robot.fixed_capsules[0]
    q0 = 0.5 * (robot.q_min + robot.q_max)
    base = robot.capsule_segments(q0)[0].mean(axis=0)
    start = base + np.array([0.5, 0.0, 0.0])
    assert escape(robot, q0, start, np.array([-0.3, 0.0, 0.0]), 1.5)[0] == 0.0
