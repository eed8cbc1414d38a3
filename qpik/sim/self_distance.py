"""The arm's own self-distances, measured by MuJoCo (``mj_geomDistance``), independent of qpik's capsules.

The model's collision geoms (``contype`` or ``conaffinity`` non-zero) on the bodies the arm's joints move are
grouped by chain link: a geom belongs to link ``k`` (1..n) when its body is welded to the body of joint
``k``. Every pair of geoms on links ``k < l`` that are not adjacent (``l − k ≥ 2``) is measured, except the
link pairs the caller allows (for example those a :class:`~qpik.control.self_collision.SelfCollisionLimit`
leaves out: :func:`allowed_links`).
"""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np

from qpik.robots.robot import Robot

DISTMAX = 10.0
"""Distances (m) beyond this are reported as this value by ``mj_geomDistance``."""


def allowed_links(robot: Robot, pairs: Iterable[tuple[int, int]]) -> set[tuple[int, int]]:
    """Capsule index pairs -> the chain-link pairs ``(k, l)``, k < l, they stand for."""
    caps = robot.capsules
    return {tuple(sorted((caps[c].link, caps[e].link))) for c, e in pairs}  # type: ignore[misc]


class SelfDistances:
    """The non-adjacent, non-allowed collision-geom pairs of ``model`` and their distances.

    Args:
        model: the arm's MuJoCo model (e.g. ``robot.mj_model()``).
        joint_names: the arm's joints in chain order.
        allowed: chain-link pairs ``(k, l)`` not measured.

    Attributes:
        pairs: (P, 2) geom ids; links: (P, 2) their chain links.
    """

    def __init__(self, model: mujoco.MjModel, joint_names: Iterable[str], allowed: Iterable[tuple[int, int]] = ()):
        self.model = model
        weld = model.body_weldid
        link_of_weld = {}
        for k, name in enumerate(joint_names, start=1):
            body = model.jnt_bodyid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)]
            link_of_weld[int(weld[body])] = k
        collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        geoms = [
            (g, link_of_weld[int(weld[model.geom_bodyid[g]])])
            for g in np.flatnonzero(collides)
            if int(weld[model.geom_bodyid[g]]) in link_of_weld
        ]
        skip = {tuple(sorted(p)) for p in allowed}
        pairs = [
            (g, h, k, m)
            for i, (g, k) in enumerate(geoms)
            for h, m in geoms[i + 1 :]
            if abs(k - m) >= 2 and tuple(sorted((k, m))) not in skip
        ]
        self.pairs = np.array([(g, h) for g, h, _, _ in pairs], dtype=int).reshape(-1, 2)
        self.links = np.array([sorted((k, m)) for _, _, k, m in pairs], dtype=int).reshape(-1, 2)

    def measure(self, data: mujoco.MjData) -> np.ndarray:
        """Signed distances (P,), m, at ``data``'s current kinematics (after ``mj_kinematics``)."""
        return np.array(
            [mujoco.mj_geomDistance(self.model, data, int(g), int(h), DISTMAX, None) for g, h in self.pairs]
        )
