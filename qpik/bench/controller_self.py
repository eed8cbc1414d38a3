"""Bench rows: a control step with self-collision pairs and a moving sphere, qpik beside mink, same model.

Scene: the iiwa14 twin from the spheres scene of :mod:`qpik.bench.controller`, its target moved
:data:`FOLD` of the way from the hand toward the arm's own shoulder (a folding motion: the forearm and the hand
come toward the upper arm and the base column), and the first sphere moving at :data:`SPEED` m/s along y,
back and forth (a triangle wave of amplitude :data:`AMPLITUDE` m).

- qpik: :meth:`Controller.for_robot`, its :class:`SelfCollisionLimit` checking every non-adjacent capsule pair
  except those that overlap at every configuration (:func:`qpik.robots.self_pairs.always_in_collision`: the
  iiwa14's capsules of links k and k + 2 wrap the joint between them; no controller could keep them apart):
  12 pairs, where the default list (:func:`~qpik.robots.self_pairs.default_allowed`) also leaves out the pairs
  never within 5 cm and keeps 3; the sphere's velocity is given to its damper (:meth:`ObstacleLimit.translate`);
- mink: ``CollisionAvoidanceLimit`` over the same capsule pairs (the twin's geoms ``link<k>_capsule``)
  and links 4–7 against the spheres; mink has no moving-obstacle term, so the sphere's geom is moved in
  its model each step and its damper treats it as standing still.

Both sides compute, every step, the distance of every pair (qpik: in its compiled step, with the witness
Jacobian rows; mink: ``mj_geomDistance`` per pair within its detection distance) and keep one row per pair
(beyond the influence distance a row is unbounded). The sphere's path is tabulated before the run (one period,
:func:`path`), so neither side's time includes computing it.
"""

from __future__ import annotations

import mujoco
import numpy as np

from qpik.bench import Row, time_interleaved
from qpik.bench.loop import D_INFLUENCE, D_SAFE, DT, HOT, XI, closed_loop, mink_step, scene
from qpik.control import Controller, ControllerOptions, ObstacleLimit
from qpik.control.self_collision import SelfCollisionLimit
from qpik.geometry.shapes import Sphere
from qpik.robots.loader import load_robot
from qpik.robots.mujoco_scene import build_scene
from qpik.robots.robot import Robot
from qpik.robots.self_pairs import always_in_collision

FOLD = 0.6
"""The target's position: this fraction of the way from the hand to the shoulder."""
SPEED, AMPLITUDE = 0.2, 0.1
"""m/s and m: the moving sphere."""


def fold_scene(robot: Robot) -> tuple[np.ndarray, np.ndarray, list[Sphere]]:
    """Start (n,), rad, the folding target (4, 4) and the four spheres (see the module docstring)."""
    q0, target, spheres = scene(robot, robot.q_home)
    target = robot.fk(q0)
    shoulder = robot.capsule_segments(q0)[1, 0]
    target[:3, 3] += FOLD * (shoulder - target[:3, 3])
    return q0, target, spheres


def path() -> tuple[np.ndarray, np.ndarray]:
    """The moving sphere's offset (P, 3), m, and velocity (P, 6) ``[v; ω]``, m/s, rad/s, at the P steps of one
    period (:func:`offset`, :func:`velocity`)."""
    steps = round(4 * AMPLITUDE / SPEED / DT)
    offsets, velocities = np.zeros((steps, 3)), np.zeros((steps, 6))
    for k in range(steps):
        offsets[k, 1], velocities[k, 1] = offset(k), velocity(k)
    return offsets, velocities


def offset(k: int) -> float:
    """The moving sphere's y offset (m) at step k (triangle wave)."""
    period = 4 * AMPLITUDE / SPEED
    phase = (k * DT) % period / period
    return AMPLITUDE * (4 * phase if phase < 0.25 else 2 - 4 * phase if phase < 0.75 else 4 * phase - 4)


def velocity(k: int) -> float:
    """The moving sphere's y velocity (m/s) at step k."""
    period = 4 * AMPLITUDE / SPEED
    phase = (k * DT) % period / period
    return SPEED if phase < 0.25 or phase >= 0.75 else -SPEED


def _qpik_step(robot: Robot, target, spheres, solver: str):
    ctrl = Controller.for_robot(
        robot, target=target, obstacles=spheres, dt=DT, solver=solver, d_safe=D_SAFE,
        options=ControllerOptions(d_influence=D_INFLUENCE, xi=XI),
    )  # fmt: skip
    swap = {
        ObstacleLimit: lambda: ObstacleLimit(spheres, D_INFLUENCE, D_SAFE, XI, moving=True),
        SelfCollisionLimit: lambda: SelfCollisionLimit(allowed=always_in_collision(robot)),
    }
    limits = [swap[type(lim)]() if type(lim) in swap else lim for lim in ctrl.limits]
    ctrl = Controller(robot, ctrl.tasks, limits, solver=solver, dt=DT)
    obstacle = next(lim for lim in limits if isinstance(lim, ObstacleLimit))
    offsets, velocities = path()
    centres = spheres[0].center + offsets
    count = [0]

    def step(q):
        k = count[0] % len(centres)
        count[0] += 1
        obstacle.translate(0, centres[k], velocities[k])
        return ctrl.step(q)

    return step, ctrl


def _mink_self_step(robot: Robot, target, spheres, solver: str, pairs):
    """mink's step with its collision rows over the self ``pairs`` too; the first sphere's geom moved each step."""
    model = build_scene(robot, spheres).kin.model  # the same model mink_step builds: geom ids agree
    geom = {
        c: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"link{cap.link}_capsule")
        for c, cap in enumerate(robot.capsules)
    }
    step, _, conf = mink_step(robot, target, spheres, solver, tuple(([geom[c]], [geom[e]]) for c, e in pairs))
    ball = mujoco.mj_name2id(conf.model, mujoco.mjtObj.mjOBJ_GEOM, "obstacles/0")
    centres = conf.model.geom_pos[ball] + path()[0]
    count = [0]

    def moved(q):
        conf.model.geom_pos[ball] = centres[count[0] % len(centres)]
        count[0] += 1
        return step(q)

    return moved


def rows(repeat: int) -> list[Row]:
    """The scene's rows: qpik + osqp, qpik + daqp and mink + daqp (median, p99, worst per step, s)."""
    robot = load_robot("iiwa14")
    q0, target, spheres = fold_scene(robot)
    checker = SelfCollisionLimit(allowed=always_in_collision(robot))
    checker.check(robot, DT)
    pairs = checker.pairs(robot)
    steps, refs = {}, {}
    for solver in ("osqp", "daqp"):
        step, _ = _qpik_step(robot, target, spheres, solver)
        steps[f"fold + moving sphere: qpik + {solver}"] = closed_loop(step, q0)
        refs[f"fold + moving sphere: qpik + {solver}"] = "fold + moving sphere: mink + daqp"
    steps["fold + moving sphere: mink + daqp"] = closed_loop(_mink_self_step(robot, target, spheres, "daqp", pairs), q0)
    times = time_interleaved(steps, max(2, repeat // HOT), warmup=50, block=HOT)
    note = (
        f"{len(pairs)} self pairs (every non-adjacent pair but {len(always_in_collision(robot))} always overlapping)"
        f" + 4 spheres, one moving at {SPEED} m/s; "
        "qpik's damper is given its velocity, mink's treats it as standing still"
    )
    out = []
    for label, t in times.items():
        out.append(Row(label, float(np.median(t)), refs.get(label), float(np.percentile(t, 99)), float(t.max()), note))
    return out
