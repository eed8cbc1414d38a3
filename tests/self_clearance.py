"""The arm's self-clearance of a scene measured by MuJoCo, for the tests of the solvers' self-collision constraint.

:func:`mujoco_self_clearance` measures, with ``mj_geomDistance`` on the arm's MuJoCo twin (its geoms are qpik's
capsules), the smallest distance over the link pairs a :class:`qpik.scene.Scene` keeps apart
(:attr:`~qpik.scene.Scene.self_pairs`): every non-adjacent collision-geom pair except the allowed ones
(:class:`qpik.sim.self_distance.SelfDistances`), independent of qpik's distance kernels.
"""

from __future__ import annotations

import mujoco
import numpy as np

from qpik.robots.self_pairs import candidate_pairs
from qpik.scene import Scene
from qpik.sim.self_distance import SelfDistances, allowed_links


def mujoco_self_clearance(scene: Scene, q: np.ndarray) -> np.ndarray:
    """(M,) the smallest MuJoCo-measured distance (m) of the geom pairs of the links ``scene.self_pairs`` names,
    at configurations q (M, n), rad."""
    robot = scene.robot
    model = robot.mj_model()
    data = mujoco.MjData(model)
    allowed = allowed_links(robot, set(candidate_pairs(robot)) - set(scene.self_pairs))
    measured = SelfDistances(model, robot.joint_names, allowed)
    assert {tuple(k) for k in measured.links} == allowed_links(robot, scene.self_pairs)
    adr = [model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)] for j in robot.joint_names]
    out = []
    for qk in np.atleast_2d(q):
        data.qpos[adr] = qk
        mujoco.mj_kinematics(model, data)
        out.append(measured.measure(data).min(initial=np.inf))
    return np.array(out)
