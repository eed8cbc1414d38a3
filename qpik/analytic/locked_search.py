r"""IK of a 7-R arm with one joint locked by a certified 1-D search (Elias & Wen 2022, IK-Geo): the search itself.

A geometry (:class:`LockedSearch`'s subclasses, :mod:`qpik.analytic.search_geometry`: the Rethink Sawyer and Baxter,
the Flexiv Rizons) reads the arm in the search's order (q7 locked, forwards; or the chain read from the flange,
:func:`~qpik.robots.locked_joint.reversed_chain`, joint k the arm's joint 8 − k, pose :math:`T^{-1}`, where the arm's
q1 is locked) and gives, for its search variable x (one joint, :attr:`LockedSearch.variable`) and each branch b (a
row of :attr:`LockedSearch.signs`, the signs of its two subproblems' roots):

- the **error function** :math:`e_b(x)`, zero where the joints its subproblems give at x reach the pose;
- the validity :math:`v_b(x)`, the subproblems' smaller relative discriminant (+ EPS), :math:`\ge 0` where they
  have roots;
- the reach, a bound of every branch's validity over x (:meth:`LockedSearch.reach`);
- the (cos, sin) of joints 1-6 at x (meaningful at a root).

Each root of :math:`e_b` where :math:`v_b \ge 0` is an IK solution.

**Every root.** :math:`e_b` and :math:`v_b` are written once against :mod:`qpik.algebra.symbolic`; their first-order
Taylor models over cells of x (:func:`qpik.algebra.enclosure.taylor_function`, compiled and mapped over rows of cells
and branches, :class:`~qpik.native.compiled.RowMap`) isolate the roots as :mod:`qpik.analytic.locked_joint_intervals`
does (Moore 1966; Makino & Berz 2003): from :data:`CELLS` cells over the circle, less those where the Taylor model of
the reach (:meth:`LockedSearch.reach`, a bound of every branch's validity) is below 0 (no branch has its
subproblems' roots there; most of the circle), a cell is discarded where the model's window
:math:`|f_0 + f_1 t| \le r +` :data:`~qpik.analytic.search_step.SLACK` is empty or the bounds exclude 0 or the branch's
validity is below 0 over the cell, replaced by that window where it is at most half as wide, else by the window cut in
:data:`SPLIT` equal parts; a window narrower than :data:`~qpik.analytic.search_step.WINDOW` holds a root (its centre),
and so do the ends of a cell where :math:`|e_b|` stays within :data:`~qpik.analytic.search_step.TOUCH` of 0 (a double
root, where the window stays the whole cell however often it is cut: such a cell is a few µm wide when it is touched).
Every root of every :math:`e_b` is then within :data:`~qpik.analytic.search_step.WINDOW` of a candidate, or inside a
touched cell whose ends are candidates, unless the search ran out of its budget (:data:`ROUNDS`, :data:`MAX_CELLS`;
``proved`` False). Where the validity vanishes inside a window the square roots of the subproblems have no slope and
the cell is cut down to :data:`~qpik.analytic.search_step.WINDOW` like any other.

**Machine precision.** The joints of each candidate (each once: two cells may end at one point) start :data:`POLISH`
rounds of Newton on the arm's own chain, the locked joint held (:func:`qpik.analytic.polish.polish`, compiled and mapped
over the candidates); a candidate is a solution where the residual is at most
:data:`~qpik.analytic.polish.RESIDUAL_TOL`, and solutions within :data:`SAME` rad of each other are one.

**Near members** (:class:`~qpik.analytic.search_geometry.ShoulderSearch`). A file whose axes miss the geometry by at
most :data:`~qpik.robots.locked_joint.NEAR_TOL` is searched on its nearest ideal chain
(:func:`~qpik.robots.locked_joint.ideal_chain`), the candidates then polished on the file's: ``proved`` is then False.
The ideal chain's rotations are the file's at every q and its end's position at most :attr:`LockedSearch.deviation` D
away (:class:`~qpik.robots.locked_joint.ChainGap`), so the file's roots are the roots of the ideal chain's :math:`e_b`
at a pose whose position is at most D away: within :math:`D\,|\nabla_p e_b|_1` of 0 on the ideal chain, to first order.
Near a fold of :math:`e_b` (a double root) the file's chain may have two roots where the ideal chain's :math:`e_b` only
nears 0, or none where it has two. So the search keeps every cell where :math:`|e_b|` may be within that bound (times
:data:`~qpik.analytic.search_step.NEAR_GAIN`, the gradient at the cell's centre) of 0, its slack and touch, and a window
of :data:`~qpik.analytic.search_step.NEAR_WINDOW` ends the cell: its candidates are the root of the window's linear
model and the window's two ends (a touched cell's likewise), each polished on the file's chain, which decides (a
candidate whose polish does not reach the pose is dropped).

**Behind** :func:`qpik.ik`: :mod:`qpik.analytic.search_solver` puts the solutions in 16 slots with identities along
the parameter.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.enclosure import DONE, HALVE, NARROW, TOUCHED, taylor_function
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.intervals import apart
from qpik.analytic.polish import RESIDUAL_TOL, polish
from qpik.analytic.search_step import SLACK, step_function
from qpik.analytic.trig import EPS
from qpik.core.validate import number, single_pose
from qpik.native.compiled import RowMap
from qpik.robots.chain import SerialChain
from qpik.robots.locked_joint import ChainGap

CELLS = 192
"""Cells of x over the circle at the start of the search."""
ROUNDS = 80
"""Rounds of the search before the answer is left unproved."""
SPLIT = 3
"""Parts (of equal width) a cell's window is cut into where it is more than half the cell's width."""
MAX_CELLS = 4096
"""Cells (of all branches) in a round above which the answer is left unproved."""
CHUNKS = (64, 16, 4)
"""Rows per compiled call of the step and of the reach (:class:`~qpik.native.compiled.RowMap`)."""
POLISH = 3
"""Rounds of :func:`~qpik.analytic.polish.polish` (each of its Newton steps) from a candidate."""
SAME = 1e-8
"""rad: solutions this close in every joint are one."""
MOST = 16
"""The most isolated solutions of a 6-R chain (Lee & Liang 1988): more is a continuum."""
VALLEY = 1e-2
"""rad: solutions of one error function this close are one where their midpoint reaches the pose
(:meth:`LockedSearch._valleys`)."""
DOUBLE = 1e-9
"""A root where the validity :math:`v_b` (the subproblems' smaller discriminant, relative) is at most this is at a
double root of a subproblem (:attr:`SearchSolutions.double`)."""
TIE = 1e-9
"""rad: the joints of two error functions' subproblems (:attr:`LockedSearch.decided`) this much nearer to a solution
are as near (:meth:`LockedSearch.branch_of`)."""
PARTNER = 1e-3
"""rad: at a double root of a subproblem, the joints of the two roots' b are this close
(:meth:`LockedSearch.branch_of`)."""


@dataclass(frozen=True)
class SearchSolutions:
    """The IK solutions of one pose at one value of the locked joint.

    Attributes:
        q: (K, 7) rad, the arm's joint order, each reaching the pose by the arm's own FK (K ≤ 16; 0 if unreachable).
        branch: (K,) the branch b (0-3) of the error function each root is of.
        residual: (K,) the polish's residual (m and rotation-matrix entries).
        proved: every root of every error function was isolated within the search's budget, on the arm's own chain
            (not a near member's ideal one).
        double: (K,) bool, the root is where the two roots of a subproblem (σ3's or σ12's) meet, so that it is a root
            of two error functions: found by both, or its validity :math:`v_b` at most :data:`DOUBLE` there; its b is
            then the smaller of the two where both found it.
    """

    q: np.ndarray
    branch: np.ndarray
    residual: np.ndarray
    proved: bool
    double: np.ndarray


class LockedSearch(ABC):
    """The certified 1-D search of a geometry (module docstring): subclasses say the geometry (:attr:`signs`,
    :attr:`variable`, :attr:`decided`, :meth:`reach`, :meth:`error`) and call this constructor, which builds and
    compiles the search's functions from it.

    Args:
        own: the arm's chain in the search's order (reversed where ``reversed``): the polish's.
        reversed: the chain is the arm read from the flange (the arm's q1 is locked), else forwards (q7 locked).
        gap: a near member's gap of ``own`` over the ideal chain the geometry was found on
            (:class:`~qpik.robots.locked_joint.ChainGap`); None for an exact member.
        near: a near member's misses in words ("" for an exact member).
    """

    signs = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
    """(B, 2) per branch b, the signs of its two subproblems' roots: ``b = 2 [σ_first < 0] + [σ_second < 0]``."""
    variable: int
    """The search variable x: its joint in the search's order (0-based)."""
    decided: tuple[int, ...]
    """The joints (search's order, 0-based) that the branch's subproblems give at x: :meth:`branch_of` compares
    them."""

    def __init__(self, own: SerialChain, reversed: bool, gap: ChainGap | None = None, near: str = ""):
        self.reversed, self.exact, self.near = reversed, gap is None, near
        self.locked = 1 if reversed else 7
        """The arm's locked joint (1-based): the parameter."""
        self.own = own
        """The arm's chain in the search's order (reversed where :attr:`reversed`): the polish's."""
        T, q7, x, sign = ca.SX.sym("T", 4, 4), ca.SX.sym("q7"), ca.SX.sym("x"), ca.SX.sym("sign", 2)
        R, p = sy.frame_of_batch(T)
        e, valid, _ = self.error(R, p, q7, x, (sign[0], sign[1]), sy.CASADI)
        model = taylor_function(ca.Function("locked_search", [T, q7, x, sign], [ca.vertcat(e, valid)]), [2])
        self.deviation = 0.0 if gap is None else gap.bound
        """m: a bound of the change of the end's position between the file's chain and the ideal one the search runs
        on, at every q (0 for an exact member; :attr:`~qpik.robots.locked_joint.ChainGap.bound`)."""
        gain = None
        if not self.exact:  # |∂e_b/∂p|_1: the file's roots are those of the ideal chain's e_b at a pose D away
            grad = ca.jacobian(e, ca.vertcat(T[0, 3], T[1, 3], T[2, 3]))
            gain = ca.Function("locked_search_gain", [T, q7, x, sign], [ca.sum2(ca.fabs(grad))])
        step = step_function(model, self.signs, gain, self.deviation)
        self._step = RowMap(step, shared=[0, 1], chunks=CHUNKS, inline=True)
        """One round's step of a cell of a branch (:func:`~qpik.analytic.search_step.step_function`), compiled, over
        rows of cells (a, b, b's index; the pose and the locked angle shared)."""
        reach = ca.Function("locked_search_reach", [T, q7, x], [self.reach(R, p, q7, x, sy.CASADI)])
        a, b = ca.SX.sym("a"), ca.SX.sym("b")
        top = [taylor_function(reach, [2])(T, q7, 0.5 * (a + b), 0.5 * (b - a), 0.0, a, b)[4] + EPS]
        self._reach = RowMap(ca.Function("locked_search_reach_cells", [T, q7, a, b], top), [0, 1], CHUNKS, inline=True)
        """The upper bound over a cell [a, b] of x of :meth:`reach` + :data:`~qpik.analytic.trig.EPS` (its Taylor
        model's), which bounds every branch's validity: compiled, over rows of cells."""
        q, rows = ca.vertsplit(ca.SX.sym("q", 7)), []
        moved = p if gap is None else sy.vsub(p, gap.expr(self.own.frames_expr(q, sy.CASADI)))  # q exact there
        for signs in self.signs:
            _, v_b, trig_b = self.error(R, moved, q7, q[self.variable], (float(signs[0]), float(signs[1])), sy.CASADI)
            pairs = [(trig_b[j], q[j]) for j in self.decided]
            turns = [ca.atan2(sn * ca.cos(o) - c * ca.sin(o), c * ca.cos(o) + sn * ca.sin(o)) for (c, sn), o in pairs]
            rows += [ca.mmax(ca.fabs(ca.vertcat(*turns))), v_b]
        fn = ca.Function("locked_search_branches", [T, q7, ca.vertcat(*q)], [ca.vertcat(*rows)])
        self._branches = RowMap(fn, shared=[0, 1])
        """Per row of a solution q (7,; rad, the search's order): for each branch b, the largest difference (modulo
        2π) of its subproblems' joints (:attr:`decided`) at q's x from q's, and its validity (2B,), on the ideal chain
        at the pose where q is an exact solution of it (a near member's pose moved by the chains' gap at q,
        :meth:`~qpik.robots.locked_joint.ChainGap.expr`); compiled, over rows of solutions (the pose and the locked
        angle shared; :meth:`branch_of`)."""
        _, _, trig = self.error(R, p, q7, x, (sign[0], sign[1]), sy.CASADI)
        joints, residual = [ca.atan2(s, c) for c, s in trig] + [q7], None
        for _ in range(POLISH):
            joints, residual = polish(self.own, R, p, joints, sy.CASADI)
        self._polished = RowMap(ca.Function("locked_search_polish", [T, q7, x, sign],
                                            [ca.vertcat(*joints), residual]), shared=[0, 1])  # fmt: skip
        """The solution of a candidate: its joints by the subproblems (:meth:`error`) at the candidate's x and signs,
        then :data:`POLISH` rounds of :func:`~qpik.analytic.polish.polish`; compiled, over rows of candidates (the
        pose and the locked angle shared)."""

    @property
    def variable_joint(self) -> int:
        """The search variable's joint in the arm's order (0-based)."""
        return 6 - self.variable if self.reversed else self.variable

    @abstractmethod
    def reach(self, R: Mat, p: Vec, q7: Scalar, x: Scalar, ops: Ops) -> Scalar:
        """A function of x (rad; the search's pose ``(R, p)`` and locked angle ``q7``) that bounds the validity
        :math:`v_b` of every branch (less :data:`~qpik.analytic.trig.EPS`): where it is negative no branch has
        its subproblems' roots."""

    @abstractmethod
    def error(
        self, R: Mat, p: Vec, q7: Scalar, x: Scalar, signs: tuple[Scalar, Scalar], ops: Ops
    ) -> tuple[Scalar, Scalar, list[tuple[Scalar, Scalar]]]:
        """The error function :math:`e_b(x)` and validity :math:`v_b(x)` of the branch of ``signs`` (a row of
        :attr:`signs`) at the search's pose ``(R, p)`` (the arm's :math:`T^{-1}` where :attr:`reversed`) and locked
        angle ``q7`` (rad), and the (cos, sin) of joints 1-6 in the search's order (meaningful at a root)."""

    def solve(self, T: np.ndarray, param: float, rounds: int = ROUNDS) -> SearchSolutions:
        """Every IK solution of the pose ``T`` (4, 4; the arm's base frame) with the locked joint at ``param`` (rad);
        ``rounds``: the search's budget (:data:`ROUNDS`).

        Raises:
            InputError: ``T`` is not one pose (:func:`~qpik.core.validate.single_pose`) or ``param`` not a finite
                number.
        """
        T = single_pose(T, "T")
        param = number(param, "param", minimum=None)
        Ts = np.linalg.inv(T) if self.reversed else T
        found, branch, left = self._isolate(Ts, param, rounds)
        proved = not left and self.exact
        none = SearchSolutions(np.zeros((0, 7)), np.zeros(0, int), np.zeros(0), proved, np.zeros(0, bool))
        if not found.size:
            return none
        q, residual = self._polished(Ts.reshape(-1, order="F"), np.array([param]), found, self.signs[branch])
        ok = residual[:, 0] <= RESIDUAL_TOL
        if not ok.any():
            return none
        q, residual = sy.NUMPY.wrap(q[ok]), residual[ok, 0]
        branch, validity = self.branch_of(Ts, param, q)  # the polish may take a candidate of one b to another's root
        double = validity - EPS <= DOUBLE
        order = np.lexsort((residual, branch))  # the smaller b first, then the smaller residual
        q, branch, residual, double = q[order], branch[order], residual[order], double[order]
        left, keep = np.ones(len(q), bool), []
        while left.any():  # the first left is kept, and those within SAME of it are not
            keep.append(i := int(np.argmax(left)))
            left &= apart(q, q[i]) > SAME
        if len(keep) < len(q):  # the same root of two error functions where the nearest kept before it is of another b
            kept, dropped = np.array(keep), np.ones(len(q), bool)
            dropped[kept] = False
            dropped = np.flatnonzero(dropped)
            gap = np.where(kept < dropped[:, None], apart(q[dropped, None], q[kept]), np.inf)
            j = kept[np.argmin(gap, axis=1)]
            double[j[branch[j] != branch[dropped]]] = True
        if len(keep) <= MOST:  # more is a continuum, each of whose solutions reaches the pose: kept as they are
            keep = self._valleys(Ts, q, branch, keep, double)
        keep = sorted(keep, key=order.__getitem__)  # in the candidates' order
        q = q[keep]
        return SearchSolutions(q[:, ::-1] if self.reversed else q, branch[keep], residual[keep], proved,
                               double[keep])  # fmt: skip

    def _valleys(
        self, Ts: np.ndarray, q: np.ndarray, branch: np.ndarray, keep: list[int], double: np.ndarray
    ) -> list[int]:
        """``keep`` (indices of solutions ``q`` (K, 7), rad, the search's order, of the pose ``Ts``) less each solution
        whose midpoint with one kept before it, of the same error function ``branch`` and within :data:`VALLEY`,
        reaches the pose to :data:`~qpik.analytic.polish.RESIDUAL_TOL` by the chain's FK; that one is marked
        ``double`` (changed in place). Near a double root of :math:`e_b` (a fold) the residual is flat along one
        direction and Newton stalls anywhere in that valley: candidates polished from several windows stop at points
        more than :data:`SAME` apart, where no FK at the tolerance tells them apart."""
        out: list[int] = []
        for i in keep:
            for j in out:
                if branch[j] == branch[i] and apart(q[i], q[j]) < VALLEY:
                    mid = q[j] + 0.5 * sy.NUMPY.wrap(q[i] - q[j])
                    if np.abs(self.own.fk(mid)[:3] - Ts[:3]).max() <= RESIDUAL_TOL:
                        double[j] = True
                        break
            else:
                out.append(i)
        return out

    def branch_of(self, Ts: np.ndarray, q7: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The error function b (K,) of solutions ``q`` (K, 7; rad, the search's order) of the search's pose ``Ts``
        (4, 4) at the locked angle ``q7`` (rad), and its validity :math:`v_b` (K,) there: the b whose subproblems at
        each solution's x give the joints (:attr:`decided`) nearest to its own (largest difference, modulo 2π; on a near
        member's ideal chain at the pose where the solution is exact: :attr:`_branches`). Where another valid b's joints
        are as near, to :data:`TIE`, or the solution is at a double root of a subproblem (:data:`DOUBLE`) where another
        b's joints are within :data:`PARTNER` and its validity is that small too (the two roots' b give the same joints
        to round-off, and either may be the nearer), the smallest such b: so that a solution's b does not change with
        the round-off of the pose."""
        (out,) = self._branches(Ts.reshape(-1, order="F"), np.array([q7]), q)
        diff, validity = out[:, 0::2], out[:, 1::2] - EPS
        rows = np.arange(len(q))
        best = np.argmin(diff, axis=1)
        small = validity <= DOUBLE
        tie = (diff <= diff[rows, best, None] + TIE) & (validity >= 0.0)
        tie |= small & small[rows, best, None] & (diff <= PARTNER)
        tie[rows, best] = True
        b = np.argmax(tie, axis=1)
        return b, out[rows, 2 * b + 1]

    def _isolate(self, Ts: np.ndarray, q7: float, rounds: int) -> tuple[np.ndarray, np.ndarray, bool]:
        """The candidates (centres of windows of roots, rad; each once), their branches (in increasing order of branch
        and candidate), and whether cells were left when the budget ran out."""
        edges = np.linspace(-np.pi, np.pi, CELLS + 1)
        Tf, angle = Ts.reshape(-1, order="F"), np.array([q7])
        (top,) = self._reach(Tf, angle, edges[:-1], edges[1:])
        near = ~(top[:, 0] < -SLACK)  # not surely out of reach for every branch
        B = len(self.signs)
        cells = np.empty((int(near.sum()), B, 3))  # rows (a, b, branch), each cell for every branch
        cells[..., 0], cells[..., 1], cells[..., 2] = edges[:-1][near, None], edges[1:][near, None], np.arange(B)
        cells = cells.reshape(-1, 3)
        ends = np.linspace(0.0, 1.0, SPLIT + 1)  # a window's parts: [x1 + (x2 − x1) ends[j], ... ends[j + 1]]
        found, which = [], []
        for _ in range(rounds):
            if not len(cells) or len(cells) > MAX_CELLS:
                break
            (out,) = self._step(Tf, angle, cells)
            order = np.argsort(out[:, 3], kind="stable")  # by fate: GONE, DONE, TOUCHED, NARROW, HALVE
            out, cells = out[order], cells[order]
            gone, done, touched, narrow = np.searchsorted(out[:, 3], (DONE, TOUCHED, NARROW, HALVE)).tolist()  # ends
            if touched > gone:
                x1, x2, k, _, best = out[gone:touched].T
                if self.exact:  # a window's centre, a touched cell's ends
                    found += [0.5 * (x1 + x2)[: done - gone], cells[done:touched, 0], cells[done:touched, 1]]
                    which += [k[: done - gone], k[done - gone :], k[done - gone :]]
                else:  # the ideal chain's roots and near-roots: where the file's may be
                    found += [best, x1, x2]
                    which += [k] * 3
            wide = out[narrow:]
            cells = np.empty((narrow - touched + SPLIT * len(wide), 3))
            cells[: narrow - touched] = out[touched:narrow, :3]
            parts = cells[narrow - touched :].reshape(-1, SPLIT, 3)
            cut = wide[:, :1] + (wide[:, 1:2] - wide[:, :1]) * ends
            cut[:, -1] = wide[:, 1]  # the window's end itself: the parts cover it
            parts[..., 0], parts[..., 1], parts[..., 2] = cut[:, :-1], cut[:, 1:], wide[:, 2:3]
        if len(cells):  # the budget ran out: the cells left are candidates too
            found += [0.5 * (cells[:, 0] + cells[:, 1])]
            which += [cells[:, 2]]
        x, k = (np.concatenate(v) if v else np.zeros(0) for v in (found, which))
        order = np.lexsort((x, k))  # by branch and x: the same candidate twice (an end of two cells) polished once
        x, k = x[order], k[order]
        once = np.ones(len(x), bool)
        once[1:] = (np.diff(x) != 0) | (np.diff(k) != 0)
        return x[once], k[once].astype(int), bool(len(cells))
