"""QP whole-arm control: tasks and limits -> one QP per control step -> a joint velocity.

Public API::

    from qpik.control import Controller, FrameTask, PostureTask, ManipulabilityTask, DampingTask
    from qpik.control import ConfigurationLimit, VelocityLimit, ObstacleLimit
    ctrl = Controller.for_robot(robot, target=pose, obstacles=[...])
    v = ctrl.step(q)            # rad/s, (n,)
    ctrl.last                   # StepInfo: status, active constraints, clearance, timings

CLIK baselines with the same ``step`` interface are in :mod:`qpik.control.clik`.
"""

from qpik.algebra.lie import pose_error, so3_log
from qpik.control.clik import CLIK, DampedLeastSquares, GradientProjection, PseudoInverseCLIK, VelocityOnly
from qpik.control.controller import Controller
from qpik.control.limits import BoxLimit, ConfigurationLimit, Limit, ObstacleLimit, RowLimit, VelocityLimit
from qpik.control.options import ControllerOptions
from qpik.control.qp import QP
from qpik.control.solvers import Solution, Solver, get_solver
from qpik.control.state import State
from qpik.control.step_info import StepInfo
from qpik.control.tasks import (
    DampingTask,
    FrameTask,
    ManipulabilityTask,
    ObjectiveTask,
    PostureTask,
    Task,
)

__all__ = [
    "CLIK",
    "QP",
    "BoxLimit",
    "ConfigurationLimit",
    "Controller",
    "ControllerOptions",
    "DampedLeastSquares",
    "DampingTask",
    "FrameTask",
    "GradientProjection",
    "Limit",
    "ManipulabilityTask",
    "ObjectiveTask",
    "ObstacleLimit",
    "PostureTask",
    "PseudoInverseCLIK",
    "RowLimit",
    "Solution",
    "Solver",
    "State",
    "StepInfo",
    "Task",
    "VelocityLimit",
    "VelocityOnly",
    "get_solver",
    "pose_error",
    "so3_log",
]
