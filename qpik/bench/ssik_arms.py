"""The 7-R arms that ssik ships, as model files qpik loads, and ``qpik.ik`` beside ssik's ``solve`` on each of them
(``qpik bench analytic``).

ssik (PyPI ``ssik``) bakes each arm's kinematics into its module ``ssik.prebuilt.<maker>.<arm>_ik``: per joint a fixed
transform before the joint (``_JOINT_T_LEFTS``), its axis (``_JOINT_AXES``), a fixed transform after it
(``_JOINT_T_RIGHTS``) and its limits (``_JOINT_LIMITS``, None for a continuous joint), its FK the product of
``T_left · R(axis, q) · T_right`` (``fk``). :func:`mjcf` writes that chain as an MJCF file (one body per joint, the
transforms as positions and quaternions at full precision, a continuous joint unlimited, a site ``tip`` at the
flange), which :func:`qpik.load_robot` reads as any user's file: its family is recognised from the axes, as for any
file. Every arm's FK is checked against ssik's own ``fk`` before it is used (the rows' notes give the agreement).

:func:`ssik_rows`: for each such arm with a closed form or the 1-D search, poses ``fk(q)`` for configurations drawn
inside its limits (seed 3), ``qpik.ik`` (every branch at the configuration's own parameter) and ssik's ``solve(T)``
(its prebuilt solver of the same arm: it samples the self-motion, a larger question, and the issue's reference for
speed), each answer checked by qpik's FK, then timed interleaved. The files are written to a temporary folder that is
removed when the rows are done.
"""

from __future__ import annotations

import importlib
import pkgutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import mujoco
import numpy as np

from qpik.analytic.api import closed_form_for, ik, redundancy_parameter, symbol
from qpik.bench import Row, cycle, import_peer, time_interleaved
from qpik.bench.analytic_locked import POSES, check_note, qpik_solutions
from qpik.core.errors import QpikError
from qpik.robots.loader import load_robot
from qpik.robots.robot import Robot

PACKAGE = "ssik.prebuilt"
TIP = "tip"
"""The site at the flange in every file :func:`mjcf` writes."""


def seven_r_arms() -> list[ModuleType]:
    """ssik's prebuilt modules of arms with 7 revolute joints, sorted by name ([] without ssik)."""
    try:
        package = import_peer(PACKAGE)
    except ImportError:
        return []
    out = []
    for info in pkgutil.walk_packages(package.__path__, f"{PACKAGE}."):
        if not info.name.endswith("_ik"):
            continue
        try:
            module = importlib.import_module(info.name)
        except ImportError:
            continue
        if getattr(module, "DOF", 0) == 7 and all(kind == "revolute" for kind in module._JOINT_TYPES):
            out.append(module)
    return sorted(out, key=lambda m: m.__name__)


def arm_name(module: ModuleType) -> str:
    """``maker/arm`` of an ssik module (``ssik.prebuilt.kinova.gen3_ik`` -> ``kinova/gen3``)."""
    maker, arm = module.__name__.split(".")[-2:]
    return f"{maker}/{arm.removesuffix('_ik')}"


def mjcf(module: ModuleType) -> str:
    """The MJCF text of an ssik module's arm (module docstring): body k at ``T_right(k−1) · T_left(k)`` in body k − 1
    with joint k about ``_JOINT_AXES[k]``, and the site :data:`TIP` at ``T_right(7)`` in body 7."""
    lefts, rights, axes, limits = (
        module._JOINT_T_LEFTS,
        module._JOINT_T_RIGHTS,
        module._JOINT_AXES,
        module._JOINT_LIMITS,
    )
    lines = [f'<mujoco model="{arm_name(module).replace("/", "_")}">', '<compiler angle="radian"/>', "<worldbody>"]
    before = np.eye(4)
    for k, (left, axis, limit) in enumerate(zip(lefts, axes, limits)):
        rng = ' limited="false"' if limit is None else f' limited="true" range="{_numbers(limit)}"'
        lines += [
            f'<body name="link{k + 1}" {_placement(before @ np.asarray(left, float))}>',
            '<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>',
            f'<joint name="joint{k + 1}" type="hinge" axis="{_numbers(axis)}"{rng}/>',
        ]
        before = np.asarray(rights[k], float)
    lines.append(f'<site name="{TIP}" {_placement(before)}/>')
    lines += ["</body>"] * len(lefts) + ["</worldbody>", "</mujoco>", ""]
    return "\n".join(lines)


def load_arm(module: ModuleType, folder: Path) -> Robot:
    """The arm of an ssik module, written by :func:`mjcf` into ``folder`` and loaded by :func:`qpik.load_robot`."""
    path = folder / f"{arm_name(module).replace('/', '_')}.xml"
    path.write_text(mjcf(module))
    return load_robot(path, tip=TIP, name=arm_name(module))


def fk_agreement(robot: Robot, module: ModuleType, q: np.ndarray) -> float:
    """The largest difference of qpik's FK of ``robot`` and ssik's ``fk`` at configurations q (N, 7) (m and rotation
    entries)."""
    return float(max(np.abs(robot.fk(x) - np.asarray(module.fk(x), float)).max() for x in q))


def ssik_rows(repeat: int, block: int, row: Callable[..., Row]) -> list[Row]:
    """The rows of every arm of :func:`seven_r_arms` with a closed form or the 1-D search (module docstring);
    ``row(label, seconds, ref, note)`` makes one."""
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as folder:
        for module in seven_r_arms():
            try:
                robot = load_arm(module, Path(folder))
            except QpikError as exc:
                print(f"qpik bench analytic: ssik's {arm_name(module)} left out: {exc}")
                continue
            if robot.closed_form is None:
                print(f"qpik bench analytic: ssik's {arm_name(module)} left out: {robot.notes.split(';')[0]}")
                continue
            rows += _beside_ssik(robot, module, max(20, repeat // block), block, row)
    return rows


def _beside_ssik(robot: Robot, module: ModuleType, samples: int, block: int, row: Callable[..., Row]) -> list[Row]:
    """qpik.ik and ssik's ``solve`` on the same poses of ``robot``, checked, then timed interleaved."""
    q = np.random.default_rng(3).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    T = robot.fk(q)
    param = np.asarray(redundancy_parameter(robot, q)[0], float)
    peers = {
        "qpik": (lambda i: ik(robot, T[i], float(param[i])), qpik_solutions),
        "ssik": (lambda i: module.solve(T[i]), lambda out: [s.q for s in out]),
    }
    notes = {k: check_note(robot, T, q, fn, solutions) for k, (fn, solutions) in peers.items()}
    notes["ssik"] += f" (ssik's fk = qpik's FK of the file to {fk_agreement(robot, module, q[:8]):.0e})"
    t = time_interleaved({k: cycle(fn, list(range(POSES))) for k, (fn, _) in peers.items()}, samples, block=block)
    solver = closed_form_for(robot)
    name, kind = arm_name(module), robot.closed_form.replace("_", " ")
    ours = f"{name}: qpik.ik, {solver.n_branches} branches ({kind}, {symbol(solver.param_name)})"
    theirs = f"{name}: ssik solve (self-motion sampled)"
    return [row(ours, t["qpik"], theirs, notes["qpik"]), row(theirs, t["ssik"], None, notes["ssik"])]


def _placement(T: np.ndarray) -> str:
    """``pos="…" quat="…"`` of a rigid transform (MuJoCo's w, x, y, z quaternion), full precision."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T[:3, :3]).ravel())
    return f'pos="{_numbers(T[:3, 3])}" quat="{_numbers(quat)}"'


def _numbers(x) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(x))
