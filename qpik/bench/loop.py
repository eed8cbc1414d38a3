"""The closed loop the controller benches share: the scene, the step of mink and the timing of a run."""

from __future__ import annotations

import mink
import numpy as np
from mink.tasks.task import BaseTask, Objective

from qpik.control import Controller, ControllerOptions
from qpik.geometry.distance import distances
from qpik.geometry.shapes import Sphere
from qpik.robots.mujoco_scene import build_scene

HOT = 50
"""Both scenes are timed hot: each sample is a block of this many consecutive steps of one library (the issue's
"hot" figures), the blocks of the libraries interleaved; the worst and CPU columns are then of such blocks."""
DT = 1e-3
D_INFLUENCE, D_SAFE, XI = 0.10, 0.02, 0.5
LINKS = (4, 5, 6, 7)
LIFT = 0.25
"""m: the target is this far above the start pose (see :func:`scene`)."""
RADIUS, GAP, SIDE = 0.05, 0.04, 0.06
"""m: the spheres' radius, their start clearance to the arm, their offset to either side of the arm's plane."""


class MinkManipulabilityTask(BaseTask):
    r"""Manipulability ascent for mink: the linear cost :math:`-w\,\nabla m^T \Delta q` (Δq = v dt).

    ∇m comes from the chain's kinematic Hessian (the MuJoCo model has the same kinematics),
    so both libraries get the same term; ``w`` is per Δq, i.e. qpik's weight times dt. The arm's
    joints are at ``qpos_adr`` of the model (hinges: the same addresses in qpos and in v).
    """

    def __init__(self, robot, weight: float, qpos_adr: np.ndarray):
        self.robot = robot
        self.weight = weight
        self.qpos_adr = qpos_adr

    def compute_qp_objective(self, configuration: mink.Configuration) -> Objective:
        nv = configuration.model.nv
        grad = np.zeros(nv)
        grad[self.qpos_adr] = self.robot.manipulability_gradient(configuration.q[self.qpos_adr])  # hinges: qpos = dof
        return Objective(np.zeros((nv, nv)), -self.weight * grad)


def scene(robot, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Sphere]]:
    """Start configuration ``q0`` (n,), rad (the iiwa14's home for both arms: elbow and wrist bent), target pose
    and the spheres: the arm pressed up against obstacles.

    The target is :data:`LIFT` m above the start pose; four spheres of radius :data:`RADIUS` sit above
    the elbow (link 4) and the wrist (link 6), :data:`SIDE` m to either side of the arm's plane, each
    raised until its nearest capsule is :data:`GAP` m away. The straight way to the target runs through
    them, so the arm approaches and then presses against them: obstacle rows bind in (almost) every step.
    """
    q0 = np.array(q0, dtype=float)
    target = robot.fk(q0)
    target[:3, 3] += (0.0, 0.0, LIFT)
    seg = robot.capsule_segments(q0)
    radii = robot.capsule_radii
    links = np.array([cap.link for cap in robot.capsules])
    spheres = []
    for k in (4, 6):
        base = seg[links == k].reshape(-1, 3).mean(axis=0)
        for side in (1.0, -1.0):
            offset = np.array((0.0, side * SIDE, 0.0))
            lo, hi = 0.0, 1.0  # height above the link, m: bisection on the clearance (it grows with the height)
            for _ in range(40):
                z = 0.5 * (lo + hi)
                ball = Sphere(base + offset + (0, 0, z), RADIUS)
                lo, hi = (z, hi) if distances(seg, radii, [ball]).d.min() < GAP else (lo, z)
            spheres.append(Sphere(base + offset + (0, 0, hi), RADIUS, name=f"ball{k}{'+' if side > 0 else '-'}"))
    return q0, target, spheres


def full_q(conf, dq: np.ndarray, robot) -> np.ndarray:
    """The arm's Δq (n,) placed in the model's velocity vector (nv,) (a loaded model may have more joints)."""
    model = conf.model
    out = np.zeros(model.nv)
    out[[model.jnt_dofadr[model.joint(j).id] for j in robot.joint_names]] = dq
    return out


def closed_loop(step, q0: np.ndarray):
    """A no-argument callable: one control step at the current q, then ``q ← q + v dt``."""
    q = q0.copy()

    def call():
        q[:] += step(q) * DT

    return call


def mink_step(robot, target, spheres, solver, extra_pairs: tuple = ()):
    """mink's control step on the robot's MuJoCo model with the same tasks, weights and limits as qpik's defaults.

    Its collision rows are the model's collision geoms on links 4–7 (the twin's capsules; a loaded arm's
    meshes) against the spheres, and ``extra_pairs`` (mink's ``(geoms, geoms)`` groups, e.g. self pairs).
    """
    scene_ = build_scene(robot, spheres)
    model = scene_.kin.model
    adr = scene_.kin.qpos_adr
    conf = mink.Configuration(model)
    qpos = model.qpos0.copy()  # joints that are not the arm's (fingers) stay at their reference
    # only to read the same default weights
    ctrl = Controller.for_robot(robot, options=ControllerOptions(self_collision=False))
    frame_task, posture, manip, damping = ctrl.tasks
    # qpik's cost w‖·‖² over v ⇔ mink's ½‖c(·)‖² over Δq = v dt with c = sqrt(2 w)·…, gains·dt
    frame = mink.FrameTask(
        robot.site,
        "site",
        position_cost=np.sqrt(frame_task.weight[0]),
        orientation_cost=np.sqrt(frame_task.weight[3]),
        gain=min(1.0, frame_task.gain[0] * DT),
    )
    frame.set_target(mink.SE3.from_matrix(target))
    post = mink.PostureTask(model, cost=np.sqrt(posture.weight), gain=posture.gain * DT)
    reference = qpos.copy()
    reference[adr] = posture.q_ref
    post.set_target(reference)
    tasks = [
        frame,
        post,
        mink.DampingTask(model, cost=np.sqrt(damping.weight)),
        MinkManipulabilityTask(robot, manip.weight * DT, adr),
    ]
    vel = {name: robot.v_max[j] for j, name in enumerate(robot.joint_names)}
    links = link_of_body(model, robot)
    arm_geoms = [int(g) for g in scene_.link_geoms if links[int(model.geom_bodyid[g])] in LINKS]
    pairs = [(arm_geoms, [int(g) for g in scene_.obstacle_geoms]), *extra_pairs]
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, vel)]
    if spheres:
        limits.append(
            mink.CollisionAvoidanceLimit(
                model, pairs, minimum_distance_from_collisions=D_SAFE, collision_detection_distance=D_INFLUENCE
            )
        )

    def step(q):
        qpos[adr] = q
        conf.update(qpos)
        return mink.solve_ik(conf, tasks, DT, solver=solver, limits=limits)[scene_.kin.dof_adr]

    return step, limits[-1], conf


def link_of_body(model, robot) -> dict[int, int]:
    """body id -> the link k (1..n) of the last arm joint above it, 0 above joint 1."""
    joint_body = {int(model.joint(name).bodyid[0]): k for k, name in enumerate(robot.joint_names, start=1)}
    out = {0: 0}
    for b in range(1, model.nbody):  # parents come first in MuJoCo's body order
        out[b] = joint_body.get(b, out[int(model.body_parentid[b])])
    return out
