"""qpik: closed-form IK branches, QP whole-arm control and self-motion planning for 7-DOF arms."""

# ruff: noqa: E402 (the GL backend is chosen before any module imports mujoco)

from qpik.render.gl import choose_backend as _choose_backend

_choose_backend()  # before any qpik module imports mujoco: see qpik.render.gl

from typing import TYPE_CHECKING

from qpik.core.lazy import exports

if TYPE_CHECKING:
    from qpik.analytic import FeasibleIntervals, IKSolutions, feasible_intervals, ik, redundancy_parameter
    from qpik.control import Controller, ControllerOptions, StepInfo
    from qpik.core.errors import (
        InfeasibleError,
        InputError,
        NoClosedFormError,
        ProblemFileError,
        QpikError,
        RenderUnavailable,
        RotationError,
        SolverError,
        UnknownRobotError,
        UnreachableError,
        ViewerError,
    )
    from qpik.nlp import BestOptions, BestResult, solve_best, solve_ik
    from qpik.planning import Plan, PlanOptions, plan_self_motion
    from qpik.planning.many import PlanningError, plan_many
    from qpik.robots import CATALOG, DHChain, Joint, LinkCapsule, Robot, SerialChain, load_robot
    from qpik.scene import Scene
    from qpik.viewer import view
    from qpik.viewer.options import ViewOptions

# every name is imported on first use (qpik.core.lazy): `import qpik` loads none of the heavy dependencies
__getattr__, __dir__ = exports(
    __name__,
    {
        "qpik.analytic": ("FeasibleIntervals", "IKSolutions", "feasible_intervals", "ik", "redundancy_parameter"),
        "qpik.control": ("Controller", "ControllerOptions", "StepInfo"),
        "qpik.core.errors": (
            "InfeasibleError",
            "InputError",
            "NoClosedFormError",
            "ProblemFileError",
            "QpikError",
            "RenderUnavailable",
            "RotationError",
            "SolverError",
            "UnknownRobotError",
            "UnreachableError",
            "ViewerError",
        ),
        "qpik.nlp": ("BestOptions", "BestResult", "solve_best", "solve_ik"),
        "qpik.planning": ("Plan", "PlanOptions", "plan_self_motion"),
        "qpik.planning.many": ("PlanningError", "plan_many"),
        "qpik.robots": ("CATALOG", "DHChain", "Joint", "LinkCapsule", "Robot", "SerialChain", "load_robot"),
        "qpik.scene": ("Scene",),
        "qpik.viewer": ("view",),
        "qpik.viewer.options": ("ViewOptions",),
    },
)

__version__ = "0.1.0"

__all__ = [
    "CATALOG",
    "BestOptions",
    "BestResult",
    "Controller",
    "ControllerOptions",
    "DHChain",
    "FeasibleIntervals",
    "IKSolutions",
    "InfeasibleError",
    "InputError",
    "Joint",
    "LinkCapsule",
    "NoClosedFormError",
    "Plan",
    "PlanOptions",
    "PlanningError",
    "ProblemFileError",
    "QpikError",
    "RenderUnavailable",
    "Robot",
    "RotationError",
    "Scene",
    "SerialChain",
    "SolverError",
    "StepInfo",
    "UnknownRobotError",
    "UnreachableError",
    "ViewOptions",
    "ViewerError",
    "feasible_intervals",
    "ik",
    "load_robot",
    "plan_many",
    "plan_self_motion",
    "redundancy_parameter",
    "solve_best",
    "solve_ik",
    "view",
]
