r"""Closed-loop runs of a joint-velocity policy on a MuJoCo model of the arm.

The model is the robot's own (:meth:`qpik.Robot.mj_spec`: the MJCF twin of a catalog
arm, the MJCF/URDF model of a loaded one) or any MJCF arm (joint names and
end-effector site given), with the obstacles added to its
``<worldbody>`` as geoms, so MuJoCo draws them and measures distances on its
own. Each step *k* (:math:`t_k = k\,\Delta t`):

1. the policy maps :math:`(t_k, q_k)` to a joint velocity :math:`v_k` (rad/s);
2. kinematic integration :math:`q_{k+1} = q_k \oplus v_k \Delta t`
   (``mj_integratePos``, which is :math:`q_k + v_k \Delta t` for hinges), then
   ``mj_kinematics``;
3. on recorded steps: end-effector pose, target pose, the signed distance of
   every link geom to every obstacle geom (``mj_geomDistance``, independent of
   the controller's own distance code) and the manipulability
   :math:`\sqrt{\det J J^\top}` from MuJoCo's site Jacobian.

A *policy* is a callable ``policy(t, q) -> v`` or a controller: any object with
``step(q, target=None, twist=None) -> v``. A controller is given the target before each step by
:func:`follow` (pose and feed-forward twist of a path), and its ``last`` step
information (status, solve time), when it has one, goes into the log.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import finite_array, joint_vector, single_pose
from qpik.geometry.contacts import geom_facts
from qpik.geometry.paths import TimedPath
from qpik.geometry.shapes import Shape
from qpik.robots.mujoco_scene import MjScene, build_scene
from qpik.robots.robot import Robot
from qpik.sim.log import SimLog
from qpik.sim.options import SimOptions

MAX_STEPS = 1e8
"""Most steps of one run (``duration / dt``)."""
MAX_RECORDS = 10**6
"""Most records of one log (``steps / record_every``): each holds the clearance of every link–obstacle pair."""


Target = np.ndarray | TimedPath | None
PolicyFn = Callable[[float, np.ndarray], np.ndarray]


def follow(controller: object, target: Target) -> PolicyFn:
    """A policy ``(t, q) -> v`` from a controller's ``step(q, target=None, twist=None)``.

    A path's pose and feed-forward twist at t are handed to every step; a constant
    pose to the first step only (the controller keeps it); ``None`` keeps the
    controller's own target.
    """
    if target is None:
        return lambda t, q: controller.step(q)
    if hasattr(target, "pose"):
        return lambda t, q: controller.step(q, target.pose(t), target.twist(t))
    pending = [target]

    def constant(t: float, q: np.ndarray) -> np.ndarray:
        return controller.step(q, pending.pop()) if pending else controller.step(q)

    return constant


def target_pose(target: Target, t: float) -> np.ndarray | None:
    """The target pose (4, 4) at t: a constant pose, a path's pose, or ``None``."""
    if target is None:
        return None
    if hasattr(target, "pose"):
        return np.asarray(target.pose(t), dtype=float)
    return target


def simulate(
    arm: Robot | str | os.PathLike | MjScene,
    policy: PolicyFn | object,
    q0: np.ndarray,
    duration: float,
    dt: float = 0.001,
    obstacles: Sequence[Shape] = (),
    target: Target = None,
    *,
    options: SimOptions | None = None,
) -> SimLog:
    """Run ``policy`` in closed loop for ``duration`` seconds and log it.

    Args:
        arm: a :class:`Robot` (MJCF twin), an MJCF string or path (its hinge joints, site ``ee``), or a ready
            :class:`~qpik.robots.mujoco_scene.MjScene` (:func:`~qpik.robots.mujoco_scene.build_scene` of any MJCF
            arm with its joint names and site).
        policy: ``policy(t, q) -> v`` (rad/s, (n,)), or an object with
            ``step(q) -> v`` — a controller, given ``target`` through :func:`follow`.
        q0: initial configuration (n,) (rad).
        duration: simulated time (s); ``round(duration / dt)`` steps are taken.
        dt: integration step (s).
        obstacles: shapes (world frame, which is the robot's base frame) added to the model (ignored for an MjScene).
        target: a pose (4, 4), a :class:`TimedPath` (``pose(t)``, ``twist(t)``) or
            ``None``; logged, and handed to a controller.
        options: what is recorded (every how many steps), the summary's velocity limits, the d_safe marked on
            plots, the label and the progress bar (:class:`~qpik.sim.options.SimOptions`; default its defaults).

    Returns:
        A :class:`SimLog` with ``1 + ceil(N / record_every)`` records, N the number of steps.
    """
    options = SimOptions() if options is None else options
    if not isinstance(options, SimOptions):
        raise InputError(f"options: expected SimOptions, got {type(options).__name__}")
    record_every, v_max, d_safe, label = options.record_every, options.v_max, options.d_safe, options.label
    scene = arm if isinstance(arm, MjScene) else build_scene(arm, obstacles)
    kin, model, data = scene.kin, scene.kin.model, scene.kin.data
    n = kin.dof
    q0, batched = joint_vector(q0, n, "q0")
    if batched:
        raise InputError(f"q0: expected shape ({n},), got {q0.shape}")
    dt = float(finite_array(dt, "dt", ()))
    duration = float(finite_array(duration, "duration", ()))
    if dt <= 0:
        raise InputError(f"dt: must be > 0, got {dt}")
    if duration <= 0 or duration < dt:
        raise InputError(f"duration: must be > 0 and >= dt = {dt:g} s (one step at least), got {duration}")
    if isinstance(record_every, bool) or not isinstance(record_every, int | np.integer) or record_every < 1:
        raise InputError(f"record_every: must be an integer >= 1, got {record_every!r}")
    if target is not None and not hasattr(target, "pose"):
        target = single_pose(target, "target")
    every = int(record_every)
    if duration / dt > MAX_STEPS:
        raise InputError(f"duration / dt: at most {MAX_STEPS:g} steps, got {duration / dt:.3g}")
    steps = round(duration / dt)
    if steps // every + 2 > MAX_RECORDS:
        raise InputError(f"record_every: at most {MAX_RECORDS:g} records are kept, {steps} steps need {every} or more")
    records = sorted(set(range(0, steps + 1, every)) | {steps})
    fn, reporter = _policy(policy, target)
    if v_max is None and scene.robot is not None:
        v_max = scene.robot.v_max

    K, L, O = len(records), len(scene.link_geoms), len(scene.obstacle_geoms)
    log_t = np.array(records, dtype=float) * dt
    log_q, log_v = np.zeros((K, n)), np.zeros((K, n))
    log_ee = np.zeros((K, 4, 4))
    log_target = np.zeros((K, 4, 4)) if target is not None else None
    log_clear = np.zeros((K, L, O))
    log_m = np.zeros(K)
    log_time = np.full(K, np.nan)
    log_status = np.full(K, "", dtype=object)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    qpos, qvel = model.qpos0.copy(), np.zeros(model.nv)
    qpos[kin.qpos_adr] = q0
    q = q0.copy()
    kin.update(q)

    bar = _progress_bar(steps + 1, options.progress, label)
    r = 0
    for k in range(steps + 1):
        t = k * dt
        v = np.asarray(fn(t, q.copy()), dtype=float)
        if v.shape != (n,) or not np.all(np.isfinite(v)):
            raise InputError(f"policy: returned {v!r} at t={t:g} s; expected a finite ({n},) vector")
        if r < K and records[r] == k:
            log_q[r], log_v[r] = q, v
            log_ee[r, :3, :3] = data.site_xmat[kin.site_id].reshape(3, 3)
            log_ee[r, :3, 3] = data.site_xpos[kin.site_id]
            log_ee[r, 3, 3] = 1.0
            if log_target is not None:
                log_target[r] = target_pose(target, t)
            scene.clearances(log_clear[r])
            mujoco.mj_jacSite(model, data, jacp, jacr, kin.site_id)
            J = kin.columns(np.vstack((jacp, jacr)))
            log_m[r] = np.sqrt(max(np.linalg.det(J @ J.T), 0.0))
            if reporter is not None:
                log_status[r], log_time[r] = reporter()
            r += 1
        if k < steps:
            qvel[kin.dof_adr] = v
            mujoco.mj_integratePos(model, qpos, qvel, dt)
            q = qpos[kin.qpos_adr].copy()
            kin.update(q)
            qpos[:] = kin.data.qpos  # mimic joints follow their leaders
        if bar is not None and (k % 200 == 0 or k == steps):
            bar.update(k + 1 - bar.n)
    if bar is not None:
        bar.close()
    return SimLog(
        t=log_t,
        q=log_q,
        v=log_v,
        ee=log_ee,
        target=log_target,
        clearance=log_clear,
        manipulability=log_m,
        solve_time=log_time,
        status=log_status,
        q_min=kin.q_min.copy(),
        q_max=kin.q_max.copy(),
        v_max=None if v_max is None else np.asarray(v_max, dtype=float),
        link_names=scene.link_names,
        obstacle_names=scene.obstacle_names,
        dt=dt,
        d_safe=d_safe,
        label=label,
        robot=scene.robot if scene.robot is not None else kin,
        obstacles=scene.obstacles,
        checked=scene.checked.copy(),
        facts=tuple(str(f) for f in geom_facts(scene, scene.checked, log_clear[0])),
    )


def _policy(policy: PolicyFn | object, target: Target) -> tuple[PolicyFn, Callable[[], tuple[str, float]] | None]:
    """The policy as ``(t, q) -> v`` and, for a controller, a reader of its last (status, solve time)."""
    if hasattr(policy, "step"):
        return follow(policy, target), lambda: _last_info(policy)
    if callable(policy):
        return policy, None
    raise InputError("policy: expected a callable (t, q) -> v or an object with step(q)")


def _last_info(controller: object) -> tuple[str, float]:
    last = getattr(controller, "last", None)
    if last is None:
        return "", float("nan")
    return str(getattr(last, "status", "")), float(getattr(last, "solve_time", float("nan")))


def _progress_bar(total: int, progress: bool | None, label: str):
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit="step", leave=False)
