r"""Feasible q7 sets of the locked-q7 closed form (:mod:`qpik.analytic.locked_joint`) under joint limits.

Every joint of a branch is a continuous function of q7 between the values where the branch appears or
disappears (a subproblem's discriminant crossing 0) or jumps (a singular case), so the sets change only at

- q7 at its own levels (exact: q7 is the parameter);
- q4 at a level L, or the elbow's discriminant at 0: exact roots. :math:`|G W - S|^2 = A + B\cos q_7 + C\sin q_7`
  (W turned about axis 7: :math:`e = S - p - R(c_7 + w_\parallel)`, :math:`A = |e|^2 + |w_\perp|^2`,
  :math:`B = -2\,e\cdot R w_\perp`, :math:`C = 2\,e\cdot R (k_7\times w_7)`, in the solver's flange-frame constants),
  so the elbow's :math:`c(q_7) = k - |GW - S|^2/2` is a sinusoid and q4 = L, i.e. :math:`c = r\cos(L - \varphi)`,
  or :math:`c = \pm r`, is :func:`qpik.analytic.trig.solve_cos_sin`;
- another joint j crossing a level L of its (shrunk) limits: a root of :math:`\sin(q_j(q_7) - L)` (which also
  vanishes at L + π: such extra roots only split a gap), L = π too for a joint whose limits reach ±π (the
  representative inside the limits changes there, :class:`~qpik.analytic.solver.AnalyticSolver`);
- a change of the branch's ``valid`` flag (the wrist's subproblem 2).

The last two are not sinusoids in q7: their roots are found by a sweep of :data:`GRID` values of q7 (the compiled
IK, :meth:`~qpik.analytic.solver.AnalyticSolver.solve_many`), a sign change (or a flag change) between neighbours
bracketing a root. Two roots of one function inside one grid cell (a joint that touches a level and turns back,
as it does at the best margin) sit about an extremum of :math:`q_j(q_7)`: where the sampled :math:`q_j` turns, the
extremum is located by bisection on the sign of a central difference and the level tested there, which brackets
both roots. All brackets are refined by bisection to :data:`ROOT_TOL` together (each step one compiled sweep of
the midpoints). The gaps between the roots are then classified as for the other families
(:class:`~qpik.analytic.intervals.SetAssembler`: one IK evaluation at each midpoint).

**Not certified:** a function with more than one extremum in a grid cell (2π/GRID ≈ 3 mrad; near a singular
configuration), or a branch valid on less than a cell, can hide roots; the exactly bounded search the S-R-S and
offset-shoulder sets have is not written for this family yet. ``margin`` shrinks the limits as there
(:func:`~qpik.analytic.intervals.shrunk_limits`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.analytic import trig
from qpik.analytic.intervals import FeasibleIntervals, SetAssembler, shrunk_limits, wrap

if TYPE_CHECKING:
    from qpik.analytic.locked_joint import LockedJointSolver

GRID = 2048
"""q7 values of the sweep over the circle."""
ROOT_TOL = 1e-12
"""Width (rad) of a bracket at which bisection stops."""
TURN_TOL = 1e-8
"""Width (rad) to which an extremum of a joint is located (its value is then exact to ~curvature·TURN_TOL²)."""
ELBOW = 3
"""Index of q4, whose levels are solved exactly."""


class Q7Intervals:
    """The feasible q7 sets of a :class:`~qpik.analytic.locked_joint.LockedJointSolver` (a ``ParameterSets``)."""

    def __init__(self, solver: LockedJointSolver):
        self._solver = solver
        self._assemble = SetAssembler(solver, solver.n_branches)
        self._grid = np.linspace(-np.pi, np.pi, GRID, endpoint=False)

    def native_sets(self) -> None:
        """No single C call for this family."""
        return None

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """Per branch, the q7 (rad) where every joint lies in the limits shrunk by ``margin``; ``T`` (4, 4)."""
        s = self._solver
        if margin > 1.0:
            empty = [[] for _ in s.branch_ids]
            return FeasibleIntervals(s.param_name, s.branch_array, empty, [[] for _ in s.branch_ids])
        lo, hi = shrunk_limits(s.robot.q_min, s.robot.q_max, margin)
        levels = _levels(lo, hi)
        branch, joint, level = self._columns(levels)
        sol = s.solve_many(T, self._grid)
        f = _values(sol.q, sol.valid, np.arange(GRID)[:, None], branch, joint, level)
        i, k = self._sign_changes(f, sol.valid, branch, joint)
        a, flag = self._grid[i], joint[k] < 0
        cols = branch[k], joint[k], level[k]
        fa = f[i, k]
        af, bf = self._bisect(T, a[flag], a[flag] + 2.0 * np.pi / GRID, fa[flag], *(c[flag] for c in cols))
        edges = self._edges(T, i[flag], af, bf, branch[k[flag]], sol.valid, f, branch, joint, level)
        turns = self._turns(T, sol.q, sol.valid, f, branch, joint, level)
        limit = ~flag
        a = np.concatenate([a[limit], edges[0], turns[0]])
        b = np.concatenate([self._grid[i[limit]] + 2.0 * np.pi / GRID, edges[1], turns[1]])
        kk = np.concatenate([k[limit], edges[2], turns[2]]).astype(int)
        cols = branch[kk], joint[kk], level[kk]
        al, bl = self._bisect(T, a, b, self._at(T, a, *cols), *cols)
        roots = wrap(0.5 * np.concatenate([af + bf, al + bl]))
        exact = self._elbow_roots(T, levels[ELBOW])
        breaks = np.concatenate([roots, exact, levels[-1]])
        sets, sing = self._assemble(T, breaks, roots, (lo, hi))
        return FeasibleIntervals(s.param_name, s.branch_array, sets, sing)

    def _columns(self, levels: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The functions whose roots are found by the sweep, as (branch, joint, level) arrays (F,): sin(q_j − L)
        per branch, joint j (not q4, not q7) and level L; then each branch's valid flag (joint −1, level 0)."""
        B = self._solver.n_branches
        branch, joint, level = [np.arange(B)], [np.full(B, -1)], [np.zeros(B)]
        for j, L in enumerate(levels[:-1]):
            if j != ELBOW:
                branch.append(np.repeat(np.arange(B), L.size))
                joint.append(np.full(B * L.size, j))
                level.append(np.tile(L, B))
        return np.concatenate(branch), np.concatenate(joint), np.concatenate(level)

    def _sign_changes(self, f, valid, branch, joint) -> tuple[np.ndarray, np.ndarray]:
        """Cells ``i`` (between grid values i and i + 1) and columns ``k`` of the sign changes of the sweep ``f``
        (GRID, F) (a limit crossing only between two valid values)."""
        g = np.concatenate([f, f[:1]])  # close the circle
        ok = np.concatenate([valid, valid[:1]])
        i, k = np.nonzero(np.signbit(g[:-1]) != np.signbit(g[1:]))
        keep = (joint[k] < 0) | (ok[i, branch[k]] & ok[i + 1, branch[k]])
        return i[keep], k[keep]

    def _edges(self, T, cell, af, bf, fb, valid, f, branch, joint, level) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Brackets ``(a, b, column)`` of the limit crossings between a branch's validity boundary (the bracket
        ``(af, bf)`` found in ``cell`` for branch ``fb``) and the valid end of that cell: the joints there against
        the grid value."""
        if cell.size == 0:
            return np.zeros(0), np.zeros(0), np.zeros(0, int)
        left = valid[cell, fb]  # the branch is valid at the cell's start (then af is the valid side)
        inside = np.where(left, af, bf)
        end = np.where(left, cell, (cell + 1) % GRID)
        sol = self._solver.solve_many(T, wrap(inside))
        out_a, out_b, out_k = [], [], []
        for r in np.flatnonzero(left | valid[(cell + 1) % GRID, fb]):
            ks = np.flatnonzero((branch == fb[r]) & (joint >= 0))
            here = np.sin(sol.q[r, fb[r], joint[ks]] - level[ks])
            cross = ks[np.signbit(here) != np.signbit(f[end[r], ks])]
            g = self._grid[cell[r]] + (0.0 if left[r] else 2.0 * np.pi / GRID)
            lo, hi = (g, inside[r]) if left[r] else (inside[r], g)
            out_a.append(np.full(cross.size, lo))
            out_b.append(np.full(cross.size, hi))
            out_k.append(cross)
        if not out_a:
            return np.zeros(0), np.zeros(0), np.zeros(0, int)
        return np.concatenate(out_a), np.concatenate(out_b), np.concatenate(out_k)

    def _turns(self, T, q, valid, f, branch, joint, level) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Brackets ``(a, b, column)`` of the pairs of roots about a turn of a joint inside three grid values: the
        extremum located, each level with a sign there other than at an end gives the bracket (end, extremum)."""
        s, h = self._solver, 2.0 * np.pi / GRID
        dq = wrap(np.roll(q, -1, axis=0) - q)  # (GRID, B, n): q[i+1] − q[i]
        ok = valid & np.roll(valid, -1, axis=0) & np.roll(valid, 1, axis=0)
        turn = (np.signbit(dq) != np.signbit(np.roll(dq, 1, axis=0))) & ok[:, :, None]  # q[i] a sampled extremum
        turn[:, :, [ELBOW, q.shape[2] - 1]] = False
        i, bj, jj = np.nonzero(turn)
        if i.size == 0:
            return np.zeros(0), np.zeros(0), np.zeros(0, int)
        lo, hi = self._grid[i] - h, self._grid[i] + h
        while (hi - lo).max() > TURN_TOL:  # bisection on the sign of the slope, the same sense as at lo
            m = 0.5 * (lo + hi)
            both = s.solve_many(T, wrap(np.concatenate([m - 0.25 * TURN_TOL, m + 0.25 * TURN_TOL])))
            rows = np.arange(i.size)
            slope = wrap(both.q[i.size :][rows, bj, jj] - both.q[: i.size][rows, bj, jj])
            rising = np.signbit(slope) == np.signbit(dq[i - 1, bj, jj])
            lo, hi = np.where(rising, m, lo), np.where(rising, hi, m)
        e = 0.5 * (lo + hi)
        at = s.solve_many(T, wrap(e))
        out_a, out_b, out_k = [], [], []
        for k in range(branch.size):  # the columns of each (branch, joint) that turns
            sel = np.nonzero((branch[k] == bj) & (joint[k] == jj))[0]
            if sel.size == 0:
                continue
            fe = np.sin(at.q[sel, bj[sel], jj[sel]] - level[k])
            for end, side in ((i[sel] - 1, 0), ((i[sel] + 1) % GRID, 1)):
                cross = (np.signbit(fe) != np.signbit(f[end, k])) & at.valid[sel, bj[sel]]
                edge = self._grid[i[sel]] + (h if side else -h)
                out_a.append(np.where(side, e[sel], edge)[cross])
                out_b.append(np.where(side, edge, e[sel])[cross])
                out_k.append(np.full(int(cross.sum()), k))
        if not out_a:
            return np.zeros(0), np.zeros(0), np.zeros(0, int)
        return np.concatenate(out_a), np.concatenate(out_b), np.concatenate(out_k)

    def _at(self, T, x, *column) -> np.ndarray:
        """The functions ``column`` (branch, joint, level) at the parameters x (K,)."""
        if x.size == 0:
            return x
        sol = self._solver.solve_many(T, wrap(x))
        return _values(sol.q, sol.valid, np.arange(x.size), *column)

    def _bisect(self, T: np.ndarray, a: np.ndarray, b: np.ndarray, fa: np.ndarray, *column):
        """Brackets ``(a, b)`` (K,) no wider than :data:`ROOT_TOL` of the roots of the functions ``column`` (branch,
        joint, level of :meth:`_columns`, each (K,)) bracketed by [a, b] (K,), ``fa`` their values at a; a keeps
        the sign of ``fa``."""
        if a.size == 0:
            return a, b
        while (b - a).max() > ROOT_TOL:
            m = 0.5 * (a + b)
            fm = self._at(T, m, *column)
            left = np.signbit(fm) == np.signbit(fa)
            a, b = np.where(left, m, a), np.where(left, b, m)
            fa = np.where(left, fm, fa)
        return a, b

    def _elbow_roots(self, T: np.ndarray, levels: np.ndarray) -> np.ndarray:
        """The q7 (rad) where q4 meets one of ``levels`` or the elbow's discriminant vanishes (module docstring)."""
        s = self._solver
        R, p = np.asarray(T, float)[:3, :3], np.asarray(T, float)[:3, 3]
        k7, c7, w7 = (np.array(x, float) for x in (s.k7, s.c7, s.w7))
        w_par = (k7 @ w7) * k7
        e = np.array(s.S) - p - R @ (c7 + w_par)
        A = e @ e + (w7 - w_par) @ (w7 - w_par)
        B, C = -2.0 * e @ (R @ (w7 - w_par)), 2.0 * e @ (R @ np.cross(k7, w7))
        # c(q7) = k − A/2 − (B/2) cos q7 − (C/2) sin q7 = target  <=>  (B/2) cos + (C/2) sin = k − A/2 − target
        targets = np.concatenate([s.r4 * np.cos(levels - s.phi), [s.r4, -s.r4]])
        plus, minus, ok = trig.solve_cos_sin(0.5 * B, 0.5 * C, s.k4 - 0.5 * A - targets, sy.NUMPY)
        return wrap(np.concatenate([plus[ok], minus[ok]]))


def _levels(lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:
    """Per joint, the angles (rad, wrapped) where it may change feasibility under the limits ``lo``, ``hi``."""
    out = []
    for lj, uj in zip(lo, hi):
        if uj - lj >= 2.0 * np.pi:
            out.append(np.zeros(0))
            continue
        levels = [lj, uj] + ([np.pi] if lj <= -np.pi or uj >= np.pi else [])
        out.append(wrap(np.array(levels)))
    return out


def _values(q: np.ndarray, valid: np.ndarray, rows, branch, joint, level) -> np.ndarray:
    """The functions (branch, joint, level) of :meth:`Q7Intervals._columns` at the parameters ``rows`` of a sweep
    (q (M, B, n), valid (M, B)): sin(q_j − L), or ±1 for a valid flag (joint −1)."""
    limit = np.sin(q[rows, branch, np.maximum(joint, 0)] - level)
    return np.where(joint < 0, np.where(valid[rows, branch], 1.0, -1.0), limit)
