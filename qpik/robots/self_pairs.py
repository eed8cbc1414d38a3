r"""Which pairs of an arm's own link capsules can collide: candidates, and the allowed list.

- :func:`candidate_pairs`: capsule pairs ``(c, e)``, c < e, on links that are not adjacent
  (``|link_c − link_e| ≥ 2``: capsules of one link or of links joined by a joint always touch
  where they meet) and not both fixed (:attr:`~qpik.robots.robot.Robot.fixed_capsules`).
- :func:`default_allowed`: the candidates to leave out, computed as MoveIt's setup assistant
  does: over ``samples`` configurations drawn uniformly inside the limits from a fixed seed, a
  pair that is *always* in collision (d < 0 at every sample) or *never* near (d > ``margin`` at
  every sample) is allowed. MoveIt's "never" is d > 0; the default ``margin`` = 0.05 m is more
  cautious (a pair kept out must stay 5 cm apart over the samples). Cached on the robot
  (``robot.cache``).
- :func:`pair_distances`: the signed distances (m) of pairs at a batch of configurations, with the
  same kernel as the controller (:func:`qpik.geometry.distance.pair_expr`, capsule–capsule).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.core.errors import InputError

if TYPE_CHECKING:
    from qpik.robots.robot import Robot

SAMPLES = 10_000
"""Configurations sampled by :func:`default_allowed` (MoveIt's default density)."""
MARGIN = 0.05
"""m: a pair never closer than this over the samples is allowed (left out)."""

Pair = tuple[int, int]


def candidate_pairs(robot: Robot) -> tuple[Pair, ...]:
    """Capsule index pairs ``(c, e)``, c < e, of links that are not adjacent, not both fixed."""
    caps, fixed = robot.capsules, robot.fixed_capsules
    return tuple(
        (c, e)
        for c in range(len(caps))
        for e in range(c + 1, len(caps))
        if abs(caps[c].link - caps[e].link) >= 2 and not (fixed[c] and fixed[e])
    )


def pair_distances(robot: Robot, q: np.ndarray, pairs: tuple[Pair, ...]) -> np.ndarray:
    """Signed distances (N, P), m, of capsule ``pairs`` at configurations ``q`` (N, n), rad."""
    from qpik.geometry.distance import pair_expr

    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[1] != robot.dof:
        raise InputError(f"q: expected shape (N, {robot.dof}), got {q.shape}")
    seg = robot.capsule_segments(q)  # (N, C, 2, 3)
    radii = robot.capsule_radii
    out = np.empty((len(q), len(pairs)))
    for k, (c, e) in enumerate(pairs):
        a, b = tuple(seg[:, c, 0].T), tuple(seg[:, c, 1].T)
        prm = (*seg[:, e, 0].T, *(seg[:, e, 1] - seg[:, e, 0]).T, radii[e])
        out[:, k] = pair_expr(a, b, radii[c], "capsule", prm, sy.NUMPY)[0]
    return out


def _sample(robot: Robot, samples: int, seed: int) -> np.ndarray:
    lo, hi = np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi)
    return lo + (hi - lo) * np.random.default_rng(seed).random((samples, robot.dof))


def _sampled(robot: Robot, samples: int, seed: int) -> np.ndarray:
    """The candidate pairs' distances (samples, P), m, over the seeded configurations."""
    pairs = candidate_pairs(robot)
    if not pairs:
        return np.zeros((samples, 0))
    return np.concatenate([pair_distances(robot, q, pairs) for q in np.array_split(_sample(robot, samples, seed), 10)])


def _allowed(robot: Robot, samples: int, seed: int, margin: float | None) -> frozenset[Pair]:
    d = robot.cache.get(("self-collision samples", samples, seed), _sampled, robot, samples, seed)
    always = np.all(d < 0.0, axis=0)
    out = always if margin is None else always | np.all(d > margin, axis=0)
    return frozenset(p for p, a in zip(candidate_pairs(robot), out) if a)


def default_allowed(robot: Robot, samples: int = SAMPLES, seed: int = 0, margin: float = MARGIN) -> frozenset[Pair]:
    """The candidate pairs always in collision or never within ``margin`` (m) over ``samples`` seeded
    configurations (module docstring); built once per robot and arguments (``robot.cache``)."""
    return robot.cache.get(("self-collision allowed", samples, seed, margin), _allowed, robot, samples, seed, margin)


def always_in_collision(robot: Robot, samples: int = SAMPLES, seed: int = 0) -> frozenset[Pair]:
    """The candidate pairs in collision (d < 0) at every one of ``samples`` seeded configurations: capsules that
    overlap where a link's shape wraps its neighbour's; no controller can keep them apart (``robot.cache``)."""
    return robot.cache.get(("self-collision always", samples, seed), _allowed, robot, samples, seed, None)
