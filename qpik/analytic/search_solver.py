r"""The 1-D search's solutions (:mod:`qpik.analytic.locked_search`) as :func:`qpik.ik` gives them: 16 slots per pose
and value of the locked joint, with identities along it.

:class:`SearchSolver` is the solver of the family ``"locked_search"`` of :func:`~qpik.robots.recognize.recognize` (an
arm of no closed form where the search's geometry holds). The parameter is the locked joint (``param_name`` ``"q1"`` for
the Sawyer and Baxter, read from the flange; ``"q7"`` read forwards), and every pose has :data:`BRANCHES` slots, public
ids 0-15: the roots of error function b take the slots ``4 b + j``, j = 0-3, in increasing order of the search variable
x in (−π, π] (the j-th root of :math:`e_b`; x is the arm's q4 for
:class:`~qpik.analytic.search_geometry.ShoulderSearch`, in either direction, and the joint at the flange's end for
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
not proved (:mod:`qpik.analytic.search_sets`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.analytic.branch_solver import BranchSolver, Solved
from qpik.analytic.intervals import apart
from qpik.analytic.locked_search import MOST, SearchSolutions
from qpik.analytic.search_geometry import search_for
from qpik.core.errors import NoClosedFormError

if TYPE_CHECKING:
    from collections.abc import Callable

    from qpik.analytic.intervals import ParameterSets
    from qpik.robots.robot import Robot

SLOTS = 4
"""Slots of :class:`SearchSolver` per error function: ids 4 b to 4 b + 3 (module docstring)."""
BRANCHES = MOST
"""Slots of :class:`SearchSolver` per pose: the most solutions a 6-R chain has."""


def slots(branch: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The slots (K,) of :class:`SearchSolver` of K ≤ :data:`BRANCHES` solutions of error functions ``branch`` (K,)
    at the search variable x (K,) rad: the j-th root of b in increasing x takes ``SLOTS·b + j`` for j < :data:`SLOTS`,
    the others the lowest slots left (module docstring), in the order of b and x; −1 for those left without (only
    where K > :data:`BRANCHES`)."""
    out = np.full(len(branch), -1)
    taken = np.zeros(BRANCHES, bool)
    order = np.lexsort((x, branch))
    rank = np.zeros(len(branch), int)
    for i, k in enumerate(order[1:], 1):
        rank[k] = rank[order[i - 1]] + 1 if branch[k] == branch[order[i - 1]] else 0
    own = rank < SLOTS
    out[own] = SLOTS * branch[own] + rank[own]
    taken[out[own]] = True
    for k, free in zip(order[~own[order]], np.flatnonzero(~taken)):
        out[k] = free
    return out


class SearchSolver(BranchSolver):
    """:func:`qpik.ik` and :func:`qpik.redundancy_parameter` of an arm of the ``"locked_search"`` family: the
    :func:`~qpik.analytic.search_geometry.search_for` of its chain in the direction recognised
    (``robot.canonical.reversed``), its solutions in :data:`BRANCHES` slots (module docstring). ``solve_batch`` and
    ``solve_many`` search each pose and parameter in turn."""

    kind = "locked_search"
    param_name = "q1"
    branch_ids = tuple(range(BRANCHES))
    closed_form_sets = False

    def __init__(self, robot: Robot, sets: Callable[[BranchSolver], ParameterSets] | None = None):
        super().__init__(robot, sets)
        canonical = robot.canonical
        if canonical is None or canonical.kind != self.kind:
            raise NoClosedFormError(f"{robot.name} is not of the 1-D search's family")
        self.search = search_for(robot.chain, (canonical.reversed,))
        """The search of the arm's chain."""
        self.param_name = f"q{self.search.locked}"
        self.locked = self.search.locked - 1
        """The locked joint's index (0-based): the parameter."""

    def solve_one(self, T: np.ndarray, param: float) -> Solved:
        """One pose (4, 4), one parameter (rad): q (B, n), valid, singular, within_limits (B,) bool."""
        return self.place(self.search.solve(T, param), param)

    def place(self, sol: SearchSolutions, param: float) -> Solved:
        """The solutions ``sol`` of the locked angle ``param`` (rad) in their slots (:func:`slots`): q (B, n) (each
        joint's representative inside its limits, :meth:`~qpik.analytic.branch_solver.BranchSolver.representative`),
        valid, singular (a root at a subproblem's double root,
        :attr:`~qpik.analytic.locked_search.SearchSolutions.double`; every valid slot where more than :data:`BRANCHES`
        solutions were found: a continuum), within_limits (B,) bool."""
        q = np.zeros((BRANCHES, self.robot.dof))
        q[:, self.locked] = sy.NUMPY.wrap(np.array(float(param)))
        at = slots(sol.branch, sol.q[:, self.search.variable_joint])
        q[at[at >= 0]] = sol.q[at >= 0]
        for j in np.flatnonzero(self._wide):
            q[:, j] = self.representative(int(j), q[:, j], sy.NUMPY)
        valid = np.zeros(BRANCHES, bool)
        valid[at[at >= 0]] = True
        within = valid & np.all((q >= self.robot.q_min) & (q <= self.robot.q_max), axis=1)
        singular = valid & (len(at) > BRANCHES)
        singular[at[at >= 0]] |= sol.double[at >= 0]
        return Solved(q, valid, singular, within)

    def solve_many(self, T: np.ndarray, params: np.ndarray, rows: int | None = None) -> Solved:
        """One pose (4, 4), parameters (M,): q (M, B, n), valid, singular, within_limits (M, B) bool; ``rows``: only the
        first ``rows`` slots."""
        params = np.asarray(params, float).ravel()
        return Solved(*(x[:, :rows] for x in self.solve_batch(np.broadcast_to(T, (len(params), 4, 4)), params)))

    def solve_batch(self, T: np.ndarray, param: np.ndarray) -> Solved:
        """Poses (N, 4, 4), parameters (N,): q (N, B, n), valid, singular, within_limits (N, B) bool."""
        out = [self.solve_one(Ti, float(x)) for Ti, x in zip(T, param)]
        return Solved(*(np.stack(parts) for parts in zip(*out)))

    def parameter(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The locked joint (rad) and branch id of configurations q (N, n) wrapped to (−π, π]: ((N,), (N,) int). The
        branch is the slot of the valid solution nearest q (largest joint difference, modulo 2π) at q's own pose (the
        FK of :attr:`robot`'s chain) and locked angle; −1 where the search finds none there."""
        q = np.asarray(q, dtype=float)
        param = q[:, self.locked].copy()
        branch = np.full(len(q), -1)
        for i, (Ti, qi) in enumerate(zip(self.robot.fk(q), q)):
            sol = self.solve_one(Ti, float(param[i]))
            if sol.valid.any():
                branch[i] = int(np.argmin(np.where(sol.valid, apart(sol.q, qi), np.inf)))
        return param, branch
