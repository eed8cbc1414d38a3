"""Closed-loop episodes with self-collision, a moving sphere and the motion limits (tests/safety_episodes.py).

The default run takes :data:`PER_ARM` seeds per arm (the four catalog arms and two loaded arms); with
``QPIK_TESTS_LARGE=1`` the large run takes :data:`EXTRA` more per arm (1,020 episodes in all). The same
episodes with one limit left out must show the violation that limit prevents, so each check can fail.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, model_robot
from safety_episodes import FAMILIES, make_episode, run_episode

import qpik
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
