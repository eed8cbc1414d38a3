r"""Feasible q7 sets of the locked-q7 closed form (:mod:`qpik.analytic.locked_joint`) under joint limits.

Every joint of a branch is a continuous function of q7 between the values where the branch appears or
disappears (a subproblem's discriminant crossing 0) or jumps (a singular case), so the sets change only at

- a joint j crossing a level L of its (shrunk) limits: a root of :math:`\sin(q_j(q_7) - L)` (which also vanishes
  at L + π: such extra roots only split a gap), L = π too for a joint whose limits reach ±π (the representative
  inside the limits changes there, :class:`~qpik.analytic.solver.AnalyticSolver`);
- q7 at its own levels (exact: q7 is the parameter);
- a change of the branch's ``valid`` flag.

These functions are not sinusoids in q7, so their roots are found by a sweep of :data:`GRID` values of q7 (the
compiled IK, :meth:`~qpik.analytic.solver.AnalyticSolver.solve_many`), a sign change (or a flag change) between
neighbours bracketing a root, refined by bisection to :data:`ROOT_TOL` over all brackets at once (each step one
compiled sweep of the midpoints). The gaps between the roots are then classified as for
the other families (:class:`~qpik.analytic.intervals.SetAssembler`: one IK evaluation at each midpoint).
**Not certified:** two roots closer than the grid spacing (2π/GRID) of the same function are missed (a joint
that touches a limit and leaves it within 3 mrad of q7); the exactly bounded search the S-R-S and offset-shoulder
sets have is not written for this family yet. ``margin`` shrinks the limits as there
(:func:`~qpik.analytic.intervals.shrunk_limits`).
"""

from __future__ import annotations

import numpy as np

from qpik.analytic.intervals import FeasibleIntervals, SetAssembler, shrunk_limits, wrap
from qpik.analytic.solver import AnalyticSolver

GRID = 2048
"""q7 values of the sweep over the circle."""
ROOT_TOL = 1e-12
"""Width (rad) of a bracket at which bisection stops."""


class Q7Intervals:
    """The feasible q7 sets of a :class:`~qpik.analytic.locked_joint.LockedJointSolver` (a ``ParameterSets``)."""

    def __init__(self, solver: AnalyticSolver):
        self._solver = solver
        self._assemble = SetAssembler(solver, solver.n_branches)
        self._grid = np.linspace(-np.pi, np.pi, GRID, endpoint=False)

    def native_sets(self) -> None:
        """No single C call for this family."""
        return None

    def _levels(self, lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:
        """Per joint, the angles (rad, wrapped) where it may change feasibility under the limits ``lo``, ``hi``."""
        out = []
        for lj, uj in zip(lo, hi):
            if uj - lj >= 2.0 * np.pi:
                out.append(np.zeros(0))
                continue
            levels = [lj, uj] + ([np.pi] if lj <= -np.pi or uj >= np.pi else [])
            out.append(wrap(np.array(levels)))
        return out

    def _columns(self, levels: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The functions whose sign changes are breakpoints, as (branch, joint, level) arrays (F,): sin(q_j − L)
        per branch, joint j < 7 and level L; then each branch's valid flag (joint −1, level 0)."""
        B = self._solver.n_branches
        branch, joint, level = [np.arange(B)], [np.full(B, -1)], [np.zeros(B)]
        for j, L in enumerate(levels[:-1]):
            branch.append(np.repeat(np.arange(B), L.size))
            joint.append(np.full(B * L.size, j))
            level.append(np.tile(L, B))
        return np.concatenate(branch), np.concatenate(joint), np.concatenate(level)

    @staticmethod
    def _values(q: np.ndarray, valid: np.ndarray, rows, branch, joint, level) -> np.ndarray:
        """The functions (branch, joint, level) of :meth:`_columns` at the parameters ``rows`` of a sweep (q (M, B,
        n), valid (M, B)): sin(q_j − L), or ±1 for a valid flag (joint −1)."""
        limit = np.sin(q[rows, branch, np.maximum(joint, 0)] - level)
        return np.where(joint < 0, np.where(valid[rows, branch], 1.0, -1.0), limit)

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """Per branch, the q7 (rad) where every joint lies in the limits shrunk by ``margin``; ``T`` (4, 4)."""
        s = self._solver
        if margin > 1.0:
            empty = [[] for _ in s.branch_ids]
            return FeasibleIntervals(s.param_name, s.branch_array, empty, [[] for _ in s.branch_ids])
        lo, hi = shrunk_limits(s.robot.q_min, s.robot.q_max, margin)
        levels = self._levels(lo, hi)
        branch, joint, level = self._columns(levels)
        grid = self._grid
        sol = s.solve_many(T, grid)
        f = self._values(sol.q, sol.valid, np.arange(GRID)[:, None], branch, joint, level)
        g = np.concatenate([f, f[:1]])  # close the circle
        ok = np.concatenate([sol.valid, sol.valid[:1]])
        i, k = np.nonzero(np.signbit(g[:-1]) != np.signbit(g[1:]))
        keep = (joint[k] < 0) | (ok[i, branch[k]] & ok[i + 1, branch[k]])  # a limit crossing between valid values
        i, k = i[keep], k[keep]
        a = grid[i]
        roots = self._bisect(T, a, a + 2.0 * np.pi / GRID, f[i, k], branch[k], joint[k], level[k])
        breaks = np.concatenate([roots, levels[-1]])
        sets, sing = self._assemble(T, breaks, roots, (lo, hi))
        return FeasibleIntervals(s.param_name, s.branch_array, sets, sing)

    def _bisect(self, T: np.ndarray, a: np.ndarray, b: np.ndarray, fa: np.ndarray, *column) -> np.ndarray:
        """Roots of the functions ``column`` (branch, joint, level of :meth:`_columns`, each (K,)) bracketed by
        [a, b] (K,), ``fa`` their values at a."""
        if a.size == 0:
            return a
        s = self._solver
        rows = np.arange(a.size)
        while (b - a).max() > ROOT_TOL:
            m = 0.5 * (a + b)
            sol = s.solve_many(T, wrap(m))
            fm = self._values(sol.q, sol.valid, rows, *column)
            left = np.signbit(fm) == np.signbit(fa)
            a, b = np.where(left, m, a), np.where(left, b, m)
            fa = np.where(left, fm, fa)
        return wrap(0.5 * (a + b))
