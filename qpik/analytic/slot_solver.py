"""What the solvers whose branches are found, not written as expressions, share: :class:`SlotSolver`, 16 slots per pose
and value of a locked joint, filled by the solutions found there (the 1-D search's,
:mod:`qpik.analytic.search_solver`, and the general 6-R's, :mod:`qpik.analytic.general_solver`)."""

from __future__ import annotations

from abc import abstractmethod
from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.analytic.branch_solver import BranchSolver, Solved
from qpik.analytic.intervals import apart
from qpik.core.errors import NoClosedFormError

if TYPE_CHECKING:
    from collections.abc import Callable

    from qpik.analytic.intervals import ParameterSets
    from qpik.robots.robot import Robot

BRANCHES = 16
"""Slots per pose: the most isolated solutions a 6-R chain has (Lee & Liang 1988)."""


class SlotSolver(BranchSolver):
    """A solver of :data:`BRANCHES` slots along a locked joint (the parameter): subclasses set :attr:`locked` and
    ``param_name`` and find one pose's solutions at one parameter (:meth:`solve_one`, with :meth:`fill`);
    ``solve_batch`` and ``solve_many`` solve each pose and parameter in turn. Its sets are found by sampling or a
    search, not as roots of closed-form functions (``closed_form_sets`` False)."""

    branch_ids = tuple(range(BRANCHES))
    closed_form_sets = False
    locked: int
    """The locked joint's index (0-based): the parameter."""
    family: str
    """The family in words, for the error where the robot is not of it."""

    def __init__(self, robot: Robot, sets: Callable[[BranchSolver], ParameterSets] | None = None):
        """Raises :class:`~qpik.core.errors.NoClosedFormError` where ``robot`` is not of the solver's family
        (``robot.canonical.kind``)."""
        super().__init__(robot, sets)
        if robot.canonical is None or robot.canonical.kind != self.kind:
            raise NoClosedFormError(f"{robot.name} is not of {self.family}")

    @abstractmethod
    def solve_one(self, T: np.ndarray, param: float) -> Solved:
        """One pose (4, 4), one parameter (rad): q (B, n), valid, singular, within_limits (B,) bool."""

    def fill(self, q: np.ndarray, at: np.ndarray, singular: np.ndarray, param: float) -> Solved:
        """Solutions ``q`` (K, n) rad (the arm's order) of the locked angle ``param`` (rad) in the slots ``at`` (K,;
        −1: none), ``singular`` (K,) bool: q (B, n) (each joint's representative inside its limits,
        :meth:`~qpik.analytic.branch_solver.BranchSolver.representative`; the other slots 0 but the locked joint),
        valid, singular, within_limits (B,) bool."""
        out = np.zeros((BRANCHES, self.robot.dof))
        out[:, self.locked] = sy.NUMPY.wrap(np.array(float(param)))
        out[at[at >= 0]] = q[at >= 0]
        for j in np.flatnonzero(self._wide):
            out[:, j] = self.representative(int(j), out[:, j], sy.NUMPY)
        valid = np.zeros(BRANCHES, bool)
        valid[at[at >= 0]] = True
        within = valid & np.all((out >= self.robot.q_min) & (out <= self.robot.q_max), axis=1)
        flags = np.zeros(BRANCHES, bool)
        flags[at[at >= 0]] = singular[at >= 0]
        return Solved(out, valid, valid & flags, within)

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
        FK of :attr:`robot`'s chain) and locked angle; −1 where none is found there."""
        q = np.asarray(q, dtype=float)
        param = q[:, self.locked].copy()
        branch = np.full(len(q), -1)
        for i, (Ti, qi) in enumerate(zip(self.robot.fk(q), q)):
            sol = self.solve_one(Ti, float(param[i]))
            if sol.valid.any():
                branch[i] = int(np.argmin(np.where(sol.valid, apart(sol.q, qi), np.inf)))
        return param, branch


def ranked(key: np.ndarray, group: np.ndarray | None = None, per_group: int = BRANCHES) -> np.ndarray:
    """The slots (K,) of K solutions by rank: the j-th in increasing ``key`` (K,) of its ``group`` g (K,; all 0 where
    None) takes ``per_group·g + j`` for j < ``per_group``, the others the lowest slots left, in the order of group and
    key; −1 for those left without (only where K > :data:`BRANCHES`)."""
    group = np.zeros(len(key), int) if group is None else np.asarray(group, int)
    out = np.full(len(key), -1)
    taken = np.zeros(BRANCHES, bool)
    order = np.lexsort((key, group))
    rank = np.zeros(len(key), int)
    for i, k in enumerate(order[1:], 1):
        rank[k] = rank[order[i - 1]] + 1 if group[k] == group[order[i - 1]] else 0
    own = rank < per_group
    out[own] = per_group * group[own] + rank[own]
    taken[out[own]] = True
    for k, free in zip(order[~own[order]], np.flatnonzero(~taken)):
        out[k] = free
    return out
