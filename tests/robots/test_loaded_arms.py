"""The whole stack on arms loaded from other people's model files: the QP controller with every task and
limit around an obstacle, simulated by MuJoCo on the model itself, and the numerical IK.

Clearances are MuJoCo's (``mj_geomDistance``) between the model's own collision geoms (meshes or
primitives, not qpik's capsules) and the obstacle; limits are checked on every logged step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from conftest import model_robot, mujoco_poses

import qpik
from qpik.algebra.lie import pose_error
from qpik.geometry import Sphere, distances
from qpik.sim import SimOptions, simulate

CONTROLLED = ("pybullet_iiwa", "robosuite_iiwa", "erd_panda", "pybullet_panda", "erd_xarm7")
DT = 0.002
D_SAFE = 0.02


def reach_scene(robot: qpik.Robot, seed: int) -> tuple[np.ndarray, np.ndarray, Sphere]:
    """A start and goal configuration and a ball that the straight joint path between them runs into.

    The ball cuts 3 cm into link 4's capsule half way; at both ends every capsule is more than
    the influence distance (0.1 m) from it.
    """
    rng = np.random.default_rng(seed)
    span = robot.q_max - robot.q_min
    lo, hi = robot.q_min + 0.15 * span, robot.q_max - 0.15 * span
    for _ in range(5000):
        q0 = rng.uniform(lo, hi)
        qt = np.clip(q0 + rng.uniform(-1.2, 1.2, robot.dof), lo, hi)
        seg = robot.capsule_segments(0.5 * (q0 + qt))[3]
        u = rng.normal(size=3)
        axis = seg[1] - seg[0]
        u -= (u @ axis) / (axis @ axis) * axis
        ball = Sphere(seg.mean(0) + u / np.linalg.norm(u) * (robot.capsules[3].radius + 0.02), 0.05, name="ball")
        if all(distances(robot.capsule_segments(q), robot.capsule_radii, [ball]).d.min() > 0.1 for q in (q0, qt)):
            return q0, qt, ball
    raise AssertionError("no scene found")


@pytest.mark.parametrize("key", CONTROLLED)
def test_reach_past_an_obstacle(key):
    robot = model_robot(key)
    q0, qt, ball = reach_scene(robot, 0)
    target = robot.fk(qt)
    # the obstacle dampers are under test, not the self pairs of the fitted capsules (#24's open work)
    ctrl = qpik.Controller.for_robot(robot, target=target, obstacles=[ball], dt=DT, d_safe=D_SAFE,
                                     options=qpik.ControllerOptions(self_collision=False))  # fmt: skip
    log = simulate(robot, ctrl, q0, 4.0, DT, obstacles=[ball], target=target, options=SimOptions(record_every=5))
    assert np.linalg.norm(pose_error(target, log.ee[-1])) < 5e-3  # the posture task's pull stays ~1e-3
    assert np.all((log.q >= robot.q_min) & (log.q <= robot.q_max))
    assert np.all(np.abs(log.v) <= robot.v_max + 1e-9)
    assert log.clearance.min() >= D_SAFE - 2e-3  # the model's own geoms, inside the capsules
    assert len(log.link_names) >= robot.dof


@dataclass(frozen=True)
class Circle:
    """A circle of radius r (m) in the base x–y plane around the pose T0, period 2 s; orientation fixed."""

    T0: np.ndarray
    r: float = 0.05
    duration: float = 3.0

    def pose(self, t: float) -> np.ndarray:
        T = self.T0.copy()
        T[:3, 3] += self.r * np.array([np.cos(np.pi * t) - 1.0, np.sin(np.pi * t), 0.0])
        return T

    def twist(self, t: float) -> np.ndarray:
        return np.r_[self.r * np.pi * np.array([-np.sin(np.pi * t), np.cos(np.pi * t), 0.0]), np.zeros(3)]


@pytest.mark.parametrize("key", ("robosuite_iiwa", "erd_panda", "erd_xarm7", "pybullet_iiwa"))
def test_track_a_circle_beside_an_obstacle(key):
    """A ball 7 cm from the forearm's capsule (inside the influence distance) while the hand draws a circle.

    The start is the most manipulable (translational index) of 200 random configurations in the middle of the
    limits whose capsules all keep 6 cm from the ball.
    """
    robot = model_robot(key)
    span = robot.q_max - robot.q_min
    Q = np.random.default_rng(4).uniform(robot.q_min + 0.25 * span, robot.q_max - 0.25 * span, (200, robot.dof))
    for q0 in Q[np.argsort(-robot.manipulability(Q, translational=True))]:
        seg = robot.capsule_segments(q0)[3]
        side = np.cross(seg[1] - seg[0], (0.0, 0.0, 1.0))
        centre = seg.mean(0) + side / np.linalg.norm(side) * (robot.capsules[3].radius + 0.12)
        ball = Sphere(centre, 0.05, name="ball")
        if distances(robot.capsule_segments(q0), robot.capsule_radii, [ball]).d.min() > 0.06:
            break
    path = Circle(robot.fk(q0))
    ctrl = qpik.Controller.for_robot(robot, path.pose(0.0), [ball], dt=DT, q_ref=q0, d_safe=D_SAFE,
                                     options=qpik.ControllerOptions(self_collision=False))  # fmt: skip
    log = simulate(
        robot, ctrl, q0, path.duration, DT, obstacles=[ball], target=path, options=SimOptions(record_every=5)
    )
    pos, _ = log.errors
    assert pos[log.t > 0.5].max() < 1e-3
    assert np.all((log.q >= robot.q_min) & (log.q <= robot.q_max))
    assert log.clearance.min() >= D_SAFE - 2e-3


@pytest.mark.parametrize("key", ("pybullet_iiwa", "robosuite_iiwa", "erd_panda", "pybullet_panda"))
def test_solve_ik_reaches_random_poses(key):
    """qpik.solve_ik from random starts to 1,000 poses of random configurations inside the limits: ≥ 99.9 %
    reach the pose to 1e-9 inside the limits, checked by MuJoCo's FK of the model itself."""
    robot = model_robot(key)
    rng = np.random.default_rng(3)
    Q, starts = (rng.uniform(robot.q_min, robot.q_max, (1000, robot.dof)) for _ in range(2))
    model = robot.mj_model()
    reached = 0
    for q_goal, q0 in zip(Q, starts):
        try:
            q = qpik.solve_ik(robot, robot.fk(q_goal), q0)
        except qpik.UnreachableError:
            continue
        assert robot.within_limits(q)
        T_goal, T = mujoco_poses(robot, np.stack([q_goal, q]), model)
        reached += np.linalg.norm(pose_error(T_goal, T)) < 1e-9
    assert reached >= 999
