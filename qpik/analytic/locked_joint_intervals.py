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
model of every column (:func:`qpik.algebra.enclosure.taylor_function`) is :math:`f(m + h t) \in f_0 + f_1 t +
[-r, r]`, beside interval bounds. One compiled row per cell and branch (whose shoulder, elbow and wrist signs are
inputs: one function for every branch, one call for all the rows of a round) solves the branch once, forms every
column's models and takes the round's step on each (:func:`~qpik.algebra.enclosure.isolation_step`): what
follows. The column's roots in the cell then lie where :math:`|f_0 + f_1 t| \le r + ` :data:`SLACK` (a Newton step
with its remainder enclosed, as in the interval Newton method, Moore 1966): the cell is discarded when that is
empty (or the bounds exclude 0, or, for a joint, the branch's validity is below 0 over it), replaced by that window
when the window is at most half as wide (near a simple root the window shrinks quadratically from round to round),
else halved. A joint's column is modelled twice, both models from one row: from the unit pair, and scaled, as
:math:`\rho_j \sin(q_j - L)` from the pair before its division by :math:`\rho_j \ge 0` (``joint_trig(scaled=True)``:
no division, so a tighter model over a wide cell; the same roots where :math:`\rho_j > 0`, and a root where the
joint is free, :math:`\rho_j = 0`); its window is the intersection of the two windows, and either model's bounds
may discard the cell. A window narrower than :data:`WINDOW` is a breakpoint (its centre); so are the ends of a cell
over which a column (unit pair) stays within :data:`TOUCH` of 0 (a tangency: a joint touching a level over a whole
cell, to round-off).
The search starts from :data:`CELLS` cells over the circle, less those where the elbow surely cannot reach
(:math:`|c(q_7)| > r(1 +` :data:`REACH`) over the cell, from the sinusoid's exact range: every branch's validity is
below 0 there, so no column has a root of interest) and, in each cell left, the branches of an elbow whose wrist
surely cannot reach over it (the Taylor model of its
:meth:`~qpik.analytic.locked_joint.LockedJointSolver.arm_validity`, a bound of its branches' validity, below 0:
:meth:`Q7Intervals._arm_reach`), and stops after :data:`ROUNDS` rounds or above
:data:`MAX_CELLS` cells in a round: then the cells left are breakpoints too (their ends), and the answer is not
proved. The gaps between the breakpoints are classified as for the other families
(:class:`~qpik.analytic.intervals.SetAssembler`: one IK evaluation at each midpoint).

**Near members** (:attr:`~qpik.analytic.locked_joint.LockedJointSolver.polished`): the columns are those of the
ideal chain's closed form, the gaps classified by the polished IK of the file's chain. The ends of the sets are
then those of the ideal chain, off from the file's by about the polish's change of the joints, until the solver
moves them onto the file's chain (:mod:`qpik.analytic.set_ends`). A validity change of the polish (where it stops
short of the pose, near a singular Jacobian: a fold of the file's chain that the ideal one does not have) is no
breakpoint; the search also isolates the roots of each branch's validity ∓ the solver's
:attr:`~qpik.analytic.locked_joint.LockedJointSolver.thin`, which bound the stretches where such a fold may lie
(:meth:`Q7Intervals.thin`). They are breakpoints too, so that no gap is classified at a middle inside such a
stretch (where the polished branch may be invalid for a few milliradians while it is valid on the rest of the gap),
and the solver samples its branches there (:func:`qpik.analytic.set_ends.resample`). The answers are not proved
(``proved`` False).

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
from qpik.algebra.enclosure import DONE, HALVE, NARROW, TOUCHED, isolation_step, taylor_function
from qpik.analytic import trig
from qpik.analytic.intervals import FeasibleIntervals, Interval, SetAssembler, gaps, merge, shrunk_limits, wrap
from qpik.analytic.locked_joint import SIGNS
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
        self._steps: dict[tuple[int, ...], RowMap] = {}
        """Per tuple of the joint columns' joints (:meth:`_columns`), one round of the search on every column of a
        branch over a cell (:meth:`_step_function`) over rows of cells and branches, the rows of a round shared
        among the cores; compiled on first use (one tuple for every margin of most arms)."""
        T, q7, sign = ca.SX.sym("T", 4, 4), ca.SX.sym("q7"), ca.SX.sym("sign")
        (arm,) = solver.arm_validity(*sy.frame_of_batch(T), q7, sy.CASADI, (sign,))
        arm_fn = ca.Function(f"arm_{solver.kind}", [T, q7, sign], [arm])
        self._arm = RowMap(taylor_function(arm_fn, [1]), shared=[0], threads=cores(), inline=True)
        """The Taylor models of the :meth:`~qpik.analytic.locked_joint.LockedJointSolver.arm_validity` of an
        elbow (inputs: T, the centre of a cell of q7, the elbow's sign, then the cell's half-width, radius 0 and
        its ends) over rows of cells and elbows (:meth:`_arm_reach`)."""
        self._validity = None
        """A near member's :meth:`~qpik.analytic.locked_joint.LockedJointSolver.validity` of every branch (8,) at T
        and q7, compiled, over rows of q7 (:meth:`_thin`)."""
        if solver.thin is not None:
            every = solver.validity(*sy.frame_of_batch(T), q7, sy.CASADI)
            self._validity = RowMap(ca.Function(f"validity_{solver.kind}", [T, q7], [ca.vertcat(*every)]), [0])
        self._last: tuple[bytes, float, FeasibleIntervals, list[list[Interval]]] | None = None
        self._cols: tuple[float, tuple] | None = None
        """The last margin and its columns (:meth:`_columns`)."""

    def _step_function(self, joints: tuple[int, ...]) -> ca.Function:
        """One round of the search on every column of a branch over a cell, its joint columns those of the joints
        ``joints`` (indices into :attr:`_joints`, one per column) at levels given at run time: the Taylor models (in
        q7 over the cell) of the branch's cos q_j and sin q_j for the joints of :attr:`_joints`, of both scaled
        (``joint_trig(scaled=True)``) and of its validity (one compiled function for every branch: its signs are
        inputs; the joints and the validity trace the closed form thrice, and ``cse`` merges the copies), combined
        into each column's two models and :func:`~qpik.algebra.enclosure.isolation_step` (the joints' columns also
        gone where the validity is below 0 over the cell or cos(q_j − L) < 0).

        Inputs: T (4, 4), the levels' (cos L, sin L) (2, F), the cell's ends a < b (rad), the branch's
        :data:`~qpik.analytic.locked_joint.SIGNS`. Output (3C,) over the C = F + 1 slots (0: the validity; i: the joint
        column of level i − 1), for a near member C = F + 3 (slots F + 1, F + 2: the validity less and plus the solver's
        :attr:`~qpik.analytic.locked_joint.LockedJointSolver.thin`): every slot's window start x1, then every slot's
        window end x2 (rad), then every slot's fate (:data:`~qpik.algebra.enclosure.GONE` ...)."""
        s, J = self._solver, len(self._joints)
        T, q7, sign = ca.SX.sym("T", 4, 4), ca.SX.sym("q7"), ca.SX.sym("sign", 3)
        R, p = sy.frame_of_batch(T)
        one = ((sign[0],), (sign[1],), (sign[2],))  # the branch of these signs, chosen at run time
        (unit,), (valid,) = s.joint_trig(R, p, q7, sy.CASADI, one), s.validity(R, p, q7, sy.CASADI, one)
        (scaled,) = s.joint_trig(R, p, q7, sy.CASADI, one, scaled=True)
        out = ca.vertcat(*[pair[j][i] for pair in (unit, scaled) for i in (0, 1) for j in self._joints], valid)
        columns = ca.Function(f"columns_{s.kind}", [T, q7, sign], [out], {"cse": True})
        levels, a, b = ca.SX.sym("levels", 2, len(joints)), ca.SX.sym("a"), ca.SX.sym("b")
        parts = taylor_function(columns, [1])(T, 0.5 * (a + b), sign, 0.5 * (b - a), 0.0, a, b)

        def model(i: int) -> tuple[ca.SX, ...]:
            return tuple(x[i] for x in parts)

        steps = [isolation_step(a, b, model(4 * J), False, SLACK, WINDOW, TOUCH)]
        invalid = parts[4][4 * J] < -SLACK
        for i, k in enumerate(joints):
            c, s_ = levels[0, i], levels[1, i]
            models, away = [], invalid
            for o in (k, 2 * J + k):  # the unit pair's cos q_j, then the scaled one's
                cos_q, sin_q = model(o), model(o + J)
                models.append(_combined(c, sin_q, -s_, cos_q))  # sin(q_j − L)
                away = ca.logic_or(away, _combined(c, cos_q, s_, sin_q)[4] < -SLACK)  # cos(q_j − L) < 0
            steps.append(isolation_step(a, b, models[0], away, SLACK, WINDOW, TOUCH, also=models[1:]))
        if s.thin is not None:  # the validity ∓ thin: the ends of its thin stretches
            c, slope, r, lo, hi = model(4 * J)
            for d in (s.thin, -s.thin):
                steps.append(isolation_step(a, b, (c - d, slope, r, lo - d, hi - d), False, SLACK, WINDOW, TOUCH))
        x1, x2, fate = zip(*steps)
        name = f"step_{s.kind}_{''.join(map(str, joints))}{'' if s.thin is None else '_thin'}"
        return ca.Function(name, [T, levels, a, b, sign], [ca.vertcat(*x1, *x2, *fate)])

    def native_sets(self) -> None:
        """No single C call for this family."""
        return None

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """Per branch, the q7 (rad) where every joint lies in the limits shrunk by ``margin``; ``T`` (4, 4). The
        last answer is kept: the same pose and margin again (a viewer's sets, then its best answer's level sets)
        return the same object."""
        return self._answer(T, margin)[0]

    def thin(self, T: np.ndarray, margin: float = 0.0) -> list[list[Interval]]:
        """Per branch, the q7 (rad) where a near member's ideal chain's validity lies within
        :attr:`~qpik.analytic.locked_joint.LockedJointSolver.thin` of 0 (either side: the polish of a branch the
        ideal chain has not may still reach the pose on the file's chain): sorted disjoint intervals, split at ±π,
        from the roots of its validity and of the validity ∓ that (the search's, kept with the last answer); empty
        for an exact member. ``T``, ``margin`` as :meth:`__call__`'s."""
        return self._answer(T, margin)[1]

    def _answer(self, T: np.ndarray, margin: float) -> tuple[FeasibleIntervals, list[list[Interval]]]:
        """The sets and the thin stretches (:meth:`thin`), computed once per pose and margin."""
        key = np.asarray(T, float).tobytes()
        if self._last is None or self._last[0] != key or self._last[1] != margin:
            self._last = (key, margin, *self._sets(T, margin))
        return self._last[2], self._last[3]

    def _sets(self, T: np.ndarray, margin: float) -> tuple[FeasibleIntervals, list[list[Interval]]]:
        s = self._solver
        none: list[list[Interval]] = [[] for _ in s.branch_ids]
        if margin > 1.0:
            return FeasibleIntervals(s.param_name, s.branch_array, none, [[] for _ in s.branch_ids]), none
        lo, hi = shrunk_limits(s.robot.q_min, s.robot.q_max, margin)
        levels = _levels(lo, hi)
        if self._cols is None or self._cols[0] != margin:
            self._cols = (margin, self._columns(levels))
        found, col, left = self._isolate(T, self._cols[1])
        br, slot, _, joints, _ = self._cols[1]
        edge = slot[col] > len(joints)  # roots of the validity ∓ ``thin`` (a near member's only)
        ends = edge | (slot[col] == 0)
        thin = none if s.thin is None else self._thin(T, found[ends], br[col[ends]])
        breaks = np.concatenate([found, left, self._elbow_roots(T, levels[ELBOW]), levels[-1]])
        sets, sing = self._assemble(T, breaks, found[~edge], (lo, hi))  # a thin stretch is no gap's middle's
        proved = not left.size and s.polished is None
        return FeasibleIntervals(s.param_name, s.branch_array, sets, sing, proved=proved), thin

    def _columns(self, levels: list[np.ndarray]) -> tuple:
        """The columns, branch by branch: their branches and slots (F,) each (slot 0: the branch's validity; slot
        i > 0: sin(q_j − L) for the joint j of :attr:`_joints` index ``joints[i − 1]`` and a level L of
        ``levels``); the levels' cosines and sines as the step reads them (column-major (2, C − 1)), ``joints`` and
        the step (:meth:`_step_function`, C slots)."""
        joints = tuple(k for k, j in enumerate(self._joints) for _ in levels[j])
        L = np.concatenate([levels[j] for j in self._joints])
        if joints not in self._steps:
            self._steps[joints] = RowMap(self._step_function(joints), shared=[0, 1], threads=cores(), inline=True)
        C, B = len(joints) + (1 if self._solver.thin is None else 3), self._solver.n_branches
        trig = np.stack([np.cos(L), np.sin(L)], axis=1).ravel()
        return np.repeat(np.arange(B), C), np.tile(np.arange(C), B), trig, joints, self._steps[joints]

    def _isolate(self, T: np.ndarray, cols: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The breakpoints of the columns ``cols`` (:meth:`_columns`) at the pose T: the centres of the windows of
        their roots (rad, wrapped), the column of each (an index into ``cols``' branches and slots), and the ends of
        the cells left when the budget ran out (empty: proved). The
        start cells where the elbow surely cannot reach (:meth:`_reach`: no branch is valid, so no column has a root
        of interest) are left out, and so are the branches of a start cell whose wrist surely cannot reach
        (:meth:`_arm_reach`)."""
        edges = np.linspace(-np.pi, np.pi, CELLS + 1)
        near = self._reach(T, edges[:-1], edges[1:])
        br, slot, trig, _, step = cols
        n, F, B = int(near.sum()), br.size, self._solver.n_branches
        Tf = np.asarray(T, float).reshape(-1, order="F")
        pairs = self._arm_reach(Tf, edges[:-1][near], edges[1:][near]).ravel()  # (cell, branch) in that order
        cell, col = np.repeat(np.arange(n), F), np.tile(np.arange(F), n)
        keep = pairs[cell * B + br[col]]
        a, b, k = edges[:-1][near][cell[keep]], edges[1:][near][cell[keep]], col[keep]
        # the first round's rows: the pairs kept, one column of each (its validity, the branch's first)
        at = np.cumsum(keep) - 1  # a kept column's index
        first = at[(np.arange(n)[:, None] * F + np.searchsorted(br, np.arange(B))).ravel()[pairs]]
        rows = first, (np.cumsum(pairs) - 1)[cell[keep] * B + br[k]]
        found, which = [], []
        for _ in range(self._rounds):
            if not a.size:
                break
            windows = self._round(step, (Tf, trig), a, b, br[k], slot[k], rows)
            if windows is None:
                break
            rows = None
            x1, x2, fate = windows
            done, touch = fate == DONE, fate == TOUCHED
            found += [0.5 * (x1 + x2)[done], a[touch], b[touch]]
            which += [k[done], k[touch], k[touch]]
            narrow, halve = fate == NARROW, fate == HALVE
            mid = 0.5 * (x1 + x2)[halve]
            a = np.concatenate([x1[narrow], x1[halve], mid])
            b = np.concatenate([x2[narrow], mid, x2[halve]])
            k = np.concatenate([k[narrow], k[halve], k[halve]])
        if not found:
            return np.zeros(0), np.zeros(0, int), wrap(np.concatenate([a, b]))
        return wrap(np.concatenate(found)), np.concatenate(which), wrap(np.concatenate([a, b]))

    def _thin(self, T: np.ndarray, roots: np.ndarray, branch: np.ndarray) -> list[list[Interval]]:
        """:meth:`thin` from the roots (rad) of the branches ``branch`` (both (K,)) of their validity and of their
        validity ∓ ``thin``: per branch, the runs of the gaps between its roots (and ±π) whose middle's validity
        (:attr:`_validity`) lies within ``thin`` of 0 (:func:`~qpik.analytic.intervals.merge`)."""
        s = self._solver
        assert self._validity is not None
        cuts = [gaps(np.concatenate([[np.pi], roots[branch == k]])) for k in range(s.n_branches)]
        mids = np.concatenate([wrap(0.5 * (lo + hi)) for lo, hi in cuts])
        (every,) = self._validity(np.asarray(T, float).reshape(-1, order="F"), mids)  # (all middles, B)
        own = np.split(every, np.cumsum([len(lo) for lo, _ in cuts])[:-1])  # per branch: its middles
        return [merge(lo, hi, np.abs(v[:, k, None]) < s.thin)[0] for k, ((lo, hi), v) in enumerate(zip(cuts, own))]

    def _round(
        self,
        step: RowMap,
        shared: tuple[np.ndarray, np.ndarray],
        a: np.ndarray,
        b: np.ndarray,
        br: np.ndarray,
        slot: np.ndarray,
        rows: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, ...] | None:
        """One round of the search over the cells [a, b] (K,) of the columns of branches ``br`` and slots ``slot``
        (K,): each column's window (x1, x2, rad) and fate (K,) each, from ``step`` (:meth:`_columns`'); None above
        :data:`MAX_CELLS` cells (of all the branches). ``shared``: the pose, column-major (16,), and the levels'
        cosines and sines (:meth:`_columns`). One row for each distinct (branch, cell) pair: ``rows`` (one column of
        each, (R,); each column's row, (K,)) when known, else found by sorting."""
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
        (out,) = step(*shared, a[first, None], b[first, None], SIGNS[br[first]])
        C, flat = out.shape[1] // 3, out.ravel()
        at = row * (3 * C) + slot
        return flat[at], flat[at + C], flat[at + 2 * C]

    def _arm_reach(self, Tf: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Over the cells [a, b] (K,) of q7 (rad), per branch (K, B), False where its elbow's
        :meth:`~qpik.analytic.locked_joint.LockedJointSolver.arm_validity` is surely below 0 (the wrist cannot
        reach; :attr:`_arm`'s model): so is the branch's validity, so none of its columns has a root of interest.
        ``Tf``: the pose, column-major (16,)."""
        if not a.size:
            return np.zeros((0, self._solver.n_branches), bool)
        x, y = np.repeat(a, 2)[:, None], np.repeat(b, 2)[:, None]
        sign = np.tile([1.0, -1.0], a.size)[:, None]  # the elbows of bit 1 = 0, 1 of a branch id
        hi = self._arm(Tf, 0.5 * (x + y), sign, 0.5 * (y - x), np.zeros_like(x), x, y)[4].reshape(-1, 2)
        return ~(hi < -SLACK)[:, (np.arange(self._solver.n_branches) >> 1) & 1]  # a branch's elbow: its bit 1

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


def _combined(w1: ca.SX, m1: tuple[ca.SX, ...], w2: ca.SX, m2: tuple[ca.SX, ...]) -> tuple[ca.SX, ...]:
    """The Taylor model (centre, slope, remainder, lo, hi) of ``w1·f1 + w2·f2`` from those of f1 and f2 (same t)."""
    return (
        w1 * m1[0] + w2 * m2[0],
        w1 * m1[1] + w2 * m2[1],
        ca.fabs(w1) * m1[2] + ca.fabs(w2) * m2[2],
        ca.fmin(w1 * m1[3], w1 * m1[4]) + ca.fmin(w2 * m2[3], w2 * m2[4]),
        ca.fmax(w1 * m1[3], w1 * m1[4]) + ca.fmax(w2 * m2[3], w2 * m2[4]),
    )
