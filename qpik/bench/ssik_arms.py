"""The 7-R arms that ssik ships, as model files qpik loads, and ``qpik.ik`` beside ssik's ``solve`` on each of them
(``qpik bench analytic``).

ssik (PyPI ``ssik``) lists the arms it ships (``ssik.list_arms()``) and gives each, through its public
``ssik.Manipulator.from_prebuilt(name)``, its prebuilt solver (``solve``), its FK (``fk``) and its chain (``kinbody``:
per joint a fixed transform before the joint, ``T_left``, its axis, a fixed transform after it, ``T_right``, and its
limits, None for a continuous joint; the FK is the product of ``T_left · R(axis, q) · T_right``). :func:`mjcf` writes
that chain as an MJCF file (one body per joint, the transforms as positions and quaternions at full precision, a
continuous joint unlimited, a site ``tip`` at the flange), which :func:`qpik.load_robot` reads as any user's file: its
family is recognised from the axes, as for any file. Every arm's FK is checked against ssik's own ``fk`` before it is
used (the rows' notes give the agreement).

:func:`ssik_rows`: for each such arm of a family (a closed form, the 1-D search or the general 6-R), poses ``fk(q)`` for
configurations drawn inside its limits (seed 3), ``qpik.ik`` (every branch at the configuration's own parameter) and
ssik's ``solve(T)`` (its prebuilt solver of the same arm: it samples the self-motion, a larger question, and the issue's
reference for speed), each answer checked by qpik's FK, then timed interleaved. The files are written to a temporary
folder that is removed when the rows are done.
"""

from __future__ import annotations

import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from qpik.analytic.api import closed_form_for, ik, redundancy_parameter, symbol
from qpik.bench import Row, cycle, import_peer, time_interleaved
from qpik.bench.analytic_locked import POSES, check_note, qpik_solutions
from qpik.core.errors import InputError, QpikError
from qpik.robots.loader import load_robot
from qpik.robots.robot import Robot

TIP = "tip"
"""The site at the flange in every file :func:`mjcf` writes."""


@dataclass(frozen=True)
class SsikArm:
    """One arm that ssik ships: ``name`` (ssik's display name), ``key`` (the name in ``ssik.list_arms()``)."""

    name: str
    key: str

    @cached_property
    def arm(self) -> Any:
        """Its ``ssik.Manipulator`` (which imports the arm's prebuilt module), made on first use."""
        return import_peer("ssik").Manipulator.from_prebuilt(self.key)


def seven_r_arms() -> list[SsikArm]:
    """The arms ssik ships with 7 joints, in its list's order, from its catalog alone ([] without ssik)."""
    try:
        ssik = import_peer("ssik")
    except ImportError:
        return []
    return [SsikArm(entry.display_name, entry.name) for entry in ssik.list_arms() if entry.dof == 7]


def mjcf(ssik_arm: SsikArm) -> str:
    """The MJCF text of an arm of ssik's (module docstring): body k at ``T_right(k−1) · T_left(k)`` in body k − 1 with
    joint k about its axis, and the site :data:`TIP` at ``T_right(7)`` in body 7.

    Raises:
        InputError: a joint of the arm is not revolute (the file has hinges only).
    """
    joints = ssik_arm.arm.kinbody.joints
    if any(joint.joint_type != "revolute" for joint in joints):
        raise InputError(f"{ssik_arm.name}: ssik's chain has a joint that is not revolute")
    lines = [f"<mujoco model={quoteattr(ssik_arm.name)}>", '<compiler angle="radian"/>', "<worldbody>"]
    before = np.eye(4)
    for k, joint in enumerate(joints):
        limit = joint.limits
        rng = ' limited="false"' if limit is None else f' limited="true" range="{_numbers(limit)}"'
        lines += [
            f'<body name="link{k + 1}" {_placement(before @ np.asarray(joint.T_left, float))}>',
            '<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>',
            f'<joint name="joint{k + 1}" type="hinge" axis="{_numbers(joint.axis)}"{rng}/>',
        ]
        before = np.asarray(joint.T_right, float)
    lines.append(f'<site name="{TIP}" {_placement(before)}/>')
    lines += ["</body>"] * len(joints) + ["</worldbody>", "</mujoco>", ""]
    return "\n".join(lines)


def load_arm(ssik_arm: SsikArm, folder: Path) -> Robot:
    """The arm, written by :func:`mjcf` into ``folder`` and loaded by :func:`qpik.load_robot`."""
    path = folder / (re.sub(r"[^A-Za-z0-9]+", "_", ssik_arm.name).strip("_") + ".xml")
    path.write_text(mjcf(ssik_arm))
    return load_robot(path, tip=TIP, name=ssik_arm.name)


def fk_agreement(robot: Robot, ssik_arm: SsikArm, q: np.ndarray) -> float:
    """The largest difference of qpik's FK of ``robot`` and ssik's ``fk`` at configurations q (N, 7) (m and rotation
    entries)."""
    return float(max(np.abs(robot.fk(x) - np.asarray(ssik_arm.arm.fk(x), float)).max() for x in q))


def ssik_rows(repeat: int, block: int, row: Callable[..., Row]) -> list[Row]:
    """The rows of every arm of :func:`seven_r_arms` of a family (module docstring);
    ``row(label, seconds, ref, note)`` makes one."""
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as folder:
        for ssik_arm in seven_r_arms():
            try:
                robot = load_arm(ssik_arm, Path(folder))
            except QpikError as exc:
                print(f"qpik bench analytic: ssik's {ssik_arm.name} left out: {exc}")
                continue
            if robot.closed_form is None:
                print(f"qpik bench analytic: ssik's {ssik_arm.name} left out: {robot.notes.split(';')[0]}")
                continue
            rows += _beside_ssik(robot, ssik_arm, max(20, repeat // block), block, row)
    return rows


def _beside_ssik(robot: Robot, ssik_arm: SsikArm, samples: int, block: int, row: Callable[..., Row]) -> list[Row]:
    """qpik.ik and ssik's ``solve`` on the same poses of ``robot``, checked, then timed interleaved."""
    q = np.random.default_rng(3).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    T = robot.fk(q)
    param = np.asarray(redundancy_parameter(robot, q)[0], float)
    peers = {
        "qpik": (lambda i: ik(robot, T[i], float(param[i])), qpik_solutions),
        "ssik": (lambda i: ssik_arm.arm.solve(T[i]), lambda out: [s.q for s in out]),
    }
    notes = {k: check_note(robot, T, q, fn, solutions) for k, (fn, solutions) in peers.items()}
    notes["ssik"] += f" (ssik's fk = qpik's FK of the file to {fk_agreement(robot, ssik_arm, q[:8]):.0e})"
    t = time_interleaved({k: cycle(fn, list(range(POSES))) for k, (fn, _) in peers.items()}, samples, block=block)
    solver = closed_form_for(robot)
    name, kind = ssik_arm.name, robot.closed_form.replace("_", " ")
    ours = f"{name}: qpik.ik, {solver.n_branches} branches ({kind}, {symbol(solver.param_name)})"
    theirs = f"{name}: ssik solve (self-motion sampled)"
    return [row(ours, t["qpik"], theirs, notes["qpik"]), row(theirs, t["ssik"], None, notes["ssik"])]


def _placement(T: np.ndarray) -> str:
    """``pos="…" quat="…"`` of a rigid transform (MuJoCo's w, x, y, z quaternion), full precision."""
    import mujoco  # here: qpik chooses MuJoCo's GL backend before mujoco is imported

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T[:3, :3]).ravel())
    return f'pos="{_numbers(T[:3, 3])}" quat="{_numbers(quat)}"'


def _numbers(x) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(x))
