r"""The locked-joint closed form read from the flange (q1 locked; the Kinova Gen3 and Jaco, TALOS's arms):
:class:`ReversedLockedJointSolver`, and :func:`locked_joint_solver`, which picks the solver of a locked-joint arm
(see :mod:`qpik.analytic.locked_joint`, "Read from the flange")."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.locked_joint import SIGNS, LockedJointSolver
from qpik.analytic.solver import AnalyticSolver, Branches
from qpik.core.errors import NoClosedFormError
from qpik.robots.locked_joint import reversed_chain
from qpik.robots.recognize import Canonical
from qpik.robots.robot import Robot

if TYPE_CHECKING:
    from qpik.analytic.intervals import FeasibleIntervals, ParameterSets
    from qpik.analytic.native_sets import NativeSets


def _inverse(R: Mat, p: Vec) -> tuple[Mat, Vec]:
    """The inverse of the pose ``(R, p)``: :math:`(R^T, -R^T p)`."""
    Rt = sy.transpose(R)
    return Rt, sy.vscale(-1.0, sy.matvec(Rt, p))


class ReversedLockedJointSolver(AnalyticSolver):
    r"""Closed-form IK with q1 locked, for an arm whose :func:`~qpik.robots.locked_joint.reversed_chain` is of the
    locked-q7 family (axes 7-6-5 meet, axes 3-2 meet; the Kinova Gen3): a :class:`LockedJointSolver` of the arm read
    from the flange (:attr:`inner`), whose joint k is the arm's joint 8 − k at the same angle and whose pose is the
    inverse, :math:`T' = T^{-1}`. Its q7 is the arm's q1 (the parameter, ``"q1"``); the branch ids are the inner
    solver's (``4·shoulder + 2·elbow + wrist``, its shoulder the arm's wrist 7-6-5, its wrist the arm's axes 3-2,
    the signs of its module docstring with the arm's axis k for the inner's 8 − k). The feasible sets are the inner
    solver's (:class:`~qpik.analytic.locked_joint_intervals.Q7Intervals` of the inner arm, whose limits are the
    arm's reversed) at :math:`T^{-1}`, unchanged: the same parameter, branches and limits."""

    kind = "locked_joint"
    param_name = "q1"
    branch_ids = tuple(range(8))
    closed_form_sets = False
    branch_signs = SIGNS

    def __init__(self, robot: Robot, sets: Callable[[AnalyticSolver], ParameterSets] | None = None):
        super().__init__(robot)
        canonical = robot.canonical
        if canonical is None or not canonical.reversed:
            raise NoClosedFormError(f"{robot.name} is not of the locked-q1 (reversed) family")
        turned = Robot(
            name=f"{robot.name} from the flange",
            chain=reversed_chain(robot.chain),
            q_min=robot.q_min[::-1].copy(),
            q_max=robot.q_max[::-1].copy(),
            v_max=robot.v_max[::-1].copy(),
            q_home=robot.q_home[::-1].copy(),
            closed_form="locked_joint",
            canonical=Canonical("locked_joint", canonical.table, canonical.joints, exact=canonical.exact),
        )
        self.inner = LockedJointSolver(turned, sets, param_name=self.param_name)
        """The locked-q7 solver of the arm read from the flange."""

    def table_branches(self, R: Mat, p: Vec, param: Scalar, ops: Ops) -> Branches:
        """All 8 branches at q1 = ``param`` (rad) for the pose ``(R, p)`` (base frame): the inner solver's at the
        inverse pose, joints in the arm's order."""
        br = self.inner.branches(*_inverse(R, p), param, ops)
        return Branches([row[::-1] for row in br.q], br.valid, br.singular)

    def one_branch(self, R: Mat, p: Vec, param: Scalar, signs: list[Scalar], ops: Ops) -> Branches | None:
        """The inner solver's branch of ``signs`` (:meth:`LockedJointSolver.one_branch`) at the inverse pose, in the
        arm's order and angles; None for an exact member."""
        br = self.inner.one_branch(*_inverse(R, p), param, signs, ops)
        if br is None:
            return None
        return Branches([self.robot_row(br.q[0][::-1], ops)], br.valid, br.singular)

    def table_parameter_expr(self, q: list[Scalar], ops: Ops) -> tuple[Scalar, Scalar]:
        """q1 (rad) and the branch id of the configuration ``q`` (7 scalars, the arm's order)."""
        return self.inner.table_parameter_expr(q[::-1], ops)

    def feasible_intervals(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """The inner solver's sets at :math:`T^{-1}` (:meth:`AnalyticSolver.feasible_intervals`)."""
        return self.inner.feasible_intervals(np.linalg.inv(np.asarray(T, float)), margin)

    @property
    def sets_proved(self) -> bool:
        """The inner solver's (:meth:`LockedJointSolver.sets_proved`)."""
        return self.inner.sets_proved

    def native_sets(self) -> NativeSets | None:
        """None: the sets are found by a search (:mod:`qpik.analytic.locked_joint_intervals`), no single C call."""
        return None


def locked_joint_solver(robot: Robot, sets: Callable[[AnalyticSolver], ParameterSets] | None = None) -> AnalyticSolver:
    """The locked-joint solver of ``robot``: :class:`ReversedLockedJointSolver` where its closed form was found with
    the chain read from the flange (``robot.canonical.reversed``), else :class:`LockedJointSolver`."""
    if robot.canonical is not None and robot.canonical.reversed:
        return ReversedLockedJointSolver(robot, sets)
    return LockedJointSolver(robot, sets)
