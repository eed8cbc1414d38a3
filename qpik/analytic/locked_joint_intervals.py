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
- a change of the branch's ``valid`` flag: a root of its validity function
  (:meth:`~qpik.analytic.locked_joint.LockedJointSolver.validity`: the subproblems' discriminants, continuous in q7).

The last two are not sinusoids in q7: their roots are found by a sweep of :data:`GRID` values of q7 (the compiled
IK, :meth:`~qpik.analytic.solver.AnalyticSolver.solve_many`, and the compiled validity functions), a sign change
between neighbours bracketing a root (a limit crossing between two valid values). Two roots of one function inside
one grid cell (a joint that touches a level and turns back, as it does at the best margin; a branch valid on less
than a cell) sit about an extremum: where the sampled function turns, the extremum is located by bisection on the
sign of a central difference and the function tested there, which brackets both roots. Limit crossings between a
validity root and the next valid value are bracketed there. All brackets are refined to :data:`ROOT_TOL` together
(regula falsi with bisection steps, :meth:`Q7Intervals._bisect`; each step one compiled sweep). The gaps between
the breakpoints are then classified as for the other families (:class:`~qpik.analytic.intervals.SetAssembler`: one
IK evaluation at each midpoint).

**Not certified:** a function with more than one extremum in three grid values (2π/GRID ≈ 3 mrad; near a singular
configuration) can hide roots; the exactly bounded search the S-R-S and offset-shoulder sets have is not written for
this family yet. ``margin`` shrinks the limits as there (:func:`~qpik.analytic.intervals.shrunk_limits`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.analytic import trig
from qpik.analytic.intervals import FeasibleIntervals, SetAssembler, shrunk_limits, wrap
from qpik.native.compiled import RowMap

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
CELL = 2.0 * np.pi / GRID

Brackets = tuple[np.ndarray, np.ndarray, np.ndarray]
"""``(a, b, column)`` (K,) each: a root of column k lies in [a, b] (rad, not wrapped)."""


def _none() -> Brackets:
    return np.zeros(0), np.zeros(0), np.zeros(0, int)


def _join(*parts: Brackets) -> Brackets:
    return tuple(np.concatenate(x) for x in zip(*parts))  # type: ignore[return-value]


class Q7Intervals:
    """The feasible q7 sets of a :class:`~qpik.analytic.locked_joint.LockedJointSolver` (a ``ParameterSets``).

    The functions whose roots are breakpoints are *columns* ``(branch, joint, level)``: sin(q_j − L) for a joint
    j (not q4, not q7), or the branch's validity function (:meth:`LockedJointSolver.validity`) as joint n = 7.
    """

    proved = False
    """The breakpoints come from a sweep (module docstring): an empty set proves nothing."""

    def __init__(self, solver: LockedJointSolver):
        self._solver = solver
        self._assemble = SetAssembler(solver, solver.n_branches)
        self._grid = np.linspace(-np.pi, np.pi, GRID, endpoint=False)
        self._n = solver.robot.dof
        T, q7 = ca.SX.sym("T", 4, 4), ca.SX.sym("q7")
        R, p = sy.frame_of_batch(T)
        f = ca.Function(f"validity_{solver.kind}", [T, q7], [ca.vertcat(*solver.validity(R, p, q7, sy.CASADI))])
        self._validity = RowMap(f, shared=[0])
        self._last: tuple[bytes, float, FeasibleIntervals] | None = None

    def native_sets(self) -> None:
        """No single C call for this family."""
        return None

    def _sweep(self, T: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """At q7 = x (M,): the joints and the validity function of every branch, (M, B, n + 1), and valid (M, B)."""
        x = wrap(x)
        sol = self._solver.solve_many(T, x)
        (v,) = self._validity(np.asarray(T, float).reshape(-1, order="F"), x[:, None])
        return np.concatenate([sol.q, v[:, :, None]], axis=2), sol.valid

    def _values(self, qa: np.ndarray, rows, branch, joint, level) -> np.ndarray:
        """The columns (branch, joint, level) at the rows ``rows`` of a sweep ``qa`` (M, B, n + 1)."""
        x = qa[rows, branch, joint]
        return np.where(joint == self._n, x, np.sin(x - level))

    def _at(self, T: np.ndarray, x: np.ndarray, *column) -> np.ndarray:
        """The columns (branch, joint, level, each (K,)) at q7 = x (K,)."""
        if x.size == 0:
            return x
        return self._values(self._sweep(T, x)[0], np.arange(x.size), *column)

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """Per branch, the q7 (rad) where every joint lies in the limits shrunk by ``margin``; ``T`` (4, 4). The
        last answer is kept: the same pose and margin again (a viewer's sets, then its best answer's level sets)
        return the same object."""
        key = np.asarray(T, float).tobytes()
        if self._last is not None and self._last[0] == key and self._last[1] == margin:
            return self._last[2]
        out = self._sets(T, margin)
        self._last = (key, margin, out)
        return out

    def _sets(self, T: np.ndarray, margin: float) -> FeasibleIntervals:
        s = self._solver
        if margin > 1.0:
            return FeasibleIntervals(s.param_name, s.branch_array, [[] for _ in s.branch_ids],
                                     [[] for _ in s.branch_ids])  # fmt: skip
        lo, hi = shrunk_limits(s.robot.q_min, s.robot.q_max, margin)
        levels = _levels(lo, hi)
        cols = self._columns(levels)
        qa, valid = self._sweep(T, self._grid)
        f = self._values(qa, np.arange(GRID)[:, None], *cols)
        signs, turns = self._sign_changes(f, valid, cols), self._turns(T, qa, valid, f, cols)
        a, b, k = _join(signs, turns)
        border = cols[1][k] == self._n
        fa = self._at(T, a, *(c[k] for c in cols))
        va, vb = self._bisect(T, a[border], b[border], fa[border], *(c[k[border]] for c in cols))
        inside = np.where(np.signbit(fa[border]), vb, va)  # the valid side of each validity root
        edges = self._edges(T, inside, cols[0][k[border]], valid, f, cols)
        a, b, k = _join((a[~border], b[~border], k[~border]), edges)
        la, lb = self._bisect(T, a, b, self._at(T, a, *(c[k] for c in cols)), *(c[k] for c in cols))
        found = wrap(0.5 * np.concatenate([va + vb, la + lb]))
        breaks = np.concatenate([found, self._elbow_roots(T, levels[ELBOW]), levels[-1]])
        sets, sing = self._assemble(T, breaks, found, (lo, hi))
        return FeasibleIntervals(s.param_name, s.branch_array, sets, sing)

    def _columns(self, levels: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The columns as (branch, joint, level) arrays (F,): each branch's validity, then sin(q_j − L) per branch,
        joint j (not q4, not q7) and level L."""
        B = self._solver.n_branches
        branch, joint, level = [np.arange(B)], [np.full(B, self._n)], [np.zeros(B)]
        for j, L in enumerate(levels[:-1]):
            if j != ELBOW:
                branch.append(np.repeat(np.arange(B), L.size))
                joint.append(np.full(B * L.size, j))
                level.append(np.tile(L, B))
        return np.concatenate(branch), np.concatenate(joint), np.concatenate(level)

    def _sign_changes(self, f: np.ndarray, valid: np.ndarray, cols) -> Brackets:
        """The sign changes of the sweep ``f`` (GRID, F) between neighbours (a limit crossing only between two valid
        values)."""
        branch, joint, _ = cols
        g = np.concatenate([f, f[:1]])  # close the circle
        ok = np.concatenate([valid, valid[:1]])
        i, k = np.nonzero(np.signbit(g[:-1]) != np.signbit(g[1:]))
        keep = (joint[k] == self._n) | (ok[i, branch[k]] & ok[i + 1, branch[k]])
        i, k = i[keep], k[keep]
        return self._grid[i], self._grid[i] + CELL, k

    def _turns(self, T: np.ndarray, qa: np.ndarray, valid: np.ndarray, f: np.ndarray, cols) -> Brackets:
        """The pairs of roots about a turn of a joint (valid at three grid values) or of a validity function inside
        two grid cells: the extremum located, each column with a sign there other than at an end gives the bracket
        (end, extremum)."""
        branch, joint, level = cols
        n = self._n
        dq = np.roll(qa, -1, axis=0) - qa  # (GRID, B, n + 1): qa[i+1] − qa[i]
        dq[..., :n] = wrap(dq[..., :n])
        ok = valid & np.roll(valid, -1, axis=0) & np.roll(valid, 1, axis=0)
        turn = np.signbit(dq) != np.signbit(np.roll(dq, 1, axis=0))  # qa[i] a sampled extremum
        turn[..., :n] &= ok[:, :, None]
        turn[..., [ELBOW, n - 1]] = False
        i, bj, jj = np.nonzero(turn)
        near = np.zeros(i.size, bool)  # a level within twice the larger neighbouring step of the sampled extremum
        reach = 2.0 * np.maximum(np.abs(dq[i, bj, jj]), np.abs(dq[i - 1, bj, jj])) + 1e-9
        for k in range(branch.size):
            mine = (bj == branch[k]) & (jj == joint[k])
            gap = np.abs(f[i, k]) if joint[k] == n else np.abs(wrap(qa[i, bj, jj] - level[k]))
            near |= mine & (gap <= reach)
        i, bj, jj = i[near], bj[near], jj[near]
        if i.size == 0:
            return _none()
        rows = np.arange(i.size)
        lo, hi = self._grid[i] - CELL, self._grid[i] + CELL
        while (hi - lo).max() > TURN_TOL:  # bisection on the sign of the slope: the extremum is where it turns
            m = 0.5 * (lo + hi)
            both = self._sweep(T, np.concatenate([m - 0.25 * TURN_TOL, m + 0.25 * TURN_TOL]))[0]
            slope = both[i.size :][rows, bj, jj] - both[: i.size][rows, bj, jj]
            slope = np.where(jj < n, wrap(slope), slope)
            on = np.signbit(slope) == np.signbit(dq[i - 1, bj, jj])  # still rising (falling) as before the turn
            lo, hi = np.where(on, m, lo), np.where(on, hi, m)
        e = 0.5 * (lo + hi)
        at = self._sweep(T, e)[0]
        out = [_none()]
        for k in range(branch.size):  # the columns of each (branch, joint) that turns
            sel = np.nonzero((branch[k] == bj) & (joint[k] == jj))[0]
            if sel.size == 0:
                continue
            fe = self._values(at, sel, branch[k], joint[k], level[k])
            for end, side in ((i[sel] - 1, 0), ((i[sel] + 1) % GRID, 1)):
                cross = np.signbit(fe) != np.signbit(f[end, k])
                edge = self._grid[i[sel]] + (CELL if side else -CELL)
                a, b = (e[sel], edge) if side else (edge, e[sel])
                out.append((a[cross], b[cross], np.full(int(cross.sum()), k)))
        return _join(*out)

    def _edges(self, T: np.ndarray, inside: np.ndarray, vb: np.ndarray, valid: np.ndarray, f: np.ndarray, cols):
        """The limit crossings next to a validity root: ``inside`` (K,) are q7 just on the valid side of the roots
        of branch ``vb`` (K,); between each and its neighbours among the grid values and the others of its branch,
        where both are valid, a limit column of the branch that changes sign gives a bracket."""
        branch, joint, level = cols
        if inside.size == 0:
            return _none()
        qa = self._sweep(T, inside)[0]
        out = [_none()]
        for bb in np.unique(vb):
            ks = np.flatnonzero((branch == bb) & (joint < self._n))
            mine = np.flatnonzero(vb == bb)
            x = np.concatenate([self._grid, wrap(inside[mine])])
            ok = np.concatenate([valid[:, bb], np.ones(mine.size, bool)])
            fx = np.concatenate([f[:, ks], self._values(qa, mine[:, None], bb, joint[ks], level[ks])])
            new = np.concatenate([np.zeros(GRID, bool), np.ones(mine.size, bool)])
            order = np.argsort(x, kind="stable")
            x, ok, fx, new = x[order], ok[order], fx[order], new[order]
            nxt = np.roll(np.arange(x.size), -1)
            pair = ok & ok[nxt] & (new | new[nxt])
            r, c = np.nonzero((np.signbit(fx) != np.signbit(fx[nxt])) & pair[:, None])
            b = np.where(nxt[r] == 0, x[nxt[r]] + 2.0 * np.pi, x[nxt[r]])
            out.append((x[r], b, ks[c]))
        return _join(*out)

    def _bisect(self, T: np.ndarray, a: np.ndarray, b: np.ndarray, fa: np.ndarray, *column):
        """Brackets ``(a, b)`` (K,) no wider than :data:`ROOT_TOL` of the roots of the columns ``column`` (branch,
        joint, level, each (K,)) bracketed by [a, b] (K,), ``fa`` their values at a; a keeps the sign of ``fa``.

        Regula falsi with the Illinois rule (the value kept at an end twice in a row is halved), every third step a
        bisection: the bracket at least halves every three steps, and a smooth root converges superlinearly. Each
        step also evaluates the columns at x ± :data:`ROOT_TOL`/2.5 (in the same compiled sweep): where their signs
        differ as at a and b, that straddle is the bracket, so a converged estimate ends the search at once instead
        of waiting for the far end to move."""
        if a.size == 0:
            return a, b
        a, b, fa = a.copy(), b.copy(), fa.copy()
        fb = self._at(T, b, *column)
        kept = np.zeros(a.size, int)  # +1: a kept last step, -1: b kept
        h = 0.4 * ROOT_TOL
        step = 0
        while (live := np.flatnonzero(b - a > ROOT_TOL)).size:
            step += 1
            A, B, FA, FB = a[live], b[live], fa[live], fb[live]
            m = 0.5 * (A + B)
            x = m
            if step % 3:
                den = np.where(FB != FA, FB - FA, 1.0)
                x = np.where(FB != FA, (A * FB - B * FA) / den, m)
                x = np.where((x > A) & (x < B), x, m)
            xl, xr = np.maximum(x - h, A), np.minimum(x + h, B)
            fl, fx, fr = self._at(T, np.concatenate([xl, x, xr]), *(np.tile(c[live], 3) for c in column)).reshape(3, -1)
            left = np.signbit(fx) == np.signbit(FA)  # the root is in [x, b]
            FB = FB * np.where(left & (kept[live] == -1), 0.5, 1.0)
            FA = FA * np.where(~left & (kept[live] == 1), 0.5, 1.0)
            exact = fx == 0.0
            na, nb = np.where(left | exact, x, A), np.where(left & ~exact, B, x)
            nfa, nfb = np.where(left, fx, FA), np.where(left, FB, fx)
            straddle = ~exact & (np.signbit(fl) == np.signbit(FA)) & (np.signbit(fr) != np.signbit(FA))
            a[live], b[live] = np.where(straddle, xl, na), np.where(straddle, xr, nb)
            fa[live], fb[live] = np.where(straddle, fl, nfa), np.where(straddle, fr, nfb)
            kept[live] = np.where(left, -1, 1)
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
