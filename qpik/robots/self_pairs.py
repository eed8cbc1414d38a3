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
- :func:`checked_pairs`: the candidates minus the allowed ones (given, from an SRDF, or the default list): the
  pairs the controller and the solvers keep apart.
- :func:`pair_distance_expr`: one pair's signed distance (m) in :mod:`qpik.algebra.symbolic`, the kernel of
  :func:`qpik.geometry.distance.pair_expr` (capsule–capsule); :func:`pair_distances` evaluates it over a batch of
  configurations (numpy), :class:`qpik.objectives.context.Context` traces it in CasADi.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
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


def checked_pairs(
    robot: Robot, allowed: frozenset[Pair] | None = None, srdf: str | os.PathLike | None = None
) -> tuple[Pair, ...]:
    """The capsule pairs kept apart: :func:`candidate_pairs` minus the allowed ones — ``allowed`` (capsule index
    pairs) if given, else the links an SRDF's ``disable_collisions`` names (``srdf``), else :func:`default_allowed`."""
    if allowed is None and srdf is not None:
        from qpik.robots.srdf import disabled_links

        links = disabled_links(robot, srdf)
        caps = robot.capsules
        allowed = frozenset((c, e) for c, e in candidate_pairs(robot) if (caps[c].link, caps[e].link) in links)
    elif allowed is None:
        allowed = default_allowed(robot)
    else:
        allowed = frozenset(tuple(sorted(p)) for p in allowed)
    return tuple(p for p in candidate_pairs(robot) if p not in allowed)


def pair_distance_expr(segments: Sequence[tuple[sy.Vec, sy.Vec]], radii: Sequence[float], pair: Pair,
                       ops: sy.Ops) -> sy.Scalar:  # fmt: skip
    """The signed distance (m) of capsules ``pair = (c, e)``: capsule c's axis (``segments[c]``, end points ``a, b``,
    world frame) against capsule e taken as a capsule obstacle (:func:`qpik.geometry.distance.pair_expr`)."""
    from qpik.geometry.distance import pair_expr

    c, e = pair
    (a, b), (qa, qb) = segments[c], segments[e]
    prm = (*qa, *sy.vsub(qb, qa), radii[e])
    return pair_expr(a, b, radii[c], "capsule", prm, ops)[0]


def pair_distances(robot: Robot, q: np.ndarray, pairs: tuple[Pair, ...]) -> np.ndarray:
    """Signed distances (N, P), m, of capsule ``pairs`` at configurations ``q`` (N, n), rad
    (:func:`pair_distance_expr`)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[1] != robot.dof:
        raise InputError(f"q: expected shape (N, {robot.dof}), got {q.shape}")
    seg = robot.capsule_segments(q)  # (N, C, 2, 3)
    segments = [(tuple(seg[:, c, 0].T), tuple(seg[:, c, 1].T)) for c in range(seg.shape[1])]
    radii = [float(r) for r in robot.capsule_radii]
    out = np.empty((len(q), len(pairs)))
    for k, pair in enumerate(pairs):
        out[:, k] = pair_distance_expr(segments, radii, pair, sy.NUMPY)
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


def never_apart(robot: Robot, d_safe: float, samples: int = SAMPLES, seed: int = 0) -> frozenset[Pair]:
    """The candidate pairs closer than ``d_safe`` (m) at every one of ``samples`` seeded configurations: MoveIt's
    "always in collision" at the clearance d_safe (capsules fitted to meshes wrap a link around its neighbour's
    neighbour), which no configuration keeps d_safe apart (the samples of :func:`default_allowed`); built once per
    robot and arguments (``robot.cache``: every :meth:`qpik.Scene.of` asks for it)."""
    key = ("self-collision never apart", float(d_safe), samples, seed)
    return robot.cache.get(key, _never_apart, robot, float(d_safe), samples, seed)


def _never_apart(robot: Robot, d_safe: float, samples: int, seed: int) -> frozenset[Pair]:
    d = robot.cache.get(("self-collision samples", samples, seed), _sampled, robot, samples, seed)
    return frozenset(p for p, a in zip(candidate_pairs(robot), np.all(d < d_safe, axis=0)) if a)


def always_in_collision(robot: Robot, samples: int = SAMPLES, seed: int = 0) -> frozenset[Pair]:
    """The candidate pairs in collision (d < 0) at every one of ``samples`` seeded configurations: capsules that
    overlap where a link's shape wraps its neighbour's; no controller can keep them apart (``robot.cache``)."""
    return robot.cache.get(("self-collision always", samples, seed), _allowed, robot, samples, seed, None)
