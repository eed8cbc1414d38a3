"""qpik: closed-form IK branches, QP whole-arm control and self-motion planning for 7-DOF arms."""

from qpik.analytic import FeasibleIntervals, IKSolutions, feasible_intervals, ik, redundancy_parameter
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
    "UnknownRobotError",
    "UnreachableError",
    "feasible_intervals",
    "ik",
    "load_robot",
    "redundancy_parameter",
]
