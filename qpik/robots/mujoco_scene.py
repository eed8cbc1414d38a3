"""An arm's MuJoCo model with obstacles as world geoms (:func:`build_scene`), and the distances MuJoCo measures
between its collision geoms and the obstacles: what :func:`qpik.sim.simulate` runs on and logs, and what the
plans' MuJoCo clearance check (:func:`qpik.planning.plan.measure`) reads."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import mujoco
import numpy as np

from qpik.core.errors import InputError
from qpik.geometry.contacts import geom_pairs
from qpik.geometry.distance import ObstacleSet
from qpik.geometry.shapes import Shape
from qpik.robots.mujoco_backend import MjKinematics
from qpik.robots.robot import Robot

DISTMAX = 10.0
"""Distances (m) beyond this are reported as this value by ``mj_geomDistance``."""
OBSTACLE_PREFIX = "obstacles/"


@dataclass
class MjScene:
    """An arm model with obstacle geoms, and the geom pairs whose distance is logged.

    Attributes:
        kin: the arm's kinematics on the model with obstacles.
        link_geoms, link_names: ids and names of the arm's collision geoms (L,); an unnamed geom is
            ``<body>/geom<id>``.
        obstacle_geoms, obstacle_names: ids of the obstacle geoms and the obstacles' names (O,).
        obstacles: the obstacle shapes (world frame).
        robot: the :class:`Robot` when the model is its own (twin or loaded model), else ``None``.
    """

    kin: MjKinematics
    link_geoms: np.ndarray
    link_names: tuple[str, ...]
    obstacle_geoms: np.ndarray
    obstacle_names: tuple[str, ...]
    obstacles: tuple[Shape, ...]
    robot: Robot | None = None

    @cached_property
    def checked(self) -> np.ndarray:
        """(L, O) bool: the link-geom–obstacle pairs that are checked (:func:`qpik.geometry.contacts.geom_pairs`: not
        those whose distance no joint motion changes, a base column on its table)."""
        return geom_pairs(self)

    def clearances(self, out: np.ndarray) -> np.ndarray:
        """Signed distances (m) (L, O) of link to obstacle geoms at the current ``kin.data`` state."""
        m, d = self.kin.model, self.kin.data
        for i, gl in enumerate(self.link_geoms):
            for j, go in enumerate(self.obstacle_geoms):
                out[i, j] = mujoco.mj_geomDistance(m, d, int(gl), int(go), DISTMAX, None)
        return out


def build_scene(
    arm: Robot | str | os.PathLike,
    obstacles: Sequence[Shape] = (),
    *,
    joint_names: Sequence[str] | None = None,
    site: str = "ee",
    link_geoms: Sequence[str] | None = None,
) -> MjScene:
    """The model of ``arm`` with ``obstacles`` as world geoms.

    Args:
        arm: a :class:`Robot` (its MuJoCo model: the MJCF twin of a catalog arm, the model of a
            loaded one), an MJCF string or an MJCF file path.
        obstacles: shapes in the world frame (the robot's base frame: its MuJoCo model is moved so that they are the
            same, :mod:`qpik.robots.loader`); each becomes geom ``obstacles/<i>``.
        joint_names, site: the arm's joints and end-effector site (an MJCF arm;
            the twin uses ``joint1..7`` and ``ee``).
        link_geoms: the arm geoms whose clearance is logged; default: every geom
            that can collide (``contype`` or ``conaffinity`` non-zero) on a
            moving body — the capsules ``link<k>_capsule`` of the twin, a loaded arm's own
            collision geoms (its capsules are drawn but do not collide).
    """
    robot = arm if isinstance(arm, Robot) else None
    if robot is not None:
        spec = robot.mj_spec()
        joint_names, site = robot.joint_names, robot.site
    else:
        spec = _mjcf_spec(arm)
    obstacles = ObstacleSet(obstacles).shapes  # checks that each is a shape (InputError naming it)
    if obstacles:
        geoms = "".join(replace(o, name=str(i)).to_mjcf_geom() for i, o in enumerate(obstacles))
        child = mujoco.MjSpec.from_string(f'<mujoco><worldbody><body name="all">{geoms}</body></worldbody></mujoco>')
        spec.worldbody.add_frame().attach_body(child.body("all"), OBSTACLE_PREFIX, "")
    model = spec.compile()
    kin = MjKinematics(model, site, joint_names, robot.model.mimic if robot is not None and robot.model else ())
    if link_geoms is None:
        moving = model.body_weldid[model.geom_bodyid] != 0
        collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        link_ids = np.flatnonzero(moving & collides)
    else:
        link_ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in link_geoms], dtype=int)
        if np.any(link_ids < 0):
            missing = [g for g, i in zip(link_geoms, link_ids) if i < 0]
            raise InputError(f"link_geoms: {missing} are not geoms of the model")
    obstacle_ids = np.array(
        [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{OBSTACLE_PREFIX}{i}") for i in range(len(obstacles))],
        dtype=int,
    )
    return MjScene(
        kin=kin,
        link_geoms=link_ids,
        link_names=tuple(
            model.geom(int(g)).name or f"{model.body(int(model.geom_bodyid[g])).name}/geom{g}" for g in link_ids
        ),
        obstacle_geoms=obstacle_ids,
        obstacle_names=tuple(o.name or f"obstacle{i}" for i, o in enumerate(obstacles)),
        obstacles=obstacles,
        robot=robot,
    )


def _mjcf_spec(arm: object) -> mujoco.MjSpec:
    """The MjSpec of an MJCF string or file; :class:`InputError` for anything else or MJCF that MuJoCo rejects."""
    if isinstance(arm, str) and arm.lstrip().startswith("<"):
        load, what = mujoco.MjSpec.from_string, "MJCF string"
    elif isinstance(arm, str | os.PathLike) and os.path.isfile(arm):
        load, what = mujoco.MjSpec.from_file, f"MJCF file {os.fspath(arm)}"
        arm = os.fspath(arm)
    elif isinstance(arm, str):
        raise InputError(
            f"arm: {arm!r} is neither an MJCF string nor a file (a catalog arm: pass qpik.load_robot({arm!r}))"
        )
    else:
        raise InputError(f"arm: expected a qpik.Robot, an MJCF string or a file path, got {type(arm).__name__}")
    try:
        return load(arm)
    except ValueError as exc:  # MuJoCo's parser
        raise InputError(f"arm: {what} rejected by MuJoCo: {exc}") from None
