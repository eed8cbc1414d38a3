"""Bench: one full control step (kinematics, QP assembly, solve) of qpik beside mink, same arm, same run.

Scene (:func:`scene`): iiwa14 reaching for a pose 0.25 m above its start, closed loop
(``q ← q + v·dt``, dt = 1 ms, so every solver is warm-started the way it runs in a robot),
with four spheres above its elbow and wrist, in the way: the arm presses up against them,
and the obstacle rows of both libraries bind in almost every step (counted, see below).

- qpik: :meth:`Controller.for_robot` — FrameTask, PostureTask, ManipulabilityTask
  (∇m from the kinematic Hessian), DampingTask; ConfigurationLimit, VelocityLimit and
  ObstacleLimit (every one of the 5 capsules a joint moves against every sphere: 20 rows) —
  with solver ``osqp`` (persistent), ``daqp``, ``proxqp``, ``quadprog``;
- mink 1.3 on the MJCF twin (same kinematics): ``configuration.update(q)`` +
  ``mink.solve_ik`` with FrameTask, PostureTask, DampingTask and a manipulability task
  (:class:`MinkManipulabilityTask`, the same gradient) and ConfigurationLimit,
  VelocityLimit, CollisionAvoidanceLimit (the 4 capsules of links 4–7 × 4 spheres),
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
The loops are timed in interleaved blocks (:data:`HOT` steps of one library, then of the next,
:func:`qpik.bench.time_interleaved`), so the machine's busy spells fall on all of them and no library's
caches are evicted by another's single steps.
The iiwa14 scene is timed twice: without obstacles (no spheres, no collision rows on either side),
then with the spheres. The OSQP pair compares qpik's persistent, warm-started
OSQP with OSQP rebuilt from dense matrices each call (mink through qpsolvers): a real advantage,
labelled as such; the daqp pair is like for like. qpik's OSQP solver runs ADMM only when the
previous step's active set, completed by its dual active-set polish, does not give the answer
(:mod:`qpik.control.solvers.osqp`): the row's note says in how many steps ADMM ran. How often
each library's obstacle rows bind in the scene is measured in an untimed replay and given in the
notes: about 4 of qpik's rows in every step (iiwa14: two symmetric pairs, above the elbow and the
wrist), and mink's collision rows too (they bind only within ~1e-6 m of the minimum distance, since
mink bounds the step Δq by gain·(d − d_min)/dt, a speed; the arm pressing on the spheres reaches
it). The notes also count the different rows that bind over the run: 8 of qpik's 20 obstacle rows
(both spheres above the elbow against links 3–5, both above the wrist against link 5), at most 6 of
them at once; with 7 joints, more than 7 rows are at their bound in one step only when some are
linearly dependent (a degenerate QP).

In the scene without obstacles, placo (the test extra) runs too (:func:`_placo_step`): its
``KinematicsSolver`` on the robot's URDF (:meth:`Robot.to_urdf`, checked against qpik's FK
first), with the same tasks and weights (frame, joint posture, manipulability, regularization)
and joint and velocity limits, solved by placo's own QP (pinocchio + qpmad, formed each call).
Its tasks have no gain (each asks Δq to close the whole error), so its closed loop runs
differently; the row times the same call, a full step from q. placo has no sphere obstacles to
express the scene with obstacles, so it is not in those rows. qpik + osqp's ratio in that scene
is against placo.

Last, the rows ``fold + moving sphere: ...`` (:mod:`qpik.bench.controller_self`): self-collision pairs of a
folding motion and a moving sphere, qpik beside mink with the same self pairs on the same model.
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import numpy as np

from qpik.bench import Row, fmt_time, import_peer, time_interleaved
from qpik.bench.loop import (
    D_INFLUENCE,
    D_SAFE,
    DT,
    HOT,
    XI,
    closed_loop,
    full_q,
    mink_step,
    scene,
)
from qpik.control import Controller, ControllerOptions
from qpik.control.solvers import available
from qpik.control.solvers.osqp import REUSED
from qpik.core.errors import InputError
from qpik.robots.loader import load_robot
from qpik.robots.packaged import packaged_model

TITLE = (
    "Controller: one control step (iiwa14 twin, then the pybullet iiwa URDF; frame + posture + manipulability; "
    f"hot: interleaved blocks of {HOT} steps)"
)
LOADED = "pybullet/iiwa"
"""The arm loaded from another package's URDF (:mod:`qpik.robots.packaged`) whose rows follow iiwa14's."""
REPLAYS = 3
"""The closed loops are run this many times from the same start; the "best of replays" worst step takes,
for every step, its least thread CPU time over the replays (a host stall rarely hits the same step
twice), then the largest over the steps: the cost of the slowest step itself."""
QPIK_OSQP = "qpik + osqp (persistent, active set reused)"
MINK_OSQP = "mink + osqp (rebuilt each call)"
PLACO = "placo (pinocchio + qpmad, QP formed each call)"
"""The OSQP pair compares a persistent OSQP, which most steps answer from the previous step's active set, with
OSQP rebuilt each call (mink through qpsolvers); the daqp pair is the like-for-like one."""


def run(args: argparse.Namespace) -> list[Row]:
    repeat = max(100, int(getattr(args, "repeat", 2000)))
    iiwa = load_robot("iiwa14")
    home = iiwa.q_home
    rows = _arm_rows(iiwa, home, "no obstacles, hot: ", repeat, obstacles=False) + _arm_rows(iiwa, home, "", repeat)
    try:
        loaded = load_robot(packaged_model(LOADED))
    except InputError as exc:
        print(f"qpik bench controller: {exc}; rows left out")
        from qpik.bench.controller_self import rows as fold_rows

        return rows + fold_rows(repeat)
    rows += _arm_rows(loaded, home, "URDF iiwa: ", repeat)
    from qpik.bench.controller_self import rows as fold_rows  # it imports this module's scene

    return rows + fold_rows(repeat)


def _arm_rows(robot, home: np.ndarray, prefix: str, repeat: int, obstacles: bool = True) -> list[Row]:
    """The rows of one arm, labelled ``prefix + "qpik + osqp"`` etc.; without ``obstacles`` no sphere and no
    collision rows for either library."""
    q0, target, spheres = scene(robot, home)
    spheres = spheres if obstacles else []
    backends = available()  # proxqp and quadprog come with the test extra
    peers = [("osqp", MINK_OSQP), ("daqp", "mink + daqp"), ("proxqp", "mink + daqp"), ("quadprog", "mink + daqp")]
    for solver, _ in peers:
        if solver not in backends:
            print(f"qpik bench controller: {solver} not installed (pip install -e '.[test]'), row left out")
    peers = [(solver, ref) for solver, ref in peers if solver in backends]
    placo = None if obstacles else _placo_step(robot, target)
    if placo is not None:
        peers = [(solver, PLACO if solver == "osqp" else ref) for solver, ref in peers]
    passes = []
    for _ in range(REPLAYS):  # the same closed loops from the same start, each time with fresh solvers
        steps, refs, ctrls = {}, {}, {}
        for solver, label in (("osqp", MINK_OSQP), ("daqp", "mink + daqp")):
            steps[prefix + label] = closed_loop(mink_step(robot, target, spheres, solver)[0], q0)
        if placo is not None:
            steps[prefix + PLACO] = closed_loop(placo, q0)
        for solver, ref in peers:
            label = prefix + (QPIK_OSQP if solver == "osqp" else f"qpik + {solver}")
            ctrls[label] = _controller(robot, target, spheres, solver)
            steps[label], refs[label] = closed_loop(ctrls[label].step, q0), prefix + ref
        with warnings.catch_warnings():  # qpsolvers warns on every dense matrix mink hands to OSQP
            warnings.simplefilter("ignore")
            cpu: dict[str, np.ndarray] = {}
            passes.append((time_interleaved(steps, repeat // HOT, warmup=50, cpu=cpu, block=HOT), cpu))
    binding = _binding(robot, q0, target, spheres, repeat) if obstacles else {}
    admm = _admm_runs(robot, q0, target, spheres, repeat)
    rows = []
    for label in passes[0][0]:
        t = np.concatenate([times[label] for times, _ in passes])
        worst_cpu = max(float(c[label].max()) for _, c in passes)
        replayed = float(np.min([c[label] for _, c in passes], axis=0).max())  # per step: best of the replays
        note = (
            f"(worst in thread CPU time: {fmt_time(worst_cpu).strip()}; "
            f"best of {REPLAYS} replays: {fmt_time(replayed).strip()})"
        )
        library = label[len(prefix) :].split(" ")[0]
        if library in binding:
            note += f" ({binding[library]})"
        if label == prefix + QPIK_OSQP:
            note += f" ({admm})"
        rows.append(Row(label, float(np.median(t)), refs.get(label), float(np.percentile(t, 99)), float(t.max()), note))
    return rows


def _controller(robot, target, spheres, solver) -> Controller:
    return Controller.for_robot(  # like for like with mink's rows: no self pairs (the fold scene has them)
        robot,
        target=target,
        obstacles=spheres,
        dt=DT,
        solver=solver,
        d_safe=D_SAFE,
        options=ControllerOptions(d_influence=D_INFLUENCE, xi=XI, self_collision=False),
    )


def _binding(robot, q0, target, spheres, steps: int) -> dict[str, str]:
    """How often each library's obstacle rows bind in the scene (daqp, untimed replay of ``steps`` steps):
    qpik's active obstacle rows (:attr:`StepInfo.active`), and mink's CollisionAvoidanceLimit rows with
    ``h − G Δq ≤ 1e-9`` (at their bound), as a mean per step and the largest used fraction of mink's bound."""
    ctrl = _controller(robot, target, spheres, "daqp")
    step, limit, conf = mink_step(robot, target, spheres, "daqp")
    q, qm, active, bound, used = q0.copy(), q0.copy(), [], [], 0.0
    for _ in range(steps):
        q += ctrl.step(q) * DT
        active.append({name for name in ctrl.last.active if name.startswith("obstacle")})
        v = step(qm)
        G, h = limit.compute_qp_inequalities(conf, DT)
        if G is not None and len(h):
            Gdq = G @ (v * DT if len(v) == G.shape[1] else full_q(conf, v * DT, robot))
            bound.append(set(np.flatnonzero(h - Gdq <= 1e-9).tolist()))
            with np.errstate(divide="ignore", invalid="ignore"):
                frac = np.where(np.abs(h) > 0, Gdq / np.abs(h), 0.0)
            used = max(used, float(np.max(frac, initial=0.0)))
        qm += v * DT
    return {
        "qpik": _share("obstacle rows", active),
        "mink": _share("collision rows", bound) + f"; largest used fraction of a bound {used:.1e}",
    }


def _admm_runs(robot, q0, target, spheres, steps: int) -> str:
    """In how many steps of an untimed replay qpik's OSQP solver ran ADMM (the others reuse the previous step's
    active set, :data:`qpik.control.solvers.osqp.REUSED`)."""
    ctrl = _controller(robot, target, spheres, "osqp")
    q, runs = q0.copy(), 0
    for _ in range(steps):
        q += ctrl.step(q) * DT
        runs += ctrl.last.solver_status != REUSED
    return f"OSQP's ADMM ran in {runs} of {steps} steps; the others: its polish from the previous step's active set"


def _share(what: str, rows: list[set]) -> str:
    """How many rows bound per step (``rows``: the set of binding rows of each step): mean, most, the share of
    steps with any, and how many different rows bound over the run."""
    n = np.array([len(r) for r in rows] if rows else [0])
    distinct = len(set().union(*rows))
    return (
        f"{what} binding: {n.mean():.1f} per step (at most {n.max()}), in {np.mean(n > 0):.0%} of steps; "
        f"{distinct} different rows over the run"
    )


def _placo_step(robot, target):
    """placo's control step ``q -> v`` (rad/s) on the robot's URDF, with qpik's default tasks and weights, joint and
    velocity limits; None (with a line saying why) when placo does not import or its FK disagrees with qpik's.

    Tasks: the frame task (placo's position and orientation weights: qpik's), a joints task to the posture
    reference, placo's manipulability task on the end-effector frame and its regularization task, each soft with
    qpik's weight. The URDF is :meth:`Robot.to_urdf`; placo's end-effector pose is checked against qpik's FK on 20
    random configurations (1e-9) before anything is timed.
    """
    try:
        placo = import_peer("placo")
    except ImportError as exc:
        print(f"qpik bench controller: placo not installed (pip install -e '.[test]'), rows left out ({exc})")
        return None
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "robot.urdf"
        path.write_text(robot.to_urdf())
        wrapper = placo.RobotWrapper(str(path), placo.Flags.ignore_collisions)
    q_at = [wrapper.get_joint_offset(name) for name in robot.joint_names]
    v_at = [wrapper.get_joint_v_offset(name) for name in robot.joint_names]
    state = wrapper.state.q  # a view of placo's configuration
    for q in np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (20, robot.dof)):
        state[q_at] = q
        wrapper.update_kinematics()
        gap = float(np.abs(wrapper.get_T_world_frame(robot.site) - robot.fk(q)).max())
        if gap > 1e-9:
            print(f"qpik bench controller: placo's FK differs from qpik's by {gap:.1e}, rows left out")
            return None
    frame_task, posture, manip, damping = Controller.for_robot(robot).tasks  # only to read the default weights
    solver = placo.KinematicsSolver(wrapper)
    solver.mask_fbase(True)
    solver.dt = DT
    solver.add_frame_task(robot.site, target).configure("frame", "soft", frame_task.weight[0], frame_task.weight[3])
    joints = solver.add_joints_task()
    joints.set_joints(dict(zip(robot.joint_names, posture.q_ref.tolist())))
    joints.configure("posture", "soft", posture.weight)
    solver.add_manipulability_task(robot.site, "both", 1.0).configure("manipulability", "soft", manip.weight)
    solver.add_regularization_task(damping.weight)
    solver.enable_joint_limits(True)
    solver.enable_velocity_limits(True)

    def step(q):
        state[q_at] = q
        wrapper.update_kinematics()
        return solver.solve(False)[v_at] / DT

    return step
