r"""Feasible q7 sets of the locked-q7 closed form (:mod:`qpik.analytic.locked_joint`) under joint limits, proved
per pose.

Every joint of a branch is a continuous function of q7 between the values where the branch appears or
disappears (a subproblem's discriminant crossing 0) or jumps (a free joint at a singular configuration), so the
sets change only at

- q7 at its own levels (exact: q7 is the parameter);
- q4 at a level L, or the elbow's discriminant at 0: exact roots. :math:`|G W - S|^2 = A + B\cos q_7 + C\sin q_7`
  (W turned about axis 7: :math:`e = S - p - R(c_7 + w_\parallel)`, :math:`A = |e|^2 + |w_\perp|^2`,
  :math:`B = -2\,e\cdot R w_\perp`, :math:`C = 2\,e\cdot R (k_7\times w_7)`, in the solver's flange-frame constants),
  so the elbow's :math:`c(q_7) = k - |GW - S|^2/2` is a sinusoid and q4 = L, i.e. :math:`c = r\cos(L - \varphi)`,
  or :math:`c = \pm r`, is :func:`qpik.analytic.trig.solve_cos_sin`;
- another joint j crossing a level L of its (shrunk) limits: a root of
  :math:`\sin(q_j - L) = \sin q_j \cos L - \cos q_j \sin L`, with :math:`(\cos q_j, \sin q_j)` the unit vectors of
  the subproblems (:meth:`~qpik.analytic.locked_joint.LockedJointSolver.joint_trig`; it also vanishes at L + π,
  which the search skips: a cell where :math:`\cos(q_j - L) < 0` holds no root of interest), L = π too for a joint
  whose limits reach ±π (the representative inside the limits changes there,
  :class:`~qpik.analytic.solver.AnalyticSolver`); only where the branch is valid;
- a change of the branch's ``valid`` flag: a root of its validity function
  (:meth:`~qpik.analytic.locked_joint.LockedJointSolver.validity`: the subproblems' discriminants, continuous in q7).

The last two are *columns*, functions of q7 whose roots are found by Taylor-model root isolation (Berz & Makino
1998; Makino & Berz 2003): over a cell :math:`[a, b] = \{m + h t : t \in [-1, 1]\}` of q7, the first-order Taylor
model of every column (:func:`qpik.algebra.enclosure.taylor_function` of the compiled columns of one branch, whose
shoulder, elbow and wrist signs are inputs: one compiled function for every branch, one call for all the cells of a
round) is :math:`f(m + h t) \in f_0 + f_1 t + [-r, r]`, beside interval bounds. The column's roots in the cell
then lie where :math:`|f_0 + f_1 t| \le r + ` :data:`SLACK` (a Newton step with its remainder enclosed, as in the
interval Newton method, Moore 1966): the cell is discarded when that is empty (or
the bounds exclude 0, or, for a joint, the branch's validity is below 0 over it), replaced by that window when
the window is at most half as wide (near a simple root the window shrinks quadratically from round to round), else
halved. A joint's column is modelled twice, both models from one row: from the unit pair, and scaled, as
:math:`\rho_j \sin(q_j - L)` from the pair before its division by :math:`\rho_j \ge 0` (``joint_trig(scaled=True)``:
no division, so a tighter model over a wide cell; the same roots where :math:`\rho_j > 0`, and a root where the
joint is free, :math:`\rho_j = 0`); its window is the intersection of the two windows, and either model's bounds
may discard the cell. A window narrower than :data:`WINDOW` is a breakpoint (its centre); so are the ends of a cell
over which a column (unit pair) stays within :data:`TOUCH` of 0 (a tangency: a joint touching a level over a whole
cell, to round-off).
The search starts from :data:`CELLS` cells over the circle, less those where the elbow surely cannot reach
(:math:`|c(q_7)| > r(1 +` :data:`REACH`) over the cell, from the sinusoid's exact range: every branch's validity is
below 0 there, so no column has a root of interest), and stops after :data:`ROUNDS` rounds or above
:data:`MAX_CELLS` cells in a round: then the cells left are breakpoints too (their ends), and the answer is not
proved. The gaps between the breakpoints are classified as for the other families
(:class:`~qpik.analytic.intervals.SetAssembler`: one IK evaluation at each midpoint).

**Near members** (:attr:`~qpik.analytic.locked_joint.LockedJointSolver.polished`): the columns are those of the
ideal chain's closed form, the gaps classified by the polished IK of the file's chain. The ends of the sets are
then those of the ideal chain, off from the file's by about the polish's change of the joints, and a validity
change of the polish (where it stops short of the pose, near a singular Jacobian) is no breakpoint: the answers
are not proved (``proved`` False).

**Proved:** when the search ends with no cell left, every root of every column lies within :data:`WINDOW` of a
breakpoint or in a cell where the column is within :data:`TOUCH` of 0, so the sets are exact except within
:data:`WINDOW` of their ends and where a joint is within :data:`TOUCH` rad of a limit (``FeasibleIntervals.proved``).
A free joint (a singular configuration: a unit vector of no direction) is resolved by halving down to
:data:`WINDOW`, which the budget may not allow. The enclosures are computed in round-to-nearest arithmetic
(:mod:`qpik.algebra.enclosure`), which :data:`SLACK` covers for these values of order 1. ``margin`` shrinks the
limits as there (:func:`~qpik.analytic.intervals.shrunk_limits`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.enclosure import taylor_function
from qpik.analytic import trig
from qpik.analytic.intervals import FeasibleIntervals, SetAssembler, shrunk_limits, wrap
from qpik.native.compiled import RowMap, cores

if TYPE_CHECKING:
    from qpik.analytic.locked_joint import LockedJointSolver

CELLS = 64
"""Cells of q7 over the circle at the start of the search."""
WINDOW = 1e-10
"""Width (rad) of a window of roots that is a breakpoint."""
SLACK = 1e-12
"""Added to every remainder: the round-off of the enclosures of values of order 1."""
TOUCH = 1e-10
"""A column within this of 0 over a whole cell (a joint that touches a level there, to this many rad) makes the
cell's ends breakpoints."""
ROUNDS = 80
"""Rounds of the search before the answer is left unproved."""
MAX_CELLS = 2048
"""Cells of q7 in a round above which the answer is left unproved."""
REACH = 1e-6
"""Relative margin beyond the elbow's reach, :math:`|c| > r(1 +` REACH), over a start cell of q7 that leaves the
cell out of the search (every branch invalid over it, with room for round-off)."""
ELBOW = 3
"""Index of q4, whose levels are solved exactly."""
SIGNS = np.array([[1 - 2 * (k >> bit & 1) for bit in (2, 1, 0)] for k in range(8)], float)
"""Per branch id ``4·shoulder + 2·elbow + wrist``, the signs of its shoulder's, elbow's and wrist's roots (8, 3)
(:data:`qpik.analytic.locked_joint.BranchSigns`)."""


class Q7Intervals:
    """The feasible q7 sets of a :class:`~qpik.analytic.locked_joint.LockedJointSolver` (a ``ParameterSets``).

    The columns (:meth:`_columns`) are sin(q_j − L) for a joint j (not q4, not q7) of a branch and a level L, or the
    branch's validity function. ``rounds``: the search's budget (:data:`ROUNDS`).
    """

    proved = True
    """Each answer says whether its search ended (``FeasibleIntervals.proved``); none of a near member's is."""

    def __init__(self, solver: LockedJointSolver, rounds: int = ROUNDS):
        self._solver, self._rounds = solver, rounds
        self._assemble = SetAssembler(solver, solver.n_branches)
        self._n = solver.robot.dof
        self._joints = [j for j in range(self._n - 1) if j != ELBOW]
        T, q7, sign = ca.SX.sym("T", 4, 4), ca.SX.sym("q7"), ca.SX.sym("sign", 3)
        R, p = sy.frame_of_batch(T)
        one = ((sign[0],), (sign[1],), (sign[2],))  # the branch of these signs, chosen at run time
        (row,), (valid,) = solver.joint_trig(R, p, q7, sy.CASADI, one), solver.validity(R, p, q7, sy.CASADI, one)
        (scaled,) = solver.joint_trig(R, p, q7, sy.CASADI, one, scaled=True)
        out = ca.vertcat(*[pairs[j][i] for pairs in (row, scaled) for i in (0, 1) for j in self._joints], valid)
        columns = ca.Function(f"columns_{solver.kind}", [T, q7, sign], [out], {"cse": True})
        self._model = RowMap(taylor_function(columns, [1]), shared=[0], threads=cores(), inline=True)
        """The Taylor models of one branch's outputs (inputs: T, the centre of a cell of q7, the branch's
        :data:`SIGNS`, then the cell's half-width, radius 0 and its ends) over rows of cells and branches, the
        rows of a round shared among the cores. The outputs: the joints' cos q_j, then sin q_j, then both scaled
        (``joint_trig(scaled=True)``), then the validity. They trace the closed form thrice: ``cse`` merges the
        copies, so a row solves the branch once."""
        self._last: tuple[bytes, float, FeasibleIntervals] | None = None
        self._cols: tuple[float, tuple[np.ndarray, ...]] | None = None
        """The last margin and its columns (:meth:`_columns`)."""

    def native_sets(self) -> None:
        """No single C call for this family."""
        return None

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
        if self._cols is None or self._cols[0] != margin:
            self._cols = (margin, self._columns(levels))
        found, left = self._isolate(T, self._cols[1])
        breaks = np.concatenate([found, left, self._elbow_roots(T, levels[ELBOW]), levels[-1]])
        sets, sing = self._assemble(T, breaks, found, (lo, hi))
        return FeasibleIntervals(s.param_name, s.branch_array, sets, sing, proved=not left.size and s.polished is None)

    def _columns(self, levels: list[np.ndarray]) -> tuple[np.ndarray, ...]:
        """The columns, (F,) each: the branch, and weights of its compiled outputs (:attr:`_model`'s, of the unit
        pairs): column k is ``w1[k]·out[i1[k]] + w2[k]·out[i2[k]]`` (sin q_j cos L − cos q_j sin L for a joint j and
        a level L of ``levels``, or the validity out[i1]), joint (False: validity); where cos(q_j − L)
        ``= w1[k]·out[i2[k]] − w2[k]·out[i1[k]]`` is negative its root is L + π, no level. The scaled column is the
        same combination of the outputs 2J further on (J joints)."""
        B, J = self._solver.n_branches, len(self._joints)
        br, i1, w1, i2, w2 = [np.arange(B)], [np.full(B, 4 * J)], [np.ones(B)], [np.zeros(B, int)], [np.zeros(B)]
        for k, j in enumerate(self._joints):
            L = levels[j]
            br.append(np.repeat(np.arange(B), L.size))
            i1.append(np.full(B * L.size, J + k))
            w1.append(np.tile(np.cos(L), B))
            i2.append(np.full(B * L.size, k))
            w2.append(np.tile(-np.sin(L), B))
        out = tuple(np.concatenate(x) for x in (br, i1, w1, i2, w2))
        return (*out, np.arange(out[0].size) >= B)

    def _isolate(self, T: np.ndarray, cols: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
        """The breakpoints of the columns ``cols`` (:meth:`_columns`) at the pose T: the centres of the windows of
        their roots (rad, wrapped), and the ends of the cells left when the budget ran out (empty: proved). The
        start cells where the elbow surely cannot reach (:meth:`_reach`: no branch is valid, so no column has a root
        of interest) are left out."""
        edges = np.linspace(-np.pi, np.pi, CELLS + 1)
        near = self._reach(T, edges[:-1], edges[1:])
        n, F, B = int(near.sum()), cols[0].size, self._solver.n_branches
        a, b, k = np.repeat(edges[:-1][near], F), np.repeat(edges[1:][near], F), np.tile(np.arange(F), n)
        # the first round's rows: (cell, branch) in that order; column b of a cell is branch b's validity
        rows = (np.arange(n)[:, None] * F + np.arange(B)).ravel(), np.repeat(np.arange(n) * B, F) + np.tile(cols[0], n)
        found = []
        Tf = np.asarray(T, float).reshape(-1, order="F")
        ints, w, joint = self._packed(cols)
        for _ in range(self._rounds):
            if not a.size:
                break
            bounds = self._bounds(Tf, a, b, (ints[:, k], w[:, k], joint[k]), rows)
            if bounds is None:
                break
            rows = None
            kept, f0, f1, rest, outside = bounds
            a, b, k = a[kept], b[kept], k[kept]
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                t1, t2 = (-f0 - rest) / f1, (-f0 + rest) / f1
            flat = ~(np.abs(f1) > 0) | ~np.isfinite(rest)  # no slope, or no model: the whole cell
            t1, t2 = np.where(flat, -1.0, np.minimum(t1, t2)), np.where(flat, 1.0, np.maximum(t1, t2))
            t1, t2 = np.maximum(t1.max(axis=0), -1.0), np.minimum(t2.min(axis=0), 1.0)  # both models' windows
            m, h = 0.5 * (a + b), 0.5 * (b - a)
            x1, x2 = m + h * t1, m + h * t2
            gone = (t1 > t2) | outside | (flat & (np.abs(f0) > rest)).any(axis=0)
            done = ~gone & (x2 - x1 <= WINDOW)
            touch = ~gone & ~done & (np.abs(f0[0]) + np.abs(f1[0]) + rest[0] <= TOUCH)
            found += [0.5 * (x1 + x2)[done], a[touch], b[touch]]
            live = ~gone & ~done & ~touch
            narrow = live & (x2 - x1 <= h)  # at most half the cell: the window is the next cell
            halve = live & ~narrow
            mid = 0.5 * (x1 + x2)[halve]
            a = np.concatenate([x1[narrow], x1[halve], mid])
            b = np.concatenate([x2[narrow], mid, x2[halve]])
            k = np.concatenate([k[narrow], k[halve], k[halve]])
        found = wrap(np.concatenate(found)) if found else np.zeros(0)
        return found, wrap(np.concatenate([a, b]))

    def _bounds(
        self,
        Tf: np.ndarray,
        a: np.ndarray,
        b: np.ndarray,
        cols: tuple[np.ndarray, np.ndarray, np.ndarray],
        rows: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, ...] | None:
        """Over the cells [a, b] (K,) of the columns ``cols`` (:meth:`_packed`, with K columns): the columns that may
        have a root of interest (indices, (K',): not those of a joint of a branch surely invalid over the cell), and
        for them the Taylor models ``f0 + f1·t ± rest`` (t ∈ [−1, 1]; rest with :data:`SLACK`) of the column and of
        its scaled column ((2, K') each) and where the column surely has no root of interest (the bounds of either
        exclude 0, or cos(q_j − L) < 0); None above :data:`MAX_CELLS`
        cells (of all the branches). ``Tf``: the pose, column-major (16,). One call of the model for the distinct
        (branch, cell) pairs: ``rows`` (one column of each, (R,); each column's row, (K,)) when known, else found
        by sorting."""
        (br, i1, i2), w, joint = cols
        P = 4 * len(self._joints) + 1  # outputs per branch, its validity last
        if rows is None:
            keys = np.stack([b, a, br])
            order = np.lexsort(keys)  # by branch, then a, then b
            ranked = keys[:, order]
            new = np.ones(a.size, bool)
            new[1:] = (ranked[:, 1:] != ranked[:, :-1]).any(axis=0)
            first = order[new]  # one column of each distinct (branch, cell)
            row = np.empty(a.size, int)
            row[order] = np.cumsum(new) - 1
        else:
            first, row = rows
        if first.size > MAX_CELLS:
            return None
        x, y = a[first, None], b[first, None]
        out = self._model(Tf, 0.5 * (x + y), SIGNS[br[first]], 0.5 * (y - x), np.zeros_like(x), x, y)
        kept = np.flatnonzero(~joint | ~(out[4][row, P - 1] < -SLACK))  # where the branch may be valid
        row, i1, i2, w, joint = row[kept], i1[kept], i2[kept], w[:, kept], joint[kept]
        end = first.size * P
        vals = np.empty((5, end + 1))  # the flattened (rows, P) results, then 0: a validity's second output
        for v, o in zip(vals, out):
            v[:end] = o.ravel()
        vals[:, end] = 0.0
        first_out = row * P + i1, np.where(joint, row * P + i2, end)
        scaled = np.where(joint, 2 * len(self._joints), 0)  # a joint's scaled outputs; the validity's own
        idx = np.stack([*first_out, first_out[0] + scaled, np.where(joint, first_out[1] + scaled, end)])
        g = np.take(vals, idx, axis=1).reshape(5, 2, 2, -1)  # (part, model, output, K')
        with np.errstate(invalid="ignore", over="ignore"):  # inf or nan (a free joint): the cell stays undecided
            c0, c1, lo, hi = w * g[[0, 1, 3, 4]]
            r = np.abs(w) * g[2]
            low, high = np.minimum(lo, hi), np.maximum(lo, hi)
            cos_hi = np.maximum(w[0] * g[3, :, 1], w[0] * g[4, :, 1]) + np.maximum(
                -w[1] * g[3, :, 0], -w[1] * g[4, :, 0]
            )
            f0, f1, rest = c0.sum(axis=1), c1.sum(axis=1), r.sum(axis=1) + SLACK
            low, high = low.sum(axis=1), high.sum(axis=1)
        far = joint & (cos_hi < -SLACK)
        return kept, f0, f1, rest, (far | (low > SLACK) | (high < -SLACK)).any(axis=0)

    @staticmethod
    def _packed(cols: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        """:meth:`_columns` as the search gathers them: the branches and the two outputs' indices (3, F), the weights
        (2, F; a validity's second weight +0), joint (F,)."""
        br, i1, w1, i2, w2, joint = cols
        return np.stack([br, i1, i2]), np.stack([w1, np.where(joint, w2, 0.0)]), joint

    def _reach(self, T: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Over the cells [a, b] (K,) of q7 (rad, within [−π, π]), False where the elbow surely cannot reach: the
        sinusoid c(q7) (:meth:`_elbow`) stays beyond ±r(1 + :data:`REACH`) over the cell, so every branch's
        validity (at most the elbow's relative discriminant + EPS) is below 0 there."""
        K, P, Q = self._elbow(T)
        rho, theta = np.hypot(P, Q), np.arctan2(Q, P)
        ca_, cb_ = K + P * np.cos(a) + Q * np.sin(a), K + P * np.cos(b) + Q * np.sin(b)
        top = np.where(np.mod(theta - a, 2.0 * np.pi) < b - a, K + rho, np.maximum(ca_, cb_))
        bottom = np.where(np.mod(theta + np.pi - a, 2.0 * np.pi) < b - a, K - rho, np.minimum(ca_, cb_))
        far = (1.0 + REACH) * self._solver.r4
        return ~((bottom > far) | (top < -far))

    def _elbow(self, T: np.ndarray) -> tuple[float, float, float]:
        r"""The elbow's :math:`c(q_7) = K + P\cos q_7 + Q\sin q_7` at the pose T (module docstring): (K, P, Q)."""
        s = self._solver
        R, p = np.asarray(T, float)[:3, :3], np.asarray(T, float)[:3, 3]
        k7, c7, w7 = (np.array(x, float) for x in (s.k7, s.c7, s.w7))
        w_par = (k7 @ w7) * k7
        e = np.array(s.S) - p - R @ (c7 + w_par)
        A = e @ e + (w7 - w_par) @ (w7 - w_par)
        B, C = -2.0 * e @ (R @ (w7 - w_par)), 2.0 * e @ (R @ np.cross(k7, w7))
        return s.k4 - 0.5 * A, -0.5 * B, -0.5 * C

    def _elbow_roots(self, T: np.ndarray, levels: np.ndarray) -> np.ndarray:
        """The q7 (rad) where q4 meets one of ``levels`` or the elbow's discriminant vanishes (module docstring)."""
        s = self._solver
        K, P, Q = self._elbow(T)
        # c(q7) = K + P cos q7 + Q sin q7 = target  <=>  −P cos + −Q sin = K − target
        targets = np.concatenate([s.r4 * np.cos(levels - s.phi), [s.r4, -s.r4]])
        plus, minus, ok = trig.solve_cos_sin(-P, -Q, K - targets, sy.NUMPY)
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
