r"""The geometries of the 1-D search of :mod:`qpik.analytic.locked_search`, and :func:`search_for`, which picks one.

Both read the arm in the search's order (q7 locked; the arm's q1 where it is read from the flange) and end alike:
with the notation of :mod:`qpik.analytic.locked_joint` (:math:`G = T M^{-1} e_7^{-1} = e_1 \cdots e_6`, W where axes
5 and 6 meet), once joints 1-4 are known, what is left, :math:`R(h_5, q_5) R(h_6, q_6) = R_4^T R_G`
(:math:`R_4 = R(h_1,q_1)\cdots R(h_4, q_4)`), exists iff axis 6 turned by it keeps its angle to axis 5: the **error
function**

.. math:: e_b(x) = (R_4 h_5)\cdot(R_G h_6) - h_5\cdot h_6
   = \big(R(h_3, q_3) R(h_4, q_4) h_5\big)\cdot\big(R(h_2, q_2)^T R(h_1, q_1)^T R_G h_6\big) - h_5\cdot h_6,

evaluated in the second form: a Taylor model's remainder grows with every rotation nested inside another, and the
rotations split between the two sides halve the depth (fewer cells to isolate the roots);
and q5, q6 then follow by subproblem 1 (:meth:`WristSearch.wrist`). They differ in how joints 1-4 follow from the
search variable x, by a subproblem 3 and a subproblem 2 (Elias & Wen 2022), each of two roots: branch
:math:`b = 2\,[\sigma_{\text{3}} < 0] + [\sigma_{\text{2}} < 0]` (4 error functions of x), valid where both
discriminants are :math:`\ge 0` (the validity :math:`v_b(x)`, as :mod:`qpik.analytic.locked_joint`'s).

:class:`ShoulderSearch` (Baxter, the Flexiv Rizons): axes 1 and 2 meet in S, axis 3 misses it (the locked-q7
geometry of :mod:`qpik.analytic.locked_joint` but for axis 3, :func:`~qpik.robots.locked_joint.find_locked_joint` with
``shoulder=2``; read from the flange, the Sawyer's axis 3 passes 136.3 mm from S); x = q4:

- :math:`|e_3 e_4 W - S| = |G W - S|`: q3 by subproblem 3 on the point :math:`e_4(x) W` about axis 3 (sign
  :math:`\sigma_3`; :func:`~qpik.analytic.subproblems.line_root`, no angle formed);
- :math:`R(h_1, q_1) R(h_2, q_2)\,u = G W - S`, :math:`u = e_3 e_4 W - S`: q1, q2 by subproblem 2 (sign
  :math:`\sigma_{12}`) and subproblem 1 (:func:`~qpik.analytic.subproblems.turn_between`: no square root, whose
  Taylor model widens fast where its argument nears 0).

:class:`ElbowSearch` (robosuite's Sawyer, whose axes 7-6 miss each other by 0.8 µm): axes 3 and 4 meet in C, axes 5
and 6 in W; x = q1. Joints 5 and 6 fix W and joints 3 and 4 fix C, so with :math:`P = e_1(x)^{-1} G W`:

- :math:`|e_2 C - P| = |C - W|`: q2 by subproblem 3 on the point C about axis 2 (sign :math:`\sigma_2`);
- :math:`R(h_3, q_3) R(h_4, q_4)\,(W - C) = e_2^{-1} P - C`: q3, q4 by subproblem 2 about C (sign
  :math:`\sigma_{34}`) and subproblem 1.

:func:`search_for` tries :class:`ShoulderSearch` on the arm's own axes, then :class:`ElbowSearch`, then
:class:`ShoulderSearch` as a near member (:func:`qpik.robots.recognize.recognize` in the same order).
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.locked_search import LockedSearch
from qpik.analytic.subproblems import constant, rotate, rotation, subproblem1, subproblem2, subproblem3, turn_between
from qpik.analytic.trig import EPS
from qpik.core.errors import NoClosedFormError
from qpik.robots.chain import SerialChain
from qpik.robots.elbow_search import ElbowSearchGeometry, find_elbow_search
from qpik.robots.locked_joint import ChainGap, LockedJointGeometry, find_locked_joint, ideal_chain, reversed_chain


class WristSearch(LockedSearch):
    """What both geometries share: the pose's G and W, and the wrist's error function (module docstring).

    Args:
        own, reversed, gap, near: as :class:`~qpik.analytic.locked_search.LockedSearch`'s.
        geometry: its axes at q = 0 (``h``, unit, and ``o``, a point on each; search's order), the point W where axes
            5 and 6 meet (``wrist``, m) and the end-effector pose at q = 0 (``home``).
    """

    def __init__(
        self,
        own: SerialChain,
        reversed: bool,
        gap: ChainGap | None,
        near: str,
        geometry: LockedJointGeometry | ElbowSearchGeometry,
    ):
        h, o, wrist, home = geometry.h, geometry.o, geometry.wrist, geometry.home
        self.h = [constant(x) for x in h]
        Rm, pm = home[:3, :3], home[:3, 3]
        self.k7, self.c7, self.w7 = constant(Rm.T @ h[6]), constant(Rm.T @ (o[6] - pm)), constant(Rm.T @ (wrist - o[6]))
        self.Rm_t = tuple(constant(r) for r in Rm.T)
        a = np.cross(h[4], h[5])
        self.a6 = constant(a / np.linalg.norm(a))  # a unit vector ⊥ h6 for q6's subproblem 1
        self.h56 = float(h[4] @ h[5])
        super().__init__(own, reversed, gap, near)

    def reach(self, R: Mat, p: Vec, q7: Scalar, x: Scalar, ops: Ops) -> Scalar:
        """The relative discriminant of the first subproblem (subproblem 3) at ``x`` (rad; the pose and locked angle as
        :meth:`error`'s): where it is negative no branch has its roots."""
        return self.joints(self.target(R, p, q7, ops)[1], x, (1.0, 1.0), ops)[1]

    def error(
        self, R: Mat, p: Vec, q7: Scalar, x: Scalar, signs: tuple[Scalar, Scalar], ops: Ops
    ) -> tuple[Scalar, Scalar, list[tuple[Scalar, Scalar]]]:
        """The error function, validity and joints 1-6 of the branch of ``signs`` (the roots of its subproblems 3 and
        2) at ``x`` (rad) (:meth:`~qpik.analytic.locked_search.LockedSearch.error`)."""
        RG, GW = self.target(R, p, q7, ops)
        trig, first, second = self.joints(GW, x, signs, ops)
        e, trig = self.wrist(RG, trig, ops)
        return e, ops.fmin(first, second) + EPS, trig

    @abstractmethod
    def joints(
        self, GW: Vec, x: Scalar, signs: tuple[Scalar, Scalar], ops: Ops
    ) -> tuple[list[tuple[Scalar, Scalar]], Scalar, Scalar]:
        """The (cos, sin) of joints 1-4 of the branch of ``signs`` at ``x`` (rad) for the point G W (m, base frame;
        :meth:`target`), and the relative discriminants of its subproblems 3 and 2 (module docstring)."""

    def target(self, R: Mat, p: Vec, q7: Scalar, ops: Ops) -> tuple[Mat, Vec]:
        """:math:`R_G` and G W at the search's pose ``(R, p)`` and locked angle ``q7`` (rad)."""
        c7, s7 = ops.cos(q7), ops.sin(q7)
        RG = sy.matmul(R, sy.matmul(rotation(self.k7, c7, sy.neg(s7)), self.Rm_t))
        GW = sy.vadd(sy.matvec(R, sy.vadd(self.c7, rotate(self.k7, c7, sy.neg(s7), self.w7))), p)
        return RG, GW

    def wrist(self, RG: Mat, trig: list[tuple[Scalar, Scalar]], ops: Ops) -> tuple[Scalar, list[tuple[Scalar, Scalar]]]:
        """The error function from :math:`R_G` and the (cos, sin) of joints 1-4, and the (cos, sin) of q5, q6
        (subproblem 1; meaningful at a root)."""
        h = self.h
        (c1, s1), (c2, s2), (c3, s3), (c4, s4) = trig

        def upper(y: Vec) -> Vec:
            """R(h2, q2)^T R(h1, q1)^T y."""
            return rotate(h[1], c2, sy.neg(s2), rotate(h[0], c1, sy.neg(s1), y))

        def back(y: Vec) -> Vec:
            """R_4^T y."""
            return rotate(h[3], c4, sy.neg(s4), rotate(h[2], c3, sy.neg(s3), upper(y)))

        h6 = sy.matvec(RG, h[5])
        e = sy.dot(rotate(h[2], c3, s3, rotate(h[3], c4, s4, h[4])), upper(h6)) - self.h56
        _, c5, s5 = subproblem1(h[4], h[5], back(h6), ops)
        end = rotate(h[4], c5, sy.neg(s5), back(sy.matvec(RG, self.a6)))
        _, c6, s6 = subproblem1(h[5], self.a6, end, ops)
        return e, [*trig, (c5, s5), (c6, s6)]


class ShoulderSearch(WristSearch):
    """The search over q4 of the module docstring's first geometry (branches ``(σ3, σ12)``).

    Args:
        chain: the arm's chain (7 revolute joints).
        directions: the directions tried, in order: True reads the chain from the flange (q1 locked), False forwards
            (q7 locked).
        near: a near member may be searched (on its ideal chain, :mod:`qpik.analytic.locked_search`).

    Raises:
        NoClosedFormError: the geometry does not apply in any of the directions (the reasons in the message).
    """

    variable = 3
    decided = (0, 1, 2)

    def __init__(self, chain: SerialChain, directions: tuple[bool, ...] = (True, False), near: bool = True):
        reasons = []
        for rev in directions:
            turned = reversed_chain(chain) if rev else chain
            table, misses = turned, ""
            g, why = find_locked_joint(turned, reversed=rev, shoulder=2)
            if g is None and near:
                table, misses = ideal_chain(turned, rev, shoulder=2)
                g, why = (None, misses) if table is None else find_locked_joint(table, reversed=rev, shoulder=2)
            if g is not None:
                break
            reasons.append(f"q{1 if rev else 7} locked: {why}")
        else:
            raise NoClosedFormError("the search over q4: " + "; ".join(reasons))
        self.o3, self.S = constant(g.o[2]), constant(g.shoulder)
        self.o4, self.w4 = constant(g.o[3]), constant(g.wrist - g.o[3])
        gap = ChainGap.between(turned, table) if misses else None
        super().__init__(turned, rev, gap, misses, g)

    def joints(
        self, GW: Vec, x: Scalar, signs: tuple[Scalar, Scalar], ops: Ops
    ) -> tuple[list[tuple[Scalar, Scalar]], Scalar, Scalar]:
        """:meth:`WristSearch.joints` of this geometry (module docstring)."""
        h = self.h
        v = sy.vsub(GW, self.S)
        c4, s4 = ops.cos(x), ops.sin(x)
        pp = sy.vsub(sy.vadd(self.o4, rotate(h[3], c4, s4, self.w4)), self.o3)  # e4 W − o3
        qq = sy.vsub(self.S, self.o3)
        c3, s3, m3 = subproblem3(h[2], pp, qq, sy.dot(v, v), signs[0], ops)
        u = sy.vsub(sy.vadd(self.o3, rotate(h[2], c3, s3, pp)), self.S)
        (w,), m12, _ = subproblem2(h[1], u, h[0], v, ops, (signs[1],))
        c2, s2 = turn_between(h[1], u, w, ops)
        c1, s1 = turn_between(h[0], w, v, ops)
        return [(c1, s1), (c2, s2), (c3, s3), (c4, s4)], m3, m12


class ElbowSearch(WristSearch):
    """The search over q1 of the module docstring's second geometry (branches ``(σ2, σ34)``; exact members only).

    Args:
        chain: the arm's chain (7 revolute joints).
        directions: the directions tried, in order: True reads the chain from the flange (q1 locked), False forwards
            (q7 locked).

    Raises:
        NoClosedFormError: the geometry does not apply in any of the directions (the reasons in the message).
    """

    variable = 0
    decided = (1, 2, 3)

    def __init__(self, chain: SerialChain, directions: tuple[bool, ...] = (True, False)):
        reasons = []
        for rev in directions:
            turned = reversed_chain(chain) if rev else chain
            g, why = find_elbow_search(turned, rev)
            if g is not None:
                break
            reasons.append(f"q{1 if rev else 7} locked: {why}")
        else:
            raise NoClosedFormError("the search over the first joint: " + "; ".join(reasons))
        self.o1, self.o2, self.C = constant(g.o[0]), constant(g.o[1]), constant(g.elbow)
        self.arm = constant(g.wrist - g.elbow)  # W − C
        self.reach2 = float((g.wrist - g.elbow) @ (g.wrist - g.elbow))  # |W − C|²
        super().__init__(turned, rev, None, "", g)

    def joints(
        self, GW: Vec, x: Scalar, signs: tuple[Scalar, Scalar], ops: Ops
    ) -> tuple[list[tuple[Scalar, Scalar]], Scalar, Scalar]:
        """:meth:`WristSearch.joints` of this geometry (module docstring)."""
        h = self.h
        c1, s1 = ops.cos(x), ops.sin(x)
        qq = sy.vsub(sy.vadd(self.o1, rotate(h[0], c1, sy.neg(s1), sy.vsub(GW, self.o1))), self.o2)  # P − o2
        pp = sy.vsub(self.C, self.o2)
        c2, s2, m2 = subproblem3(h[1], pp, qq, self.reach2, signs[0], ops)
        target = sy.vsub(sy.vadd(self.o2, rotate(h[1], c2, sy.neg(s2), qq)), self.C)  # e2⁻¹ P − C
        (w,), m34, _ = subproblem2(h[3], self.arm, h[2], target, ops, (signs[1],))
        c4, s4 = turn_between(h[3], self.arm, w, ops)
        c3, s3 = turn_between(h[2], w, target, ops)
        return [(c1, s1), (c2, s2), (c3, s3), (c4, s4)], m2, m34


def search_for(chain: SerialChain, directions: tuple[bool, ...] = (True, False)) -> LockedSearch:
    """The 1-D search of ``chain`` (7 revolute joints): :class:`ShoulderSearch` on the arm's own axes, else
    :class:`ElbowSearch`, else :class:`ShoulderSearch` as a near member, each in ``directions`` (True: read from the
    flange, q1 locked; False: forwards, q7 locked; tried in order).

    Raises:
        NoClosedFormError: no geometry fits (the reasons of each in the message).
    """
    reasons = []
    for make in (lambda: ShoulderSearch(chain, directions, near=False), lambda: ElbowSearch(chain, directions),
                 lambda: ShoulderSearch(chain, directions)):  # fmt: skip
        try:
            return make()
        except NoClosedFormError as err:
            reasons.append(str(err))
    raise NoClosedFormError("no 1-D search applies: " + "; ".join(reasons[1:]))
