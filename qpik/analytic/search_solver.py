r"""The 1-D search's solutions (:mod:`qpik.analytic.locked_search`) as :func:`qpik.ik` gives them: 16 slots per pose
and value of the locked joint, with identities along it.

:class:`SearchSolver` is the solver of the family ``"locked_search"`` of :func:`~qpik.robots.recognize.recognize` (an
arm of no closed form where the search's geometry holds). The parameter is the locked joint (``param_name`` ``"q1"`` for
the Sawyer and Baxter, read from the flange; ``"q7"`` read forwards), and every pose has 16 slots
(:data:`~qpik.analytic.slot_solver.BRANCHES`), public ids 0-15: the roots of error function b take the slots ``4 b +
j``, j = 0-3, in increasing order of the search variable x in (−π, π] (the j-th root of :math:`e_b`; x is the arm's q4
for :class:`~qpik.analytic.search_geometry.ShoulderSearch`, in either direction, and the joint at the flange's end for
:class:`~qpik.analytic.search_geometry.ElbowSearch`, the Sawyer's q7). A branch so keeps its id along the parameter
while no root of the same :math:`e_b` below it appears or vanishes (in pairs at a fold, :math:`e_b = \partial
e_b/\partial x = 0`, or one at the edge of the validity, where it passes to the error function of the other sign) and
none crosses x = ±π: roots of one function meet only at a fold, so they never swap. An error function with more than 4
roots at one pose and parameter (rare; 6 seen on the Sawyer) puts the roots past its fourth in the lowest slots that no
root has taken (no more than 16 solutions exist: a 6-R chain's bound). The other slots are ``valid`` False, their joints
0 but the locked one (the parameter).

A root where the two roots of a subproblem meet (it is then a root of two error functions,
:attr:`~qpik.analytic.locked_search.SearchSolutions.double`) is one solution, in the slots of the smaller b where
both find it, and ``singular``: its b may change with the round-off of the pose, and the slots of the other roots of
its error functions with it.
More than 16 solutions is a continuum (the Sawyer at q = 0, two axes aligned with q1 fixed: the search then runs
out of its budget with thousands of candidates): 16 of them fill the slots (4 per b, then the lowest slots left, in
the order of b and x), each ``singular``. The branch of a configuration (:meth:`SearchSolver.parameter`) is the
slot of the solution nearest to it at its own pose and locked angle. The feasible sets of the parameter are sampled,
not proved (:mod:`qpik.analytic.sampled_sets`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.branch_solver import Solved
from qpik.analytic.locked_search import SearchSolutions
from qpik.analytic.search_geometry import search_for
from qpik.analytic.slot_solver import BRANCHES, SlotSolver, ranked

if TYPE_CHECKING:
    from collections.abc import Callable

    from qpik.analytic.branch_solver import BranchSolver
    from qpik.analytic.intervals import ParameterSets
    from qpik.robots.robot import Robot

SLOTS = 4
"""Slots of :class:`SearchSolver` per error function: ids 4 b to 4 b + 3 (module docstring)."""


class SearchSolver(SlotSolver):
    """:func:`qpik.ik` and :func:`qpik.redundancy_parameter` of an arm of the ``"locked_search"`` family: the
    :func:`~qpik.analytic.search_geometry.search_for` of its chain in the direction recognised
    (``robot.canonical.reversed``), its solutions in 16 slots (module docstring)."""

    kind = "locked_search"
    family = "the 1-D search's family"
    param_name = "q1"

    def __init__(self, robot: Robot, sets: Callable[[BranchSolver], ParameterSets] | None = None):
        super().__init__(robot, sets)
        self.search = search_for(robot.chain, (robot.canonical.reversed,))
        """The search of the arm's chain."""
        self.param_name = f"q{self.search.locked}"
        self.locked = self.search.locked - 1

    def solve_one(self, T: np.ndarray, param: float) -> Solved:
        """One pose (4, 4), one parameter (rad): q (B, n), valid, singular, within_limits (B,) bool."""
        return self.place(self.search.solve(T, param), param)

    def place(self, sol: SearchSolutions, param: float) -> Solved:
        """The solutions ``sol`` of the locked angle ``param`` (rad) in their slots (the j-th root of e_b in increasing
        x takes slot 4 b + j, :func:`~qpik.analytic.slot_solver.ranked`;
        :meth:`~qpik.analytic.slot_solver.SlotSolver.fill`), singular at a subproblem's double root
        (:attr:`~qpik.analytic.locked_search.SearchSolutions.double`) and every valid slot where more than 16 solutions
        were found (a continuum)."""
        at = ranked(sol.q[:, self.search.variable_joint], sol.branch, SLOTS)
        return self.fill(sol.q, at, sol.double | (len(at) > BRANCHES), param)
