"""Common machinery of the closed-form solvers.

A solver (:class:`AnalyticSolver` subclass) writes its algorithm once, in
:meth:`AnalyticSolver.branches`, against :mod:`qpik.algebra.symbolic`. This base class
turns that one source into

- a CasADi function ``q(T, param)`` of all branches, for exact derivatives (NLP);
- that function plus the joint-limit test, compiled to machine code
  (:func:`qpik.native.build.native`), for one pose (:meth:`AnalyticSolver.solve_one`)
  and mapped over chunks of parameters for a sweep of one pose
  (:meth:`AnalyticSolver.solve_many`, the feasible intervals);
- a numpy evaluation over a batch of poses and parameters
  (:meth:`AnalyticSolver.solve_batch`).

Its inverse, the parameter and branch of a configuration, is written once too
(:meth:`AnalyticSolver.parameter_expr`): numpy over a batch, compiled for one
configuration (:meth:`AnalyticSolver.parameter`).

One pose goes through compiled code and a batch of poses through numpy vectorised across
poses (the design notes give the measurements). The tests check that all of them agree.

What the public functions call of a solver is :class:`~qpik.analytic.branch_solver.BranchSolver`, of which
:class:`AnalyticSolver` is one kind and the 1-D search of :mod:`qpik.analytic.locked_search`
(:class:`~qpik.analytic.search_solver.SearchSolver`, branches found as roots, no expressions) another.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.branch_solver import BranchSolver, Solved
from qpik.native.compiled import Compiled

KERNEL_LARGE = 4_000_000
"""Bytes of C up to which the single-pose kernel (:meth:`AnalyticSolver.checked`, every :func:`qpik.ik` call of one
pose) is compiled at ``-O2`` (:func:`qpik.native.build.optimisation`): a near member's kernel, whose corrections and
polish (:mod:`qpik.analytic.locked_joint`) make it hundreds of kB of C, runs faster than at ``-O1`` for a compile of
seconds more, once per machine."""
SWEEP_CHUNKS = (32, 8)
"""Parameters per call of the compiled sweeps of :meth:`AnalyticSolver.solve_many`: the large one while
more than 3/4 of it would be used, then the small one (so that 38 parameters cost 40 evaluations, not 64)."""

if TYPE_CHECKING:
    from qpik.analytic.intervals import ParameterSets
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


class AnalyticSolver(BranchSolver):
    r"""Closed-form IK of one arm family for a given redundancy parameter.

    Subclasses set ``kind`` (the ``Robot.closed_form`` value), ``param_name``
    (``"delta"`` or ``"psi"``), ``branch_ids`` (the public number of each
    branch, in output order) and implement :meth:`table_branches` and
    :meth:`table_parameter_expr`; the exact feasible sets of the parameter come from ``sets``
    (:class:`BranchSolver`: ``DeltaIntervals``, ``PsiIntervals``).

    They are written for the catalog's DH table of their family (:attr:`table`: the
    robot's chain, or for a loaded arm the table found in it, ``robot.canonical``).
    :meth:`branches` turns the table's joint angles into the robot's, once, for every
    evaluation: :math:`q = s \odot (q^{DH} - c)` (:class:`~qpik.robots.recognize.JointMap`)
    wrapped to (−π, π], then each joint's representative inside its limits
    (:meth:`BranchSolver.representative`).
    """

    branch_signs: np.ndarray | None = None
    """Per branch, the roots its subproblems take (B, k), where the family has :meth:`one_branch`."""

    def __init__(self, robot: Robot, sets: Callable[[BranchSolver], ParameterSets] | None = None):
        super().__init__(robot, sets)
        canonical = robot.canonical
        self.table = robot.chain if canonical is None else canonical.table
        self.joint_map = None if canonical is None or canonical.joints.identity else canonical.joints

    # ---- the one source -----------------------------------------------------

    @abstractmethod
    def table_branches(self, R: Mat, p: Vec, param: Scalar, ops: Ops) -> Branches:
        """All branches for end-effector rotation ``R`` and position ``p`` (world frame), in :attr:`table`'s angles."""

    @abstractmethod
    def table_parameter_expr(self, q: list[Scalar], ops: Ops) -> tuple[Scalar, Scalar]:
        """Redundancy parameter (rad) and branch id (a scalar holding an integer) of the configuration ``q``
        (n scalars) of :attr:`table`: the inverse of :meth:`table_branches`."""

    def branches(self, R: Mat, p: Vec, param: Scalar, ops: Ops) -> Branches:
        """All branches for end-effector rotation ``R`` and position ``p`` (world frame), in the robot's angles."""
        br = self.table_branches(R, p, param, ops)
        return Branches([self.robot_row(row, ops) for row in br.q], br.valid, br.singular)

    def one_branch(self, R: Mat, p: Vec, param: Scalar, signs: list[Scalar], ops: Ops) -> Branches | None:
        """The branch of :meth:`branches` whose subproblems take the roots ``signs`` (a row of :attr:`branch_signs`, or
        symbols) alone, for a family whose single-pose kernel loops over its branches (:meth:`checked`);
        None (here) where all branches are one expression."""
        return None

    def robot_row(self, row: list[Scalar], ops: Ops) -> list[Scalar]:
        """The robot's joints from a row of :attr:`table`'s angles (see the class docstring)."""
        if self.joint_map is None and not self._wide.any():
            return row
        return [self._joint(j, x, ops) for j, x in enumerate(row)]

    def _joint(self, j: int, x: Scalar, ops: Ops) -> Scalar:
        """The robot's joint j from the table's angle x (see the class docstring)."""
        if self.joint_map is not None:
            s, c = float(self.joint_map.sign[j]), float(self.joint_map.shift[j])
            x = ops.wrap(sy.mul(s, sy.sub(x, c)))
        return self.representative(j, x, ops)

    def parameter_expr(self, q: list[Scalar], ops: Ops) -> tuple[Scalar, Scalar]:
        r"""Redundancy parameter (rad) and branch id of the robot's configuration ``q`` (n scalars): the
        inverse of :meth:`branches`, through the table's angles :math:`s \odot q + c` (wrapped)."""
        if self.joint_map is not None:
            sign, shift = self.joint_map.sign, self.joint_map.shift
            q = [ops.wrap(sy.add(sy.mul(float(s), x), float(c))) for x, s, c in zip(q, sign, shift)]
        return self.table_parameter_expr(q, ops)

    def levels(self, j: int) -> list[float]:
        """The angles of :attr:`table`'s joint j (rad) where the robot's joint j can change feasibility.

        Its limits and, where a limit reaches ±π, the wrap at π, mapped to the table's angles; none
        for a joint whose range spans a whole turn (some representative is always inside).
        """
        lo, hi = float(self.robot.q_min[j]), float(self.robot.q_max[j])
        if hi - lo >= 2.0 * np.pi:
            return []
        out = [x for x in (lo, hi) if -np.pi < x < np.pi or self._wide[j]]
        if lo <= -np.pi or hi >= np.pi:
            out.append(np.pi)
        if self.joint_map is not None:
            s, c = float(self.joint_map.sign[j]), float(self.joint_map.shift[j])
            out = [float(sy.NUMPY.wrap(np.array(s * x + c))) for x in out]
        elif self._wide[j]:
            out = [float(sy.NUMPY.wrap(np.array(x))) for x in out]
        return out

    # ---- evaluations -----------------------------------------------------------

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

    def _checked_function(self, rows: int) -> ca.Function:
        """``(T, param, q_min (n,), q_max (n,)) -> (Qᵀ (n x rows), flags (3 rows,))`` of the first ``rows`` branches.

        :attr:`casadi_function` plus the limit test: ``flags`` stacks ``valid``,
        ``singular`` and ``within_limits = valid ∧ ∀j q_min_j <= q_j <= q_max_j``
        (1.0 or 0.0), so that no numpy pass over the joints is needed. Q is
        transposed so that a mapped evaluation writes (pose, branch, joint) in C order. A family with
        :meth:`one_branch` instead maps the function of one branch over the rows of :attr:`branch_signs` (a loop in C,
        its body once: a near member's 8 corrected branches written out are several times the size of an instruction
        cache, and run slower than the loop).
        """
        n = self.robot.dof
        name = f"ik_{self.kind}_checked" + ("" if rows == self.n_branches else f"_{rows}")
        body = self._branch_function
        if body is None:
            T, param = ca.SX.sym("T", 4, 4), ca.SX.sym(self.param_name)
            lo, hi = ca.SX.sym("q_min", 1, n), ca.SX.sym("q_max", 1, n)
            Q, valid, singular = (x[:rows, :] for x in self.casadi_function(T, param))
            Qt, valid, singular = Q.T, valid.T, singular.T
        else:
            T, param = ca.MX.sym("T", 4, 4), ca.MX.sym(self.param_name)
            lo, hi = ca.MX.sym("q_min", 1, n), ca.MX.sym("q_max", 1, n)
            loop = body.map(f"{name}_branches", "serial", rows, [0, 1], [])
            Qt, valid, singular = loop(T, param, ca.DM(self.branch_signs[:rows].T))
        within = valid
        for j in range(n):
            within = within * (Qt[j, :] >= lo[j]) * (Qt[j, :] <= hi[j])
        return ca.Function(name, [T, param, lo, hi], [Qt, ca.vertcat(valid.T, singular.T, within.T)])

    @cached_property
    def _branch_function(self) -> ca.Function | None:
        """:meth:`one_branch` as ``(T (4, 4), param, signs) -> (q (n,), valid, singular)``, or None."""
        if self.branch_signs is None:
            return None
        T, param = ca.SX.sym("T", 4, 4), ca.SX.sym(self.param_name)
        signs = ca.SX.sym("signs", self.branch_signs.shape[1])
        R, p = sy.frame_of_batch(T)
        br = self.one_branch(R, p, param, [signs[i] for i in range(signs.numel())], sy.CASADI)
        if br is None:
            return None
        out = [ca.vertcat(*br.q[0]), br.valid[0], br.singular[0]]
        return ca.Function(f"ik_{self.kind}_branch", [T, param, signs], out)

    def checked(self, rows: int) -> Compiled:
        """The compiled :meth:`_checked_function` of the first ``rows`` branches at one parameter (cached; ``-O2`` up
        to :data:`KERNEL_LARGE`, with the inlining flags)."""
        if rows not in self._checked:
            self._checked[rows] = Compiled(self._checked_function(rows), large=KERNEL_LARGE, inline=True)
        return self._checked[rows]

    @cached_property
    def _checked(self) -> dict[int, Compiled]:
        return {}

    @property
    def _one(self) -> Compiled:
        return self.checked(self.n_branches)

    @cached_property
    def fresh_one(self):
        """``fresh(T, param) -> (q (B, n), flags (3, B) bool)`` of all branches through the compiled extension
        (:meth:`qpik.native.fastcall.Kernel.fresh`: T (4, 4) checked as a pose and param as one finite real number in C,
        flags ``valid, singular, within_limits``), None for arguments it does not take; None without the
        extension."""
        one, B, n = self._one, self.n_branches, self.robot.dof
        kernel = one.fast(("pose", "scalar"), (("raw", (B, n)), ("flags", (3, B))))
        if kernel is None:
            return None
        one(np.eye(4), 0.0, self.robot.q_min, self.robot.q_max)  # the limits stay in the buffers
        return kernel.fresh

    @cached_property
    def _sweeps(self) -> dict[tuple[int, int], Compiled]:
        return {}

    def _sweep(self, rows: int, chunk: int) -> Compiled:
        """One pose, ``chunk`` parameters, the first ``rows`` branches: a mapped call (body once, a C loop)."""
        if (rows, chunk) not in self._sweeps:
            f = self._checked_function(rows)
            name = f"{f.name()}_sweep" + ("" if chunk == SWEEP_CHUNKS[0] else f"_{chunk}")
            self._sweeps[rows, chunk] = Compiled(f.map(name, "serial", chunk, [0, 2, 3], []))
        return self._sweeps[rows, chunk]

    def solve_one(self, T: np.ndarray, param: float) -> Solved:
        """One pose (4, 4), one parameter (rad): q (B, n), valid, singular, within_limits (B,) bool."""
        Qt, flags = self._one(T, np.array([param]), self.robot.q_min, self.robot.q_max)
        valid, singular, within = flags.reshape(3, -1) > 0.5
        return Solved(Qt.T.copy(), valid, singular, within)

    def solve_many(self, T: np.ndarray, params: np.ndarray, rows: int | None = None) -> Solved:
        """One pose (4, 4), parameters (M,): q (M, B, n), valid, singular, within_limits (M, B) bool.

        The compiled path, :data:`SWEEP_CHUNKS` parameters per call (the last chunk
        padded): for a sweep of one pose (feasible intervals, M of order 100) it
        is several times faster than :meth:`solve_batch`, whose cost at small M
        is Python overhead. ``rows``: only the first ``rows`` branches (B = rows).
        """
        params = np.asarray(params, dtype=float).ravel()
        B = self.n_branches if rows is None else rows
        M, n = params.size, self.robot.dof
        Q, flags = np.empty((M, B, n)), np.empty((M, 3 * B))
        for i, m, q, fl in self._chunks(T, params, B):
            Q[i : i + m] = q.T.reshape(-1, B, n)[:m]  # (n, chunk·B) output, (chunk, B, n) in C order
            flags[i : i + m] = fl.T[:m]
        valid, singular, within = (flags > 0.5).reshape(M, 3, B).transpose(1, 0, 2)
        return Solved(Q, valid, singular, within)

    def flags_many(
        self, T: np.ndarray, params: np.ndarray, rows: int, limits: tuple[np.ndarray, np.ndarray] | None = None
    ) -> np.ndarray:
        """:meth:`solve_many` without the joint values: flags (M, 3, rows) bool, ``[:, 0]`` valid,
        ``[:, 1]`` singular, ``[:, 2]`` within limits (the feasible intervals need only these).
        ``limits``: ``(q_min, q_max)`` (n,) rad of the limit test instead of the robot's."""
        parts = [fl.T[:m] > 0.5 for _, m, _, fl in self._chunks(T, params, rows, limits)]
        return (parts[0] if len(parts) == 1 else np.concatenate(parts)).reshape(-1, 3, rows)

    def _chunks(self, T: np.ndarray, params: np.ndarray, B: int, limits: tuple[np.ndarray, np.ndarray] | None = None):
        """The compiled sweep over params (M,) in chunks: yields ``(i, m, q (n, size·B), flags (3B, size))``
        for params[i : i + m] (views of the output buffers, valid until the next chunk); the limit test
        against ``limits`` ``(q_min, q_max)``, by default the robot's."""
        lo, hi = (self.robot.q_min, self.robot.q_max) if limits is None else limits
        Tf = np.asarray(T, dtype=float).reshape(-1, order="F")  # 1-D: the compiled call's fast path
        big, small = SWEEP_CHUNKS
        M, i = params.size, 0
        while i < M:
            size = big if M - i > 3 * big // 4 else small
            m = min(size, M - i)
            chunk = np.full(size, params[i])
            chunk[:m] = params[i : i + m]
            q, fl = self._sweep(B, size)(Tf, chunk, lo, hi)
            yield i, m, q, fl
            i += m

    def parameter(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Redundancy parameter (rad) and branch id of configurations q (N, n): ((N,), (N,) int).

        :meth:`parameter_expr` over numpy columns; one configuration (N = 1) through its
        compiled form.
        """
        q = np.asarray(q, dtype=float)
        if len(q) == 1:
            param, branch = self._parameter_one(q[0])
            return param.copy(), np.rint(branch).astype(int)
        param, branch = self.parameter_expr([q[:, j] for j in range(q.shape[1])], sy.NUMPY)
        N = (len(q),)
        return np.broadcast_to(param, N).astype(float), np.broadcast_to(branch, N).astype(int)

    @cached_property
    def _parameter_one(self) -> Compiled:
        """:meth:`parameter_expr` of one configuration (n,), compiled: ``q -> (param, branch)``."""
        q = ca.SX.sym("q", self.robot.dof)
        param, branch = self.parameter_expr([q[i] for i in range(self.robot.dof)], sy.CASADI)
        return Compiled(ca.Function(f"parameter_{self.kind}", [q], [param, branch]))

    def solve_batch(self, T: np.ndarray, param: np.ndarray) -> Solved:
        """Poses (N, 4, 4), parameters (N,): q (N, B, n), valid, singular, within_limits (N, B) bool.

        :meth:`branches` on numpy arrays of N poses, vectorised across poses.
        """
        N = T.shape[0]
        R, p = sy.frame_of_batch(T)
        br = self.branches(R, p, param, sy.NUMPY)
        # fill (B, n, N) contiguously (fast), return the (N, B, n) view
        B, n = len(br.q), len(br.q[0])
        Q = np.empty((B, n, N))
        for b, row in enumerate(br.q):
            for j, x in enumerate(row):
                Q[b, j] = x
        valid = sy.stack(br.valid, sy.NUMPY, (N,)) > 0.5
        singular = sy.stack(br.singular, sy.NUMPY, (N,)) > 0.5
        within = valid.T.copy()  # (B, N), then every joint inside its limits
        test = np.empty((B, N), bool)
        for j, (lo, hi) in enumerate(zip(self.robot.q_min, self.robot.q_max)):
            within &= np.greater_equal(Q[:, j], lo, out=test)
            within &= np.less_equal(Q[:, j], hi, out=test)
        return Solved(Q.transpose(2, 0, 1), valid, singular, within.T)
