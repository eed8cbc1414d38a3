r"""IK of a 7-R arm of no other family (the ``"locked_general"`` family of :func:`~qpik.robots.recognize.recognize`):
q7 locked (or q1, the arm read from the flange, :func:`~qpik.robots.locked_joint.reversed_chain`, pose
:math:`T^{-1}`), the 6-R chain left solved by elimination to one eigenproblem (Raghavan & Roth 1993; Manocha & Canny
1994; :mod:`qpik.algebra.loop6r`), each candidate polished on the arm's own chain.

Per pose T and locked angle t, in the search's order (joint 7 locked):

1. :math:`G = T\,(E_7(t)\,M)^{-1}`, the pose of joints 1-6 (M the end's pose at q = 0, :math:`E_7` the locked joint's
   motion);
2. the candidates of :meth:`~qpik.algebra.loop6r.Loop6R.solve` (one per real eigenvalue, at most 16);
3. :data:`POLISH` Newton steps on the arm's chain, the locked joint held (:func:`qpik.analytic.polish.polish`, compiled
   and mapped over the candidates); a candidate whose residual is then above
   :data:`~qpik.analytic.polish.RESIDUAL_TOL` is dropped, and solutions within :data:`SAME` rad of each other are one;
4. the slots: the j-th solution in increasing order of the eigenproblem's joint (the first of its window's left side,
   :attr:`GeneralSolver.ranked_joint`) takes slot j (:func:`~qpik.analytic.slot_solver.ranked`). A slot so keeps its
   id along the parameter while no solution below it in that joint appears or vanishes (in pairs, at a fold) and none
   crosses ±π there; a solution where the six joints' Jacobian is nearly singular (smallest singular value below
   :data:`SINGULAR`) is ``singular``.

Not proved: an eigenvalue taken for complex by round-off (:data:`~qpik.algebra.loop6r.REAL`) near a fold, where two
solutions meet, or an eigenvector of a double eigenvalue, may lose a solution there. The feasible sets of the
parameter are sampled (:mod:`qpik.analytic.sampled_sets`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.loop6r import Loop6R, turns
from qpik.analytic.branch_solver import Solved
from qpik.analytic.intervals import apart
from qpik.analytic.polish import RESIDUAL_TOL, polish
from qpik.analytic.slot_solver import SlotSolver, ranked
from qpik.core.errors import NoClosedFormError
from qpik.core.validate import number, single_pose
from qpik.native.compiled import RowMap
from qpik.robots.locked_joint import reversed_chain

if TYPE_CHECKING:
    from collections.abc import Callable

    from qpik.analytic.branch_solver import BranchSolver
    from qpik.analytic.intervals import ParameterSets
    from qpik.robots.robot import Robot

POLISH = 4
"""Newton steps (:func:`qpik.analytic.polish.polish`) on the arm's chain from each candidate."""
SAME = 1e-8
"""rad: solutions this close in every joint are one."""
SINGULAR = 1e-6
"""A solution whose six joints' Jacobian has its smallest singular value below this is ``singular``."""


class GeneralSolver(SlotSolver):
    """:func:`qpik.ik` and :func:`qpik.redundancy_parameter` of an arm of the ``"locked_general"`` family (module
    docstring): q7 locked, or q1 where ``robot.canonical.reversed``.

    Raises:
        NoClosedFormError: the robot is not of this family, or no window of the elimination holds its chain.
    """

    kind = "locked_general"
    family = "the general 6-R family"
    param_name = "q7"

    def __init__(self, robot: Robot, sets: Callable[[BranchSolver], ParameterSets] | None = None):
        super().__init__(robot, sets)
        self.reversed = robot.canonical.reversed
        self.chain = reversed_chain(robot.chain) if self.reversed else robot.chain
        """The arm's chain in the search's order (read from the flange where :attr:`reversed`)."""
        h, o = self.chain.axes(np.zeros(7))
        loop, why = Loop6R.of(h[:6], o[:6])
        if loop is None:
            raise NoClosedFormError(f"{robot.name}: {why}")
        self.loop = loop
        """The elimination of joints 1-6 (search's order)."""
        self._last = (h[6], o[6], self.chain.fk(np.zeros(7)))
        """The locked joint's axis (direction, point) and the end's pose at q = 0, search's order."""
        T, q = ca.SX.sym("T", 4, 4), ca.SX.sym("q", 7)
        joints, residual = polish(self.chain, *sy.frame_of_batch(T), ca.vertsplit(q), sy.CASADI, POLISH)
        jv, jw = self.chain.jacobian_expr(self.chain.frames_expr(joints, sy.CASADI))
        columns = [x for j in range(6) for x in (*jv[j], *jw[j])]
        self._polish = RowMap(ca.Function("general_polish", [T, q], [ca.vertcat(*joints), residual,
                                                                     ca.vertcat(*columns)]), shared=[0])  # fmt: skip
        """:data:`POLISH` steps of :func:`~qpik.analytic.polish.polish` from a candidate q (7,; rad, search's order)
        toward the pose T (4, 4; column-major, shared): the joints (7,), the residual (1,) and the Jacobian's columns
        1-6 there (36,; ``[v; ω]`` each); compiled, over rows of candidates."""
        self.locked = 0 if self.reversed else 6
        self.param_name = f"q{self.locked + 1}"
        first = loop.window.left[0]
        self.ranked_joint = 6 - first if self.reversed else first
        """The joint (the arm's order, 0-based) whose value orders the slots."""

    def solve_one(self, T: np.ndarray, param: float) -> Solved:
        """One pose (4, 4), one parameter (rad): q (B, n), valid, singular, within_limits (B,) bool.

        Raises:
            InputError: ``T`` is not one pose or ``param`` not a finite number.
        """
        T = single_pose(T, "T")
        param = number(param, "param", minimum=None)
        Ts = np.linalg.inv(T) if self.reversed else T
        h, o, home = self._last
        found = self.loop.solve(Ts @ np.linalg.inv(turns(h, o, param) @ home))
        q, singular = self._polished(Ts, np.column_stack([found, np.full(len(found), param)]))
        if self.reversed:
            q = q[:, ::-1]
        return self.fill(q, ranked(q[:, self.ranked_joint]), singular, param)

    def _polished(self, Ts: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The candidates ``q`` (K, 7) rad (search's order) after :data:`POLISH` Newton steps on the chain toward the
        pose ``Ts`` (4, 4; search's order), the locked joint held (:attr:`_polish`): those that reach it, each once
        (wrapped), and whether each is singular."""
        if not len(q):
            return np.zeros((0, 7)), np.zeros(0, bool)
        q, residual, J = self._polish(Ts.reshape(-1, order="F"), q)
        ok = residual[:, 0] <= RESIDUAL_TOL
        q, residual = sy.NUMPY.wrap(q[ok]), residual[ok, 0]
        sigma = np.linalg.svd(J[ok].reshape(-1, 6, 6), compute_uv=False)[:, -1]  # the rows are J's columns
        keep: list[int] = []
        for i in np.argsort(residual, kind="stable"):
            if all(apart(q[i], q[k]) > SAME for k in keep):
                keep.append(int(i))
        return q[keep], sigma[keep] < SINGULAR
