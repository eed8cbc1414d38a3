"""qpik: closed-form IK branches, QP whole-arm control and self-motion planning for 7-DOF arms."""

import os as _os
import sys as _sys

# MuJoCo picks its GL backend once, when it is first imported: on a Linux machine
# with no display, default to software rendering (Debian libosmesa6) before any
# qpik module imports mujoco. An explicit MUJOCO_GL is left alone.
if (
    "MUJOCO_GL" not in _os.environ
    and "mujoco" not in _sys.modules
    and _sys.platform.startswith("linux")
    and not (_os.environ.get("DISPLAY") or _os.environ.get("WAYLAND_DISPLAY"))
):
    _os.environ["MUJOCO_GL"] = "osmesa"

from qpik.analytic import FeasibleIntervals, IKSolutions, feasible_intervals, ik, redundancy_parameter
from qpik.control import Controller, StepInfo
from qpik.errors import (
    InfeasibleError,
    InputError,
    NoClosedFormError,
    QpikError,
    RotationError,
    UnknownRobotError,
    UnreachableError,
)
from qpik.robots import CATALOG, DHChain, LinkCapsule, Robot, load_robot

__version__ = "0.1.0"

__all__ = [
    "CATALOG",
    "Controller",
    "DHChain",
    "FeasibleIntervals",
    "IKSolutions",
    "InfeasibleError",
    "InputError",
    "LinkCapsule",
    "NoClosedFormError",
    "QpikError",
    "Robot",
    "RotationError",
    "StepInfo",
    "UnknownRobotError",
    "UnreachableError",
    "feasible_intervals",
    "ik",
    "load_robot",
    "redundancy_parameter",
]
