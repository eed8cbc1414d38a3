"""Pose + Jacobian of the end effector: qpik beside pinocchio, mink and raw MuJoCo on the same arm.

For each arm, mink runs on the robot's MuJoCo model (:meth:`Robot.mj_model`, site
:attr:`Robot.site`): the MJCF twin of a catalog arm, and for the arms loaded from the
URDFs of other packages (:data:`LOADED`, when installed) their own model, meshes and
all; its pose and Jacobian are first checked against qpik's (mink
returns the Jacobian in the site frame, so it is rotated to the base frame).
Rows per arm:

- qpik single configuration, ``robot.fk_jacobian(q)`` (q checked, new pose and Jacobian arrays);
- pinocchio (``pin``, the test extra) on the URDF of :meth:`Robot.to_urdf`, first checked against
  qpik: ``pin.computeFrameJacobian(model, data, q, ee, LOCAL_WORLD_ALIGNED)``, which returns J
  and updates ``data.oMf[ee]``, plus ``data.oMf[ee].homogeneous`` (the pose as an array): the same
  two outputs as qpik's call. A second row gives ``computeFrameJacobian`` alone (J only);
- mink: ``cfg.update(q)``, ``get_frame_jacobian("ee", "site")``,
  ``get_transform_frame_to_world("ee", "site")``;
- raw MuJoCo, the floor under mink: ``mj_kinematics + mj_comPos + mj_jacSite``
  (no pose copy, no frame change);
- qpik batched, ``robot.fk_jacobian(Q)`` with Q (10000, 7), reported per configuration.

Configurations are drawn once, uniformly inside the limits; the single-q rows
cycle through the first 1000 of them and are timed interleaved, in blocks of :data:`BLOCK` calls
of one peer ("hot"; every row includes the same loop and cycling, about 0.1 µs).
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
from collections.abc import Callable
from pathlib import Path

import mink
import mujoco
import numpy as np

from qpik.bench import Row, import_peer, time_calls, time_interleaved
from qpik.core.errors import InputError
from qpik.robots.loader import load_robot
from qpik.robots.packaged import packaged_model
from qpik.robots.robot import Robot

TITLE = "kinematics: end-effector pose + geometric Jacobian (qpik vs pinocchio vs mink vs raw MuJoCo; hot)"
ARMS = ("iiwa14", "panda", "nammoto7", "zheng7")
LOADED = {"pybullet iiwa URDF": "pybullet/iiwa", "erd panda URDF": "erd/panda"}
"""Arms loaded from other packages' model files (:mod:`qpik.robots.packaged`; erd: example-robot-data): label -> key."""
BATCH = 10_000
BLOCK = 50
"""Single-q rows: each sample is a block of this many calls (q cycling), timed as one and divided."""
BATCH_CALLS = 20
"""Batched calls timed per batched row (at least; more with a larger --repeat)."""


def run(args: argparse.Namespace) -> list[Row]:
    rows: list[Row] = []
    for name in ARMS:
        rows += _arm_rows(name, load_robot(name), args.repeat)
    for label, key in LOADED.items():
        try:
            robot = load_robot(packaged_model(key))
        except InputError as exc:
            print(f"qpik bench kinematics: {exc}; row left out")
            continue
        rows += _arm_rows(label, robot, args.repeat)
    return rows


def _arm_rows(name: str, robot: Robot, repeat: int) -> list[Row]:
    Q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, size=(BATCH, robot.dof))
    model = robot.mj_model()
    cfg = mink.Configuration(model)
    data = mujoco.MjData(model)
    site = model.site(robot.site).id
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    adr = np.array([model.jnt_qposadr[model.joint(j).id] for j in robot.joint_names])
    qpos = model.qpos0.copy()  # the joints that are not the arm's (fingers) stay at their reference

    def qpik_single(q: np.ndarray) -> object:
        return robot.fk_jacobian(q)

    def mink_single(q: np.ndarray) -> tuple[np.ndarray, mink.SE3]:
        qpos[adr] = q
        cfg.update(qpos)
        return cfg.get_frame_jacobian(robot.site, "site"), cfg.get_transform_frame_to_world(robot.site, "site")

    def raw_single(q: np.ndarray) -> None:
        data.qpos[adr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jp, jr, site)

    dof = np.array([model.jnt_dofadr[model.joint(j).id] for j in robot.joint_names])
    agree = _twin_error(robot, Q[:100], mink_single, dof)

    def cycled(fn: Callable[[np.ndarray], object]) -> Callable[[], object]:
        it = itertools.cycle(Q[:1000])
        return lambda: fn(next(it))

    mink_label = f"{name}: mink"
    pin_label = f"{name}: pinocchio J + pose"
    peers = {
        f"{name}: qpik fk_jacobian (1 q)": (qpik_single, pin_label, ""),
        pin_label: None,
        f"{name}: pinocchio J only": None,
        mink_label: (mink_single, None, f"(model agrees with qpik to {agree:.0e})"),
        f"{name}: raw mujoco (floor)": (raw_single, mink_label, ""),
    }
    pin_calls = _pinocchio(robot, Q[:100])
    if pin_calls is None:
        del peers[pin_label], peers[f"{name}: pinocchio J only"]
        peers[f"{name}: qpik fk_jacobian (1 q)"] = (qpik_single, mink_label, "")
    else:
        both, only, pin_agree = pin_calls
        note = f"(computeFrameJacobian + oMf[ee].homogeneous; agrees with qpik to {pin_agree:.0e})"
        peers[pin_label] = (both, None, note)
        peers[f"{name}: pinocchio J only"] = (only, pin_label, "(computeFrameJacobian alone: no pose array)")
    times = time_interleaved({label: cycled(fn) for label, (fn, _, _) in peers.items()}, repeat, block=BLOCK)
    rows = [
        Row(label, float(np.median(t)), ref, float(np.percentile(t, 99)), float(t.max()), note)
        for (label, (_, ref, note)), t in zip(peers.items(), times.values())
    ]
    tb = time_calls(lambda: robot.fk_jacobian(Q), max(BATCH_CALLS, repeat // 100), warmup=1)
    per_q = float(np.median(tb)) / BATCH
    rows.append(Row(f"{name}: qpik batched N={BATCH}, per q", per_q, mink_label, note=f"({1 / per_q:.2e} q/s)"))
    return rows


def _pinocchio(robot: Robot, Q: np.ndarray):
    """``(both, only, agreement)``: pinocchio's pose + Jacobian call and its Jacobian-only call of one q on the
    robot's URDF, and their largest difference from qpik over ``Q``; None without pinocchio."""
    try:
        pin = import_peer("pinocchio")
    except ImportError:
        print("qpik bench kinematics: pinocchio (pin) not installed (pip install -e '.[test]'), rows left out")
        return None
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp, "arm.urdf")
        path.write_text(robot.to_urdf())
        model = pin.buildModelFromUrdf(str(path))
    data, ee, frame = model.createData(), model.getFrameId("ee"), pin.LOCAL_WORLD_ALIGNED

    def both(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return pin.computeFrameJacobian(model, data, q, ee, frame), data.oMf[ee].homogeneous

    def only(q: np.ndarray) -> np.ndarray:
        return pin.computeFrameJacobian(model, data, q, ee, frame)

    err = 0.0
    for q in Q:
        J, T = both(q)
        Tq, Jq = robot.fk_jacobian(q)
        err = max(err, np.abs(T - Tq).max(), np.abs(J - Jq).max())
    return both, only, err


def _twin_error(robot: Robot, Q: np.ndarray, mink_single: Callable[[np.ndarray], tuple], dof: np.ndarray) -> float:
    """Largest difference of pose and base-frame Jacobian between qpik and mink on the robot's model."""
    err = 0.0
    for q in Q:
        T, J = robot.fk_jacobian(q)
        J_site, pose = mink_single(q)
        J_site = J_site[:, dof]  # the arm's columns (a model may have more joints: fingers)
        Tm = pose.as_matrix()
        R = Tm[:3, :3]
        J_base = np.vstack([R @ J_site[:3], R @ J_site[3:]])
        err = max(err, np.abs(Tm - T).max(), np.abs(J_base - J).max())
    return err
