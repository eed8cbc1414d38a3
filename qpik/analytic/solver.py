"""Common machinery of the closed-form solvers.

A solver (:class:`AnalyticSolver` subclass) writes its algorithm once, in
:meth:`AnalyticSolver.branches`, against :mod:`qpik.symbolic`. This base class
turns that one source into

- a compiled CasADi function for one pose (the fast path),
- a numpy evaluation over a batch of poses and parameters,
- a CasADi function ``q(T, param)`` per branch, for exact derivatives (NLP).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik import symbolic as sy
from qpik.compiled import Compiled
from qpik.symbolic import Mat, Ops, Scalar, Vec

MANY_CHUNK = 32
"""Parameters per call of the compiled sweep :meth:`AnalyticSolver.solve_many`."""

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


@dataclass
class Branches:
    """What :meth:`AnalyticSolver.branches` returns, for B branches.

    Attributes:
        q: B lists of n joint scalars, wrapped to (-pi, pi], always finite.
        valid: B scalars, 1 where the branch reaches the pose, else 0.
        singular: B scalars, 1 where the branch is at a singular case
            (its joint values are then a defined, documented choice).
    """

    q: list[list[Scalar]]
    valid: list[Scalar]
    singular: list[Scalar]


class AnalyticSolver(ABC):
    """Closed-form IK of one arm family for a given redundancy parameter.

    Subclasses set ``kind`` (the ``Robot.closed_form`` value), ``param_name``
    (``"delta"`` or ``"psi"``), ``branch_ids`` (the public number of each
    branch, in output order) and implement :meth:`branches`,
    :meth:`parameter` and :meth:`feasible_intervals`.
    """

    kind: str
    param_name: str
    branch_ids: tuple[int, ...]

    def __init__(self, robot: Robot):
        self.robot = robot

    @property
    def n_branches(self) -> int:
        return len(self.branch_ids)

    # ---- the one source -----------------------------------------------------

    @abstractmethod
    def branches(self, R: Mat, p: Vec, param: Scalar, ops: Ops) -> Branches:
        """All branches for end-effector rotation ``R`` and position ``p`` (world frame)."""

    @abstractmethod
    def parameter(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Redundancy parameter and branch id of configurations q (N, n): ((N,), (N,))."""

    @abstractmethod
    def feasible_intervals(self, T: np.ndarray) -> list:
        """Per branch, the exact parameter set where every joint is within limits."""

    # ---- three evaluations --------------------------------------------------

    @cached_property
    def casadi_function(self) -> ca.Function:
        """``f(T (4x4), param) -> (Q (B x n), valid (B,), singular (B,))`` as a CasADi function."""
        T = ca.SX.sym("T", 4, 4)
        param = ca.SX.sym(self.param_name)
        R, p = sy.frame_of_batch(T)
        br = self.branches(R, p, param, sy.CASADI)
        Q = ca.vertcat(*[ca.horzcat(*row) for row in br.q])
        return ca.Function(
            f"ik_{self.kind}",
            [T, param],
            [Q, ca.vertcat(*br.valid), ca.vertcat(*br.singular)],
            ["T", self.param_name],
            ["q", "valid", "singular"],
        )

    @cached_property
    def _compiled(self) -> Compiled:
        return Compiled(self.casadi_function)

    def solve_one(self, T: np.ndarray, param: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One pose (4, 4), one parameter: q (B, n), valid (B,) bool, singular (B,) bool."""
        Q, valid, singular = self._compiled(T, np.array([param]))
        return Q.copy(), valid > 0.5, singular > 0.5

    @cached_property
    def _compiled_many(self) -> Compiled:
        T = ca.SX.sym("T", 4, 4)
        params = ca.SX.sym(self.param_name, MANY_CHUNK)
        out = self.casadi_function.map(MANY_CHUNK)(ca.repmat(T, 1, MANY_CHUNK), params.T)
        return Compiled(ca.Function(f"ik_{self.kind}_many", [T, params], list(out)))

    def solve_many(self, T: np.ndarray, params: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One pose (4, 4), parameters (M,): q (M, B, n), valid (M, B), singular (M, B).

        The compiled path in chunks of ``MANY_CHUNK`` parameters: for a sweep of
        one pose (feasible intervals) it is much faster than :meth:`solve_batch`,
        whose cost for small M is Python overhead.
        """
        params = np.asarray(params, dtype=float).ravel()
        M, B, n = params.size, self.n_branches, self.robot.dof
        Q, valid, singular = np.empty((M, B, n)), np.empty((M, B), bool), np.empty((M, B), bool)
        f = self._compiled_many
        chunk = np.empty(MANY_CHUNK)
        for i in range(0, M, MANY_CHUNK):
            m = min(MANY_CHUNK, M - i)
            chunk[:m] = params[i : i + m]
            chunk[m:] = params[i]
            q, v, s = f(T, chunk)
            Q[i : i + m] = q.reshape(B, MANY_CHUNK, n).transpose(1, 0, 2)[:m]
            valid[i : i + m] = v.T[:m] > 0.5  # (B, chunk) outputs
            singular[i : i + m] = s.T[:m] > 0.5
        return Q, valid, singular

    def solve_batch(self, T: np.ndarray, param: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Poses (N, 4, 4), parameters (N,): q (N, B, n), valid (N, B), singular (N, B)."""
        N = T.shape[0]
        R, p = sy.frame_of_batch(T)
        br = self.branches(R, p, param, sy.NUMPY)
        # fill (B, n, N) contiguously (fast), return the (N, B, n) view
        Q = np.empty((len(br.q), len(br.q[0]), N))
        for b, row in enumerate(br.q):
            for j, x in enumerate(row):
                Q[b, j] = x
        Q = Q.transpose(2, 0, 1)
        valid = sy.stack(br.valid, sy.NUMPY, (N,)) > 0.5
        singular = sy.stack(br.singular, sy.NUMPY, (N,)) > 0.5
        return Q, valid, singular
