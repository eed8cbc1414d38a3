"""Bench: one full control step (kinematics, QP assembly, solve) of qpik beside mink, same arm, same run.

Scene: iiwa14 reaching for a pose 0.25 m away, closed loop (``q ← q + v·dt``, dt = 1 ms,
so every solver is warm-started the way it runs in a robot), with two spheres placed
close to links 4–7 so that 8 capsule–sphere pairs are inside the influence distance.

- qpik: :meth:`Controller.for_robot` — FrameTask, PostureTask, ManipulabilityTask
  (∇m from the kinematic Hessian), DampingTask; ConfigurationLimit, VelocityLimit and
  ObstacleLimit (every one of the 7 capsules against both spheres: 14 rows, 8 active) —
  with solver ``osqp`` (persistent), ``daqp``, ``proxqp``, ``quadprog``;
- mink 1.3 on the MJCF twin (same kinematics): ``configuration.update(q)`` +
  ``mink.solve_ik`` with FrameTask, PostureTask, DampingTask and a manipulability task
  (:class:`MinkManipulabilityTask`, the same gradient) and ConfigurationLimit,
  VelocityLimit, CollisionAvoidanceLimit (the 4 capsules of links 4–7 × 2 spheres),
  solver ``osqp`` and ``daqp``.

Then the same rows (labels ``URDF iiwa: ...``) for the iiwa loaded from pybullet's URDF
(:data:`LOADED`, when pybullet is installed), mink running on that model itself: its
CollisionAvoidanceLimit gets the model's own collision meshes of links 4–7 (``mj_geomDistance``
on meshes), qpik its capsules fitted to those meshes: the same scene, each library with
the geometry it would use.

Rows: seconds per step over all replays (median, p99, worst, wall clock; and the worst in
thread CPU time, and the worst step as the best of :data:`REPLAYS` replays of the same closed
loop: on a virtual machine thread CPU time still counts the time the host takes the virtual
CPU away, which a replay does not repeat); ratios compare qpik with mink on the same solver.
The six loops are timed interleaved (one step of each per round,
:func:`qpik.bench.time_interleaved`), so the machine's busy spells fall on all of them.
Targets (issue): qpik+OSQP ≥ 5x faster than mink+OSQP and no slower than mink+daqp;
qpik+daqp ≥ 2x faster than mink+daqp; worst step < 1 ms.
"""

from __future__ import annotations

import argparse
import warnings

import mink
import numpy as np
from mink.tasks.task import BaseTask, Objective

from qpik.bench import Row, fmt_time, time_interleaved
from qpik.control import Controller
from qpik.control.solvers import available
from qpik.errors import InputError
from qpik.geometry.shapes import Sphere
from qpik.robots.loader import load_robot
from qpik.robots.packaged import packaged_model
from qpik.sim.run import build_scene

TITLE = "Controller: one control step (iiwa14 twin, then the pybullet iiwa URDF; frame + posture + manipulability)"
LOADED = "pybullet/iiwa"
"""The arm loaded from another package's URDF (:mod:`qpik.robots.packaged`) whose rows follow iiwa14's."""
DT = 1e-3
REPLAYS = 3
"""The closed loops are run this many times from the same start; the "best of replays" worst step takes,
for every step, its least thread CPU time over the replays (a host stall rarely hits the same step
twice), then the largest over the steps: the cost of the slowest step itself."""
D_INFLUENCE, D_SAFE, XI = 0.10, 0.02, 0.5
LINKS = (4, 5, 6, 7)


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


def scene(robot) -> tuple[np.ndarray, np.ndarray, list[Sphere]]:
    """Start configuration, target pose and two spheres near links 4–7."""
    q0 = robot.q_home.copy()
    target = robot.fk(q0)
    target[:3, 3] += (0.15, 0.1, -0.15)
    seg = robot.capsule_segments(q0)
    caps = robot.capsule_radii
    spheres = []
    for k, side in ((4, 1.0), (6, -1.0)):
        c = k - 1
        mid = 0.5 * (seg[c, 0] + seg[c, 1])
        u = np.array([0.0, side, 0.0])
        spheres.append(Sphere(mid + u * (caps[c] + 0.05 + 0.05), 0.05, name=f"ball{k}"))
    return q0, target, spheres


def run(args: argparse.Namespace) -> list[Row]:
    repeat = max(100, int(getattr(args, "repeat", 2000)))
    rows = _arm_rows(load_robot("iiwa14"), "", repeat)
    try:
        loaded = load_robot(packaged_model(LOADED))
    except InputError as exc:
        print(f"qpik bench controller: {exc}; rows left out")
        return rows
    return rows + _arm_rows(loaded, "URDF iiwa: ", repeat)


def _arm_rows(robot, prefix: str, repeat: int) -> list[Row]:
    """The rows of one arm, labelled ``prefix + "qpik + osqp"`` etc."""
    q0, target, spheres = scene(robot)
    backends = available()  # proxqp and quadprog come with the test extra
    peers = [("osqp", "mink + osqp"), ("daqp", "mink + daqp"), ("proxqp", "mink + daqp"), ("quadprog", "mink + daqp")]
    for solver, _ in peers:
        if solver not in backends:
            print(f"qpik bench controller: {solver} not installed (pip install -e '.[test]'), row left out")
    peers = [(solver, ref) for solver, ref in peers if solver in backends]
    passes = []
    for _ in range(REPLAYS):  # the same closed loops from the same start, each time with fresh solvers
        steps, refs, ctrls = {}, {}, {}
        for solver in ("osqp", "daqp"):
            steps[f"{prefix}mink + {solver}"] = _closed_loop(_mink_step(robot, target, spheres, solver), q0)
        for solver, ref in peers:
            label = f"{prefix}qpik + {solver}"
            ctrls[label] = Controller.for_robot(
                robot,
                target=target,
                obstacles=spheres,
                dt=DT,
                solver=solver,
                d_influence=D_INFLUENCE,
                d_safe=D_SAFE,
                xi=XI,
            )
            steps[label], refs[label] = _closed_loop(ctrls[label].step, q0), prefix + ref
        with warnings.catch_warnings():  # qpsolvers warns on every dense matrix mink hands to OSQP
            warnings.simplefilter("ignore")
            cpu: dict[str, np.ndarray] = {}
            passes.append((time_interleaved(steps, repeat, warmup=50, cpu=cpu), cpu))
    rows = []
    for label in passes[0][0]:
        t = np.concatenate([times[label] for times, _ in passes])
        worst_cpu = max(float(c[label].max()) for _, c in passes)
        replayed = float(np.min([c[label] for _, c in passes], axis=0).max())  # per step: best of the replays
        note = (
            f"(worst in thread CPU time: {fmt_time(worst_cpu).strip()}; "
            f"best of {REPLAYS} replays: {fmt_time(replayed).strip()})"
        )
        if label in ctrls:
            active = sum(name.startswith("obstacle") for name in ctrls[label].last.active)
            note += f" (last step: {active} obstacle rows active)" if active else ""
        rows.append(Row(label, float(np.median(t)), refs.get(label), float(np.percentile(t, 99)), float(t.max()), note))
    return rows


def _closed_loop(step, q0: np.ndarray):
    """A no-argument callable: one control step at the current q, then ``q ← q + v dt``."""
    q = q0.copy()

    def call():
        q[:] += step(q) * DT

    return call


def _mink_step(robot, target, spheres, solver):
    """mink's control step on the robot's MuJoCo model with the same tasks, weights and limits as qpik's defaults.

    Its collision rows are the model's collision geoms on links 4–7 (the twin's capsules; a loaded arm's
    meshes) against the spheres.
    """
    scene_ = build_scene(robot, spheres)
    model = scene_.kin.model
    adr = scene_.kin.qpos_adr
    conf = mink.Configuration(model)
    qpos = model.qpos0.copy()  # joints that are not the arm's (fingers) stay at their reference
    ctrl = Controller.for_robot(robot)  # only to read the same default weights
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
    links = _links(model, robot)
    arm_geoms = [int(g) for g in scene_.link_geoms if links[int(model.geom_bodyid[g])] in LINKS]
    pairs = [(arm_geoms, [int(g) for g in scene_.obstacle_geoms])]
    limits = [
        mink.ConfigurationLimit(model),
        mink.VelocityLimit(model, vel),
        mink.CollisionAvoidanceLimit(
            model, pairs, minimum_distance_from_collisions=D_SAFE, collision_detection_distance=D_INFLUENCE
        ),
    ]

    def step(q):
        qpos[adr] = q
        conf.update(qpos)
        return mink.solve_ik(conf, tasks, DT, solver=solver, limits=limits)[scene_.kin.dof_adr]

    return step


def _links(model, robot) -> dict[int, int]:
    """body id -> the link k (1..n) of the last arm joint above it, 0 above joint 1."""
    joint_body = {int(model.joint(name).bodyid[0]): k for k, name in enumerate(robot.joint_names, start=1)}
    out = {0: 0}
    for b in range(1, model.nbody):  # parents come first in MuJoCo's body order
        out[b] = joint_body.get(b, out[int(model.body_parentid[b])])
    return out
