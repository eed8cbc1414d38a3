r"""Which arm geometry is checked against which obstacle: one rule for the planner's checks, the
controller's status, the simulation log and the reports.

A pair (a link capsule or a collision geom of the arm's MuJoCo model, an obstacle) is *checked*
unless its signed distance is the same, to :data:`CONSTANT_TOL` m, at :data:`PROBES`
configurations drawn uniformly inside the joint limits (clipped to ±π) from a fixed seed. Such a
distance is one no joint motion changes: a base column standing on its table, a column that turns
about its own axis above the table's plane. It constrains nothing and cannot be a failure of a
motion; it is reported as a fact (:func:`facts`) instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qpik.geometry.distance import ObstacleSet, distances

PROBES = 16
"""Configurations at which a pair's distance is measured."""
CONSTANT_TOL = 1e-9
"""m: a pair whose distance varies by at most this over the probes is constant."""


@dataclass(frozen=True)
class Fact:
    """A pair left out of the checks: its names and its constant distance (m, negative: overlap)."""

    link: str
    obstacle: str
    distance: float

    def __str__(self) -> str:
        how = "touches" if self.distance < 0 else "to"
        return f"{self.link} {how} {self.obstacle}: {self.distance * 1e3:.0f} mm, constant, not checked"


def probes(q_min: np.ndarray, q_max: np.ndarray) -> np.ndarray:
    """(PROBES, n) configurations, rad, uniform inside the limits clipped to ±π, seed 0."""
    lo, hi = np.maximum(q_min, -np.pi), np.minimum(q_max, np.pi)
    return lo + (hi - lo) * np.random.default_rng(0).random((PROBES, len(lo)))


def constant(d: np.ndarray) -> np.ndarray:
    """Which pairs are constant, from their distances (PROBES, ...) at the probes: (...) bool."""
    return np.ptp(d, axis=0) <= CONSTANT_TOL


def capsule_pairs(robot, obstacles) -> np.ndarray:
    """(C, O) bool, read-only: which capsule–obstacle pairs of ``robot`` (a :class:`qpik.Robot`) are checked
    (found once per robot and obstacle geometry: ``robot.cache``)."""
    obs = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
    return robot.cache.get(("capsule pairs", obs.kinds, obs.params.tobytes()), _capsule_pairs, robot, obs)


def _capsule_pairs(robot, obs: ObstacleSet) -> np.ndarray:
    if not len(obs):
        out = np.zeros((len(robot.capsules), 0), bool)
    else:
        out = ~constant(distances(robot.capsule_segments(probes(robot.q_min, robot.q_max)), robot.capsule_radii,
                                  obs).d)  # fmt: skip
    out.flags.writeable = False
    return out


def capsule_clearance(robot, q: np.ndarray, obstacles) -> np.ndarray:
    """(M,) the smallest distance over the checked capsule–obstacle pairs at configurations q (M, n), m
    (inf without checked pairs)."""
    obs = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
    q = np.atleast_2d(q)
    mask = capsule_pairs(robot, obs)
    if not mask.any():
        return np.full(len(q), np.inf)
    if len(q) == 1:  # one configuration: the compiled kinematics and distances
        d = distances(robot.capsule_segments(q[0]), robot.capsule_radii, obs).d[None]
    else:
        d = distances(robot.capsule_segments(q), robot.capsule_radii, obs).d  # (M, C, O)
    return np.where(mask[None], d, np.inf).reshape(len(q), -1).min(axis=1)


def capsule_facts(robot, obstacles) -> list[Fact]:
    """The capsule–obstacle pairs left out (constant), with their distance, m."""
    obs = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
    if not len(obs):
        return []
    d = distances(robot.capsule_segments(probes(robot.q_min, robot.q_max)[:1]), robot.capsule_radii, obs).d[0]
    names = _obstacle_names(obs.shapes)
    return [
        Fact(_capsule_name(robot, c), names[o], float(d[c, o])) for c, o in zip(*np.nonzero(~capsule_pairs(robot, obs)))
    ]


def geom_pairs(scene) -> np.ndarray:
    """(L, O) bool: which link-geom–obstacle pairs of a :class:`qpik.robots.mujoco_scene.MjScene` are checked
    (distances by MuJoCo's ``mj_geomDistance``); the scene's state is restored."""
    L, O = len(scene.link_geoms), len(scene.obstacle_geoms)
    if not L * O:
        return np.ones((L, O), bool)
    kin = scene.kin
    saved = kin.data.qpos.copy()
    d = np.empty((PROBES, L, O))
    for k, q in enumerate(probes(kin.q_min, kin.q_max)):
        kin.update(q)
        scene.clearances(d[k])
    kin.update(saved[kin.qpos_adr])
    return ~constant(d)


def geom_facts(scene, checked: np.ndarray, d: np.ndarray) -> list[Fact]:
    """The pairs of ``scene`` left out (``~checked``, (L, O)) with their distances ``d`` (L, O), m."""
    return [Fact(scene.link_names[i], scene.obstacle_names[j], float(d[i, j])) for i, j in zip(*np.nonzero(~checked))]


def _capsule_name(robot, c: int) -> str:
    cap = robot.capsules[c]
    fixed = bool(robot.fixed_capsules[c])
    return f"capsule {c} (link {cap.link}{', base column' if fixed or c == 0 else ''})"


def _obstacle_names(shapes) -> list[str]:
    return [getattr(s, "name", "") or f"obstacle {o} ({type(s).__name__})" for o, s in enumerate(shapes)]
