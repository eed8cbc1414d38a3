r"""Closed-form IK of a 7-R arm with q7 locked (Franka Panda, xArm7): 8 branches in the parameter q7.

He & Liu 2021 and Tittel 2021 solve the Panda with q7 given; this module writes that solution once for any
chain of the geometry of :mod:`qpik.robots.locked_joint` (axes 1-2-3 meet in the shoulder point S, axes 5-6
in the wrist point W), in the product-of-exponentials form and the subproblems of Elias & Wen 2022
(IK-Geo): with the axes :math:`h_i` through :math:`o_i` at q = 0 (base frame) and the home pose M,

.. math:: T = e_1 e_2 \cdots e_7 M,\qquad e_i = \exp(\hat\xi_i q_i),\qquad
          G := e_1 \cdots e_6 = T M^{-1} e_7^{-1} \quad\text{(known once q7 is given).}

**Elbow q4 (subproblem 3).** :math:`e_5 e_6` fix W and :math:`e_1 e_2 e_3` fix S, so
:math:`|e_4 W - S| = |G W - S| =: D`. With :math:`w = W - o_4`, :math:`s = S - o_4`:
:math:`a\cos q_4 + b\sin q_4 = c`, :math:`a = s\cdot w - (h_4\cdot s)(h_4\cdot w)`,
:math:`b = s\cdot(h_4\times w)` (constants of the arm), :math:`c = (|w|^2 + |s|^2 - D^2)/2 - (h_4\cdot s)(h_4\cdot w)`;
:math:`q_4 = \varphi \pm \mathrm{atan2}(\sqrt{r^2 - c^2}, c)`, :math:`\varphi = \mathrm{atan2}(b, a)`,
:math:`r^2 = a^2 + b^2`, with :math:`r^2 - c^2 = (r - c)(r + c)`, evaluated as
:math:`(\varphi \pm \pi/2) + \mathrm{atan2}(\mp c, \sqrt{r^2 - c^2})`, whose vector stays off atan2's cut where the
elbow stretches or folds (:math:`c = \pm r`).

**Wrist q5, q6 (subproblem 2).** :math:`e_5 e_6 (G^{-1} S) = e_4^{-1} S`, about W:
:math:`R(h_5, q_5) R(h_6, q_6)\,x = y`, :math:`x = R_G^T (S - G W)`, :math:`y = R(h_4, -q_4)\,s - (W - o_4)`.
The common vector :math:`v = R(h_6, q_6) x = R(h_5, -q_5) y` is :math:`v = \alpha h_6 + \beta h_5 + \gamma\,(h_6
\times h_5)` (:func:`~qpik.analytic.subproblems.subproblem2`), two signs of γ; q6 and q5 then follow by subproblem 1
(:func:`~qpik.analytic.subproblems.subproblem1`).

**Shoulder q1, q2, q3 (subproblems 2 and 1).** :math:`R(h_1,q_1) R(h_2,q_2) R(h_3,q_3) = R_H :=
R_G R(h_6,-q_6) R(h_5,-q_5) R(h_4,-q_4)`: subproblem 2 on :math:`R(h_2,q_2) h_3 = R(h_1,-q_1) R_H h_3`
(two signs), then q3 by subproblem 1 on a unit vector :math:`a \perp h_3`.

**Branches** (public ids 0-7; 2 elbows × 2 wrists × 2 shoulders)::

    branch = 4·shoulder + 2·elbow + wrist

- *elbow* = 1 where :math:`\sin(q_4 - \varphi) < 0` (the root :math:`\varphi - \mathrm{atan2}(\cdot)`), 0 for the
  other root; the two meet where the elbow is stretched or folded;
- *wrist* = 1 where :math:`(h_6 \times h_5)\cdot R(h_5, -q_5)\,y(q_4) < 0` (γ < 0 in the wrist's subproblem 2):
  the shoulder point S lies on the negative side of the plane of axes 5 and 6 (normal :math:`z_6 \times z_5`);
- *shoulder* = 1 where :math:`(h_2 \times h_1)\cdot R(h_2, q_2)\,h_3 < 0` (γ < 0 in the shoulder's
  subproblem 2): axis 3 on the negative side of the plane of axes 1 and 2.

On the Panda (the catalog's table and the Panda files of example-robot-data and pybullet, whose axes point the
same way): φ = 2.6746 rad, so *elbow* = 1 iff q4 > φ − π = −0.4670 rad (the elbow bent less than where the
shoulder-wrist distance is largest; Franka's q4 range is [−3.0718, −0.0698]); *shoulder* = 1 iff q2 < 0;
*wrist* = 1 iff :math:`\cos q_5 > 0` (:math:`|q_5| < \pi/2`) for every q4 in (−π, 0), Franka's range (there S lies on
one side of the forearm axis; the side changes at q4 = 0 and 2.6308 rad).

The parameter is q7 itself: :meth:`LockedJointSolver.table_parameter_expr` returns it with the bits above.

**Singular cases** (defined results, ``singular`` set, every valid branch still reaches the pose):

- *elbow stretched or folded*: :math:`r^2 - c^2 <` ``BRANCH_TOL`` :math:`r^2`: the two elbow roots coincide;
- *wrist* or *shoulder* subproblem 2 with :math:`\gamma^2 <` ``BRANCH_TOL`` :math:`|x|^2`: its two roots
  coincide; where the vector to turn lies on the axis (S on axis 6, or axes 1 and 3 aligned) that joint is
  free: subproblem 1 returns ``atan2`` of what is left (any value reaches the pose) and the next joint takes
  the rest.

**Near members** (a file whose axes miss the geometry by at most
:data:`~qpik.robots.locked_joint.NEAR_TOL`, :func:`~qpik.robots.locked_joint.ideal_chain`): the branches above are
those of the ideal chain (:attr:`~LockedJointSolver.table`), each then polished by Newton on the file's chain
(:mod:`qpik.analytic.polish`) and valid where the polish reaches the pose; :meth:`~LockedJointSolver.validity` and
:meth:`~LockedJointSolver.joint_trig` stay the ideal chain's. The ideal chain differs from the file's only in the
translations of its joint frames, so its end's rotation is the file's at every q and its position differs by
:math:`\Delta(q)` (:class:`~qpik.robots.locked_joint.ChainGap`, at most D = its ``bound``): a file's solution q is
the ideal chain's at the pose moved by :math:`-\Delta(q)`, a fixed point. Near a singular Jacobian of the six joints
it lies far from the ideal chain's solution at the pose itself (about D over the smallest singular value, beyond
Newton's reach), so each branch first takes rounds of that map (the ideal chain's branch of the same signs at
:math:`p - \Delta(q)`), then twice as many Newton steps of the polish (:func:`correction_rounds`: more for a larger
D).

An unreachable pose gives ``valid = 0`` (a negative discriminant beyond round-off, ``EPS`` relative); the square
roots are clamped at 0, so q stays finite.

**Read from the flange** (:class:`~qpik.analytic.locked_joint_reversed.ReversedLockedJointSolver`; the Kinova Gen3): an
arm whose axes 7-6-5 meet and whose axes 3-2 meet is of this geometry read backwards
(:func:`~qpik.robots.locked_joint.reversed_chain`: joint k is the arm's joint 8 − k at the same angle, FK inverted;
``robot.canonical.reversed``, its ``table`` that chain). Its solver is this one on that chain
(:attr:`~qpik.analytic.locked_joint_reversed.ReversedLockedJointSolver.inner`, a robot with the limits reversed) at
:math:`T^{-1}`, the rows reversed: the parameter is the arm's q1 (``param_name`` ``"q1"``), the branch ids are the inner
solver's (*shoulder* the arm's wrist 7-6-5, *wrist* its axes 3-2), and the feasible sets are the inner solver's
(:mod:`qpik.analytic.locked_joint_intervals` unchanged, its limits and levels those of the reversed robot, its q7 the
arm's q1). :func:`~qpik.analytic.locked_joint_reversed.locked_joint_solver` picks the solver of a robot.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.polish import RESIDUAL_TOL, polish
from qpik.analytic.set_ends import refine_ends, resample
from qpik.analytic.solver import AnalyticSolver, Branches
from qpik.analytic.subproblems import (
    BOTH,
    BRANCH_TOL,
    Signs,
    constant,
    plane_vector,
    rotate,
    rotation,
    subproblem2,
    unit,
)
from qpik.analytic.trig import EPS
from qpik.core.errors import NoClosedFormError
from qpik.robots.locked_joint import ChainGap, find_locked_joint
from qpik.robots.robot import Robot

if TYPE_CHECKING:
    from qpik.analytic.intervals import FeasibleIntervals, ParameterSets

SCALE = 0.1
"""m per rad: the singular value of the six joints' position Jacobian that :func:`correction_rounds` sizes the rounds
for (smaller ones, near a singular configuration, get the same rounds, which then remove less)."""
MAX_ROUNDS = 8
"""The most rounds :func:`correction_rounds` gives."""
THIN = 2.0
r"""A near member's branch is sampled on the file's chain (:func:`qpik.analytic.set_ends.resample`) where its ideal
chain's validity lies within :math:`(\text{THIN}\,D/\text{SCALE})^2` of 0 (:attr:`LockedJointSolver.thin`): a
validity is a relative discriminant, the square of an angle of order D/:data:`SCALE` where two solutions of a
subproblem are that close, so that the file's chain, D away, may have none there, or have two where the ideal chain
has none (a fold of the file's chain the ideal one misses; the polish starts from the ideal chain's branch clamped
at its double root, and may reach the file's)."""
SPACING = 1.0 / 16.0
"""The samples of a thin stretch of a near member's branch are :data:`SPACING` D/:data:`SCALE` rad apart."""


def correction_rounds(deviation: float) -> int:
    r"""Rounds of the correction of a near member's branch for the bound D = ``deviation`` (m) of the difference
    :math:`\Delta(q)` of the two chains' end positions (module docstring); its polish then takes twice as many Newton
    steps. Each round takes the ideal chain's branch at the pose moved by :math:`-\Delta(q)` at the last round's q: a
    contraction by about :math:`\kappa = D/\sigma`, :math:`\sigma` the smallest singular value of the six joints'
    position Jacobian, from a start about D/σ away. The fewest k ≥ 1 with :math:`D\kappa^k \le` ``RESIDUAL_TOL`` at
    σ = :data:`SCALE` (at most :data:`MAX_ROUNDS`). Near a singular configuration (σ ≪ :data:`SCALE`) the rounds
    contract less and Newton converges only linearly (about halving the error per step), hence the polish's 2k."""
    if deviation <= RESIDUAL_TOL:
        return 1
    kappa = deviation / SCALE
    if kappa >= 1.0:
        return MAX_ROUNDS
    return int(min(MAX_ROUNDS, max(1, math.ceil(math.log(RESIDUAL_TOL / deviation) / math.log(kappa)))))


SIGNS = np.array([[1 - 2 * (k >> bit & 1) for bit in (2, 1, 0)] for k in range(8)], float)
"""Per branch id ``4·shoulder + 2·elbow + wrist``, the signs of its shoulder's, elbow's and wrist's roots (8, 3)
(:data:`BranchSigns`)."""
BranchSigns = tuple[Signs, Signs, Signs]
"""The signs of the shoulder's, the elbow's and the wrist's roots (:data:`~qpik.analytic.subproblems.Signs`): the
branches ``(4·shoulder + 2·elbow + wrist)`` of every combination, numbered in that order; one sign each is one
branch."""
ALL: BranchSigns = (BOTH, BOTH, BOTH)
"""The 8 branches, ids 0-7."""


class LockedJointSolver(AnalyticSolver):
    """Closed-form IK with q7 locked; see the module docstring. Branch ids 0-7:
    ``4·shoulder + 2·elbow + wrist``."""

    kind = "locked_joint"
    param_name = "q7"
    branch_ids = tuple(range(8))
    closed_form_sets = False  # the sets are isolated by Taylor models (qpik.analytic.locked_joint_intervals)
    branch_signs = SIGNS

    def __init__(
        self, robot: Robot, sets: Callable[[AnalyticSolver], ParameterSets] | None = None, param_name: str = "q7"
    ):
        super().__init__(robot, sets)
        self.param_name = param_name
        """The parameter's name: q7, or q1 where this solver serves a
        :class:`~qpik.analytic.locked_joint_reversed.ReversedLockedJointSolver`."""
        g, why = find_locked_joint(self.table)
        if g is None:
            raise NoClosedFormError(f"the locked-q7 closed form does not apply: {why}")
        self.geometry = g
        canonical = robot.canonical
        self.polished = None if canonical is None or canonical.exact else robot.chain
        """The chain the branches are polished on (:mod:`qpik.analytic.polish`): the robot's own, where
        :attr:`table` is its nearest ideal chain (a near member, :func:`qpik.robots.locked_joint.ideal_chain`)."""
        self.gap = None if self.polished is None else ChainGap.between(self.polished, self.table)
        """A near member's :class:`~qpik.robots.locked_joint.ChainGap` of its chain over :attr:`table`."""
        self.thin = None if self.gap is None else (THIN * self.gap.bound / SCALE) ** 2
        """A near member's validity below which its branch is sampled on its own chain (:data:`THIN`); None for an
        exact member."""
        self._refined: tuple[FeasibleIntervals, FeasibleIntervals] | None = None
        """A near member's last sets (:meth:`feasible_intervals`): as given, and with their ends moved."""
        h, o, S, W = g.h, g.o, g.shoulder, g.wrist
        self.h = [constant(x) for x in h]
        Rm, pm = g.home[:3, :3], g.home[:3, 3]
        self.k7 = constant(Rm.T @ h[6])  # axis 7 in the home flange frame
        self.c7 = constant(Rm.T @ (o[6] - pm))
        self.w7 = constant(Rm.T @ (W - o[6]))
        self.Rm_t = tuple(constant(r) for r in Rm.T)  # M's rotation, transposed
        self.S = constant(S)
        w, s = W - o[3], S - o[3]
        self.s4, self.w4 = constant(s), constant(w)
        hw, hs = float(h[3] @ w), float(h[3] @ s)
        self.a4 = float(s @ w - hs * hw)
        self.b4 = float(s @ np.cross(h[3], w))
        self.k4 = 0.5 * float(w @ w + s @ s) - hs * hw
        self.r4 = float(np.hypot(self.a4, self.b4))
        self.phi = float(np.arctan2(self.b4, self.a4))
        """φ (rad): the elbow roots are φ ± atan2(√(r²−c²), c)."""
        a = np.cross(h[1], h[2])
        self.a3 = constant(a / np.linalg.norm(a))  # a unit vector ⊥ h3 for q3's subproblem 1

    def table_branches(self, R: Mat, p: Vec, param: Scalar, ops: Ops) -> Branches:
        """All 8 branches at q7 = ``param`` (rad) for the pose ``(R, p)`` (base frame); for a near member
        (:attr:`polished`), each polished on the robot's chain and valid where the polish reaches the pose
        (:data:`~qpik.analytic.polish.RESIDUAL_TOL`), whatever the ideal chain's discriminants say
        (:meth:`_corrected`)."""
        br = self._solve(R, p, param, ops)[0]
        if self.polished is None:
            return br
        signs = [tuple((float(x),) for x in row) for row in SIGNS]
        rows = [self._corrected(R, p, param, row, signs[k], ops) for k, row in enumerate(br.q)]
        return Branches([q for q, _ in rows], [valid for _, valid in rows], br.singular)

    def one_branch(self, R: Mat, p: Vec, param: Scalar, signs: list[Scalar], ops: Ops) -> Branches | None:
        """A near member's (:attr:`polished`) branch of the roots ``signs`` (shoulder, elbow, wrist: ±1, or symbols)
        at q7 = ``param`` (rad) for the pose ``(R, p)``, in the robot's angles: the row of :meth:`table_branches`
        of those signs (:meth:`~qpik.analytic.solver.AnalyticSolver.one_branch`); None for an exact member, whose
        branches share most of their work."""
        if self.polished is None:
            return None
        sg = tuple((x,) for x in signs)
        br = self._solve(R, p, param, ops, sg)[0]
        q, valid = self._corrected(R, p, param, br.q[0], sg, ops)
        return Branches([self.robot_row(q, ops)], [valid], br.singular)

    def _corrected(
        self, R: Mat, p: Vec, param: Scalar, row: list[Scalar], signs: BranchSigns, ops: Ops
    ) -> tuple[list[Scalar], Scalar]:
        """A near member's branch of ``signs`` (one sign each) on the robot's chain from the ideal chain's ``row``
        (module docstring): its joints (wrapped but q7) and whether the polish reaches the pose."""
        rounds = correction_rounds(self.gap.bound)
        for _ in range(rounds):  # the fixed point of q -> the ideal chain's branch at p - Δ(q)
            moved = sy.vsub(p, self.gap.expr(self.polished.frames_expr(row, ops)))
            row = self._solve(R, moved, param, ops, signs)[0].q[0]
        qk, residual = polish(self.polished, R, p, row, ops, 2 * rounds)
        return [ops.wrap(x) for x in qk[:6]] + qk[6:], residual <= RESIDUAL_TOL

    def feasible_intervals(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """The sets of :meth:`~qpik.analytic.branch_solver.BranchSolver.feasible_intervals`; a near member's
        (:attr:`polished`) with their ends moved onto its own chain (:func:`qpik.analytic.set_ends.refine_ends`, about
        D/:data:`SCALE` rad away: the joints' change by the correction, over joint rates of order 1), then sampled on
        its chain where the ideal chain's validity is within :attr:`thin` of 0 (:func:`qpik.analytic.set_ends.resample`,
        :data:`SPACING`)."""
        fi = super().feasible_intervals(T, margin)
        if self.polished is None:
            return fi
        if self._refined is None or self._refined[0] is not fi:  # the sets keep their last answer: so does this
            angle = self.gap.bound / SCALE
            moved = refine_ends(fi, self, T, margin, angle)
            self._refined = (fi, resample(moved, self, T, margin, self._sets.thin(T, margin), SPACING * angle))
        return self._refined[1]

    @property
    def sets_proved(self) -> bool:
        """Whether :meth:`feasible_intervals` can be proved: not for a near member (:attr:`polished`; module
        docstring of :mod:`qpik.analytic.locked_joint_intervals`)."""
        return self.polished is None and super().sets_proved

    def validity(self, R: Mat, p: Vec, param: Scalar, ops: Ops, signs: BranchSigns = ALL) -> list[Scalar]:
        r"""Per branch, a continuous function of the pose and q7 whose sign is the branch's ``valid`` flag:
        :math:`\min(\text{elbow}, \text{wrist}, \text{shoulder}) + ` EPS, each subproblem's discriminant relative to
        its scale (:func:`~qpik.analytic.subproblems.subproblem2`; the elbow's :math:`(r^2 - c^2)/r^2`), clamped
        nowhere. For the feasible sets (:mod:`qpik.analytic.locked_joint_intervals`), whose validity changes are its
        roots. ``signs``: the branches (:data:`ALL`: 0-7)."""
        return [m + EPS for m in self._solve(R, p, param, ops, signs)[1]]

    def arm_validity(self, R: Mat, p: Vec, param: Scalar, ops: Ops, elbows: Signs = BOTH) -> list[Scalar]:
        """Per elbow sign of ``elbows``, :meth:`validity` without the shoulder's discriminant: min(elbow, wrist) +
        EPS, at least the validity of each of the elbow's four branches (where it is below 0, so are theirs)."""
        return [m + EPS for m in self._solve(R, p, param, ops, ((1.0,), elbows, (1.0,)))[4]]

    def joint_trig(
        self, R: Mat, p: Vec, param: Scalar, ops: Ops, signs: BranchSigns = ALL, scaled: bool = False
    ) -> list[list[tuple[Scalar, Scalar]]]:
        r"""Per branch, :math:`(\cos q_j, \sin q_j)` of the robot's joints 1-6 at q7 = ``param`` (rad) for the pose
        ``(R, p)`` (base frame): the unit vectors the subproblems return
        (:func:`~qpik.analytic.subproblems.subproblem1`), not functions of the angles, so continuous wherever the joint
        is not free (no cut at ±π); through the joint map :math:`q = s\,(q^{DH} - c)`
        (:class:`~qpik.analytic.solver.AnalyticSolver`): :math:`\cos q = \cos(q^{DH} - c)`,
        :math:`\sin q = s \sin(q^{DH} - c)`. A representative :math:`q + 2\pi k` has the same pair. ``signs``: the
        branches (:data:`ALL`: 0-7). ``scaled``: the pairs :math:`\rho_j (\cos q_j, \sin q_j)` instead, the vectors
        of :func:`~qpik.analytic.subproblems.plane_vector` before their division by :math:`\rho_j \ge 0` (m² for q5,
        q6, 1 for q4, unitless for q1-q3; 0 where the joint is free), of the same signs and roots of
        :math:`\sin(q_j - L)`, and smoother; q3's from the other end of the shoulder,
        :math:`R(h_3, q_3)\,R_H^T h_1 = R(h_2, -q_2)\,h_1` (subproblem 2, its γ of the opposite sign:
        :math:`(h_2\times h_3)\cdot R(h_2,-q_2) h_1 = -(h_2\times h_1)\cdot R(h_2,q_2) h_3`), which needs neither q1
        nor q2."""
        out = self._solve(R, p, param, ops, signs, scaled)[3 if scaled else 2]
        if self.joint_map is None:
            return out
        turned = []
        for row in out:
            pairs = []
            for (c, s), sign, shift in zip(row, self.joint_map.sign, self.joint_map.shift):
                cc, sc = float(np.cos(shift)), float(np.sin(shift))
                pairs.append((sy.lin((c, cc), (s, sc)), sy.mul(float(sign), sy.lin((s, cc), (c, -sc)))))
            turned.append(pairs)
        return turned

    def _solve(
        self, R: Mat, p: Vec, param: Scalar, ops: Ops, signs: BranchSigns = ALL, scaled: bool = False
    ) -> tuple[Branches, list[Scalar], list[list], list[list], list[Scalar]]:
        """The branches of ``signs`` (:data:`BranchSigns`), their validity measures (:meth:`validity` without the
        EPS), the cosines and sines of their joints 1-6 in the table's angles (:meth:`joint_trig`) and, with
        ``scaled``, those pairs before their normalisation (:meth:`joint_trig`'s ``scaled``; else None); per elbow
        sign, the least of the elbow's and the wrist's measures (:meth:`arm_validity`)."""
        shoulders, elbows, wrists = signs
        h = self.h
        c7, s7 = ops.cos(param), ops.sin(param)
        back7 = rotation(self.k7, c7, sy.neg(s7))  # R(k7, −q7)
        RG = sy.matmul(R, sy.matmul(back7, self.Rm_t))  # rotation of G = T M⁻¹ e7⁻¹
        GW = sy.vadd(sy.matvec(R, sy.vadd(self.c7, rotate(self.k7, c7, sy.neg(s7), self.w7))), p)
        d = sy.vsub(self.S, GW)
        x = sy.matvec(sy.transpose(RG), d)
        # elbow: a cos q4 + b sin q4 = c
        cc = self.k4 - 0.5 * sy.dot(d, d)
        r = self.r4
        disc = (r - cc) * (r + cc)
        sb = ops.safe_sqrt(disc)
        rho = ops.sqrt(cc * cc + sb * sb)  # r where the elbow reaches, |c| > r where not: never 0
        cb, sb = cc / rho, sb / rho
        cp, sp = float(np.cos(self.phi)), float(np.sin(self.phi))
        m4 = disc / (r * r)
        close4 = m4 < BRANCH_TOL
        n = len(shoulders) * len(elbows) * len(wrists)
        q, valid, singular, measure, trig, vectors = ([None] * n for _ in range(6))
        arm: list[Scalar] = []
        for e, sign in enumerate(elbows):
            # φ ± atan2(√(r²−c²), c) as (φ ± π/2) + atan2(∓c, √(r²−c²)): that vector never lies on atan2's cut (its x
            # is ≥ 0, and y = ∓c ≠ 0 where x = 0), so its Taylor model stays continuous where the elbow stretches or
            # folds (the angle tags of :mod:`qpik.algebra.angle_tags` follow an atan2 plus a constant)
            q4 = ops.wrap(self.phi + sign * 0.5 * np.pi + ops.atan2(-sign * cb, sb))
            c4, s4 = cp * cb - sp * (sign * sb), sp * cb + cp * (sign * sb)
            y = sy.vsub(rotate(h[3], c4, sy.neg(s4), self.s4), self.w4)
            v_w = subproblem2(h[5], x, h[4], y, ops, wrists)
            arm.append(ops.fmin(m4, v_w[1]))
            for w, v in enumerate(v_w[0]):
                v6, v5 = plane_vector(h[5], x, v), plane_vector(h[4], v, y)
                (q6, c6, s6), (q5, c5, s5) = unit(*v6, ops), unit(*v5, ops)

                def back(u: Vec, c4=c4, s4=s4, c5=c5, s5=s5, c6=c6, s6=s6) -> Vec:
                    """R_H u = R_G R(h6, −q6) R(h5, −q5) R(h4, −q4) u."""
                    u = rotate(h[3], c4, sy.neg(s4), u)
                    u = rotate(h[4], c5, sy.neg(s5), u)
                    return sy.matvec(RG, rotate(h[5], c6, sy.neg(s6), u))

                t, ta = back(h[2]), back(self.a3)
                v_s = subproblem2(h[1], h[2], h[0], t, ops, shoulders)
                if scaled:  # R(h3, q3) R_H^T h1 = R(h2, −q2) h1: q3 by subproblem 2 without q1, q2 (γ of opposite sign)
                    u = sy.matvec(sy.transpose(RG), h[0])
                    u = rotate(h[3], c4, s4, rotate(h[4], c5, s5, rotate(h[5], c6, s6, u)))
                    v_3 = subproblem2(h[1], h[0], h[2], u, ops, tuple(-x for x in shoulders))[0]
                for s, vs in enumerate(v_s[0]):
                    v2, v1 = plane_vector(h[1], h[2], vs), plane_vector(h[0], vs, t)
                    (q2, c2, s2), (q1, c1, s1) = unit(*v2, ops), unit(*v1, ops)
                    b = rotate(h[1], c2, sy.neg(s2), rotate(h[0], c1, sy.neg(s1), ta))
                    v3 = plane_vector(h[2], self.a3, b)
                    q3, c3, s3 = unit(*v3, ops)
                    k = (s * len(elbows) + e) * len(wrists) + w
                    q[k] = [q1, q2, q3, q4, q5, q6, ops.wrap(param)]
                    trig[k] = [(c1, s1), (c2, s2), (c3, s3), (c4, s4), (c5, s5), (c6, s6)]
                    if scaled:
                        vectors[k] = [v1, v2, plane_vector(h[2], u, v_3[s]), (c4, s4), v5, v6]
                    measure[k] = ops.fmin(ops.fmin(m4, v_w[1]), v_s[1])
                    valid[k] = measure[k] >= -EPS
                    singular[k] = ops.fmax(ops.fmax(close4, v_w[2]), v_s[2])
        return Branches(q, valid, singular), measure, trig, vectors, arm

    def table_parameter_expr(self, q: list[Scalar], ops: Ops) -> tuple[Scalar, Scalar]:
        """q7 (rad) and the branch id ``4·shoulder + 2·elbow + wrist`` of the configuration ``q`` (7 scalars)."""
        h = self.h
        c4, s4 = ops.cos(q[3]), ops.sin(q[3])
        elbow = ops.where(self.a4 * s4 - self.b4 * c4 < 0, 2.0, 0.0)
        y = sy.vsub(rotate(h[3], c4, sy.neg(s4), self.s4), self.w4)
        v = rotate(h[4], ops.cos(q[4]), sy.neg(ops.sin(q[4])), y)
        wrist = ops.where(sy.dot(sy.cross(h[5], h[4]), v) < 0, 1.0, 0.0)
        vs = rotate(h[1], ops.cos(q[1]), ops.sin(q[1]), h[2])
        shoulder = ops.where(sy.dot(sy.cross(h[1], h[0]), vs) < 0, 4.0, 0.0)
        return q[6], shoulder + elbow + wrist
