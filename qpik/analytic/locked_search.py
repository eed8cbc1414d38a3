r"""IK of a 7-R arm with one joint locked by a certified 1-D search (Elias & Wen 2022, IK-Geo): the Rethink Sawyer.

The Sawyer's consecutive axes meet except axes 1-2 (81 mm apart), and no three meet in one point: with any joint
locked the 6-R chain left has no closed form. Read from the flange (:func:`~qpik.robots.locked_joint.reversed_chain`,
joint k the arm's joint 8 − k, pose :math:`T^{-1}`) with its last joint (the arm's q1) locked, it is the locked-q7
geometry of :mod:`qpik.analytic.locked_joint` but for axis 3, which misses the point S where axes 1 and 2 meet
(:func:`~qpik.robots.locked_joint.find_locked_joint` with ``shoulder=2``; the Sawyer: 136.3 mm). With the
notation of that module (:math:`G = T M^{-1} e_7^{-1} = e_1 \cdots e_6`, W where axes 5 and 6 meet), for the search
variable :math:`x = q_4`:

- :math:`|e_3 e_4 W - S| = |G W - S| = D`: q3 by subproblem 3 on the point :math:`P = e_4(x) W` about axis 3
  (two roots, sign :math:`\sigma_3`; :math:`a\cos q_3 + b\sin q_3 = c`, :math:`\cos q_3 = (ac - \sigma_3 b\sqrt{r^2 -
  c^2})/r^2`, :math:`\sin q_3 = (bc + \sigma_3 a\sqrt{r^2-c^2})/r^2`, no angle formed);
- :math:`R(h_1, q_1) R(h_2, q_2)\,u = v`, :math:`u = e_3 P - S`, :math:`v = G W - S`: q1, q2 by subproblem 2
  (sign :math:`\sigma_{12}`) and subproblem 1 (:func:`~qpik.analytic.subproblems.turn_between`: no square root,
  whose Taylor model widens fast where its argument nears 0);
- what is left, :math:`R(h_5, q_5) R(h_6, q_6) = R_4^T R_G` (:math:`R_4 = R(h_1,q_1)\cdots R(h_4, x)`), exists iff
  axis 6 turned by it keeps its angle to axis 5: the **error function**

  .. math:: e_b(x) = (R_4 h_5)\cdot(R_G h_6) - h_5\cdot h_6,

  one per branch :math:`b = 2\,[\sigma_3 < 0] + [\sigma_{12} < 0]` (4 functions of x), valid where both
  discriminants are :math:`\ge 0` (the validity :math:`v_b(x)`, as :mod:`qpik.analytic.locked_joint`'s). Each root
  of :math:`e_b` where :math:`v_b \ge 0` is an IK solution; q5 and q6 then follow by subproblem 1.

**Every root.** :math:`e_b` and :math:`v_b` are written once against :mod:`qpik.algebra.symbolic`; their first-order
Taylor models over cells of x (:func:`qpik.algebra.enclosure.taylor_function`, compiled and mapped over rows of cells
and branches, :class:`~qpik.native.compiled.RowMap`) isolate the roots as :mod:`qpik.analytic.locked_joint_intervals`
does (Moore 1966; Makino & Berz 2003): from :data:`CELLS` cells over the circle, less those where the Taylor model of
q3's relative discriminant (:meth:`LockedSearch.reach`, a bound of every branch's validity) is below 0 (no branch has a
q3 there: the elbow cannot reach the wrist; most of the circle), a cell is discarded where the model's window
:math:`|f_0 + f_1 t| \le r +` :data:`~qpik.analytic.search_step.SLACK` is empty or the bounds exclude 0 or the branch's
validity is below 0 over the cell, replaced by that window where it is at most half as wide, else by the window cut in
:data:`SPLIT` equal parts; a window narrower than :data:`~qpik.analytic.search_step.WINDOW` holds a root (its centre),
and so do the ends of a cell where :math:`|e_b|` stays within :data:`~qpik.analytic.search_step.TOUCH` of 0 (a double
root, where the window stays the whole cell however often it is cut: such a cell is a few µm wide when it is touched).
Every root of every :math:`e_b` is then within :data:`~qpik.analytic.search_step.WINDOW` of a candidate, or inside a
touched cell whose ends are candidates, unless the search ran out of its budget (:data:`ROUNDS`, :data:`MAX_CELLS`;
``proved`` False). Where the validity vanishes inside a window the square roots of the subproblems have no slope and
the cell is cut down to :data:`~qpik.analytic.search_step.WINDOW` like any other.

**Machine precision.** The joints of each candidate (each once: two cells may end at one point; q5, q6 by subproblem
1 on the rotation left) start :data:`POLISH` rounds of Newton on the arm's own chain, the locked joint held
(:func:`qpik.analytic.polish.polish`, compiled and mapped over the candidates); a candidate is a solution where the
residual is at most :data:`~qpik.analytic.polish.RESIDUAL_TOL`, and solutions within :data:`SAME` rad of each other are
one.

**Near members.** A file whose axes miss the geometry by at most :data:`~qpik.robots.locked_joint.NEAR_TOL` (the
Sawyer's axes 6-7: 0.8 µm) is searched on its nearest ideal chain (:func:`~qpik.robots.locked_joint.ideal_chain`), the
candidates then polished on the file's: ``proved`` is then False. The ideal chain's rotations are the file's at every q
and its end's position at most :attr:`LockedSearch.deviation` D away (:class:`~qpik.robots.locked_joint.ChainGap`), so
the file's roots are the roots of the ideal chain's :math:`e_b` at a pose whose position is at most D away: within
:math:`D\,|\nabla_p e_b|_1` of 0 on the ideal chain, to first order. Near a fold of :math:`e_b` (a double root) the
file's chain may have two roots where the ideal chain's :math:`e_b` only nears 0, or none where it has two. So the
search keeps every cell where :math:`|e_b|` may be within that bound (times
:data:`~qpik.analytic.search_step.NEAR_GAIN`, the gradient at the cell's centre) of 0, its slack and touch, and a
window of :data:`~qpik.analytic.search_step.NEAR_WINDOW` ends the cell: its candidates are the root of the window's
linear model and the window's two ends (a touched cell's likewise), each polished on the file's chain, which decides (a
candidate whose polish does not reach the pose is dropped).

**Behind** :func:`qpik.ik`: :mod:`qpik.analytic.search_solver` puts the solutions in 16 slots with identities along
the parameter.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.enclosure import DONE, HALVE, NARROW, TOUCHED, taylor_function
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.intervals import apart
from qpik.analytic.polish import RESIDUAL_TOL, polish
from qpik.analytic.search_step import SIGNS, SLACK, step_function
from qpik.analytic.subproblems import constant, rotate, rotation, subproblem1, subproblem2, turn_between
from qpik.analytic.trig import EPS
from qpik.core.errors import NoClosedFormError
from qpik.core.validate import number, single_pose
from qpik.native.compiled import RowMap
from qpik.robots.chain import SerialChain
from qpik.robots.locked_joint import ChainGap, find_locked_joint, ideal_chain, reversed_chain

CELLS = 192
"""Cells of x = q4 over the circle at the start of the search."""
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
"""rad: joints 1-3 of two error functions' subproblems this much nearer to a solution are as near
(:meth:`LockedSearch.branch_of`)."""
PARTNER = 1e-3
"""rad: at a double root of a subproblem, the joints 1-3 of the two roots' b are this close
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


class LockedSearch:
    """The certified 1-D search of a chain of the module docstring's geometry; see there.

    Args:
        chain: the arm's chain (7 revolute joints).
        directions: the directions tried, in order: True reads the chain from the flange (q1 locked), False forwards
            (q7 locked).

    Raises:
        NoClosedFormError: the geometry does not apply in any of the directions (the reasons in the message).
    """

    def __init__(self, chain: SerialChain, directions: tuple[bool, ...] = (True, False)):
        reasons = []
        for rev in directions:
            turned = reversed_chain(chain) if rev else chain
            table, near = turned, ""
            geometry, why = find_locked_joint(turned, reversed=rev, shoulder=2)
            if geometry is None:
                table, near = ideal_chain(turned, rev, shoulder=2)
                geometry, why = (None, near) if table is None else find_locked_joint(table, reversed=rev, shoulder=2)
            if geometry is not None:
                break
            reasons.append(f"q{1 if rev else 7} locked: {why}")
        else:
            raise NoClosedFormError("no 1-D search applies: " + "; ".join(reasons))
        self.reversed, self.exact, self.near = rev, not near, near
        self.locked = 1 if rev else 7
        """The arm's locked joint (1-based): the parameter."""
        self.own = turned
        """The arm's chain in the search's order (reversed where :attr:`reversed`): the polish's."""
        g = geometry
        h, o, S, W = g.h, g.o, g.shoulder, g.wrist
        self.h = [constant(x) for x in h]
        self.o3, self.S = constant(o[2]), constant(S)
        self.o4, self.w4 = constant(o[3]), constant(W - o[3])
        Rm, pm = g.home[:3, :3], g.home[:3, 3]
        self.k7, self.c7, self.w7 = constant(Rm.T @ h[6]), constant(Rm.T @ (o[6] - pm)), constant(Rm.T @ (W - o[6]))
        self.Rm_t = tuple(constant(r) for r in Rm.T)
        a = np.cross(h[4], h[5])
        self.a6 = constant(a / np.linalg.norm(a))  # a unit vector ⊥ h6 for q6's subproblem 1
        self.h56 = float(h[4] @ h[5])
        T, q7, x, sign = ca.SX.sym("T", 4, 4), ca.SX.sym("q7"), ca.SX.sym("x"), ca.SX.sym("sign", 2)
        R, p = sy.frame_of_batch(T)
        e, valid, _ = self.error(R, p, q7, x, (sign[0], sign[1]), sy.CASADI)
        model = taylor_function(ca.Function("locked_search", [T, q7, x, sign], [ca.vertcat(e, valid)]), [2])
        gap = None if self.exact else ChainGap.between(turned, table)
        self.deviation = 0.0 if gap is None else gap.bound
        """m: a bound of the change of the end's position between the file's chain and the ideal one the search runs
        on, at every q (0 for an exact member; :attr:`~qpik.robots.locked_joint.ChainGap.bound`)."""
        gain = None
        if not self.exact:  # |∂e_b/∂p|_1: the file's roots are those of the ideal chain's e_b at a pose D away
            grad = ca.jacobian(e, ca.vertcat(T[0, 3], T[1, 3], T[2, 3]))
            gain = ca.Function("locked_search_gain", [T, q7, x, sign], [ca.sum2(ca.fabs(grad))])
        self._step = RowMap(step_function(model, gain, self.deviation), shared=[0, 1], chunks=CHUNKS, inline=True)
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
        for s3, s12 in SIGNS:
            _, v_b, trig_b = self.error(R, moved, q7, q[3], (s3, s12), sy.CASADI)
            turns = [ca.atan2(sn * ca.cos(o) - c * ca.sin(o), c * ca.cos(o) + sn * ca.sin(o))
                     for (c, sn), o in zip(trig_b[:3], q[:3])]  # fmt: skip
            rows += [ca.mmax(ca.fabs(ca.vertcat(*turns))), v_b]
        fn = ca.Function("locked_search_branches", [T, q7, ca.vertcat(*q)], [ca.vertcat(*rows)])
        self._branches = RowMap(fn, shared=[0, 1])
        """Per row of a solution q (7,; rad, the search's order): for each branch b, the largest difference (modulo
        2π) of its subproblems' joints 1-3 at q's x = q4 from q's, and its validity (8,), on the ideal chain at the
        pose where q is an exact solution of it (a near member's pose moved by the chains' gap at q,
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

    def _elbow(
        self, R: Mat, p: Vec, q7: Scalar, x: Scalar, ops: Ops
    ) -> tuple[Mat, Vec, tuple[Scalar, Scalar], Vec, tuple[Scalar, Scalar, Scalar]]:
        r"""At the search's pose ``(R, p)``, locked angle ``q7`` and ``x`` (rad): :math:`R_G`, :math:`v = GW - S`,
        (cos x, sin x), :math:`P - o_3`, and q3's subproblem 3 :math:`a\cos q_3 + b\sin q_3 = c` as (a, b, c) (module
        docstring)."""
        h = self.h
        c7, s7 = ops.cos(q7), ops.sin(q7)
        RG = sy.matmul(R, sy.matmul(rotation(self.k7, c7, sy.neg(s7)), self.Rm_t))
        GW = sy.vadd(sy.matvec(R, sy.vadd(self.c7, rotate(self.k7, c7, sy.neg(s7), self.w7))), p)
        v = sy.vsub(GW, self.S)
        c4, s4 = ops.cos(x), ops.sin(x)
        P = sy.vadd(self.o4, rotate(h[3], c4, s4, self.w4))
        pp, qq = sy.vsub(P, self.o3), sy.vsub(self.S, self.o3)
        k = h[2]
        kp, kq = sy.dot(k, pp), sy.dot(k, qq)
        a = sy.dot(pp, qq) - kp * kq
        b = sy.dot(qq, sy.cross(k, pp))
        c = 0.5 * (sy.dot(pp, pp) + sy.dot(qq, qq) - sy.dot(v, v)) - kp * kq
        return RG, v, (c4, s4), pp, (a, b, c)

    def reach(self, R: Mat, p: Vec, q7: Scalar, x: Scalar, ops: Ops) -> Scalar:
        """The relative discriminant :math:`(a^2 + b^2 - c^2)/(a^2 + b^2)` of q3's subproblem 3 at ``x`` (rad; the
        pose and locked angle as :meth:`error`'s): where it is negative no branch has a q3, and the validity
        :math:`v_b` of every branch is at most it + :data:`~qpik.analytic.trig.EPS`."""
        _, _, _, _, (a, b, c) = self._elbow(R, p, q7, x, ops)
        r2 = a * a + b * b
        return (r2 - c * c) * (1.0 / ops.fmax(r2, 1e-300))

    def error(
        self, R: Mat, p: Vec, q7: Scalar, x: Scalar, signs: tuple[Scalar, Scalar], ops: Ops
    ) -> tuple[Scalar, Scalar, list[tuple[Scalar, Scalar]]]:
        """The error function :math:`e_b(x)` and validity :math:`v_b(x)` of the branch of ``signs`` (σ3, σ12) at the
        search's pose ``(R, p)`` (the arm's :math:`T^{-1}` where :attr:`reversed`) and locked angle ``q7`` (rad), and
        the (cos, sin) of its joints 1-6 (q5 and q6 meaningful at a root only)."""
        h = self.h
        RG, v, (c4, s4), pp, (a, b, c) = self._elbow(R, p, q7, x, ops)
        k = h[2]
        r2 = a * a + b * b
        disc = r2 - c * c
        root = ops.safe_sqrt(disc)
        inv = 1.0 / ops.fmax(r2, 1e-300)
        c3 = (a * c - signs[0] * b * root) * inv
        s3 = (b * c + signs[0] * a * root) * inv
        u = sy.vsub(sy.vadd(self.o3, rotate(k, c3, s3, pp)), self.S)
        (w,), m12, _ = subproblem2(h[1], u, h[0], v, ops, (signs[1],))
        c2, s2 = turn_between(h[1], u, w, ops)
        c1, s1 = turn_between(h[0], w, v, ops)

        def turn(y: Vec) -> Vec:
            """R_4 y = R(h1, q1) R(h2, q2) R(h3, q3) R(h4, x) y."""
            y = rotate(h[3], c4, s4, y)
            return rotate(h[0], c1, s1, rotate(h[1], c2, s2, rotate(h[2], c3, s3, y)))

        h6 = sy.matvec(RG, h[5])
        e = sy.dot(turn(h[4]), h6) - self.h56
        valid = ops.fmin(disc * inv, m12) + EPS

        def back(y: Vec) -> Vec:
            """R_4^T y."""
            y = rotate(h[0], c1, sy.neg(s1), y)
            y = rotate(h[2], c3, sy.neg(s3), rotate(h[1], c2, sy.neg(s2), y))
            return rotate(h[3], c4, sy.neg(s4), y)

        _, c5, s5 = subproblem1(h[4], h[5], back(h6), ops)
        end = rotate(h[4], c5, sy.neg(s5), back(sy.matvec(RG, self.a6)))
        _, c6, s6 = subproblem1(h[5], self.a6, end, ops)
        return e, valid, [(c1, s1), (c2, s2), (c3, s3), (c4, s4), (c5, s5), (c6, s6)]

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
        q, residual = self._polished(Ts.reshape(-1, order="F"), np.array([param]), found, SIGNS[branch])
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
        each solution's q4 give the joints 1-3 nearest to its own (largest difference, modulo 2π; on a near member's
        ideal chain at the pose where the solution is exact: :attr:`_branches`). Where another valid b's joints are as
        near, to :data:`TIE`, or the solution is at a double root of a subproblem (:data:`DOUBLE`)
        where another b's joints are within :data:`PARTNER` and its validity is that small too (the two roots' b give
        the same joints to round-off, and either may be the nearer), the smallest such b: so that a solution's b does
        not change with the round-off of the pose."""
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
        B = len(SIGNS)
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
