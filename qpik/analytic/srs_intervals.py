r"""Exact feasible arm-angle sets of an S-R-S arm under joint limits (Shimizu et al. 2008).

For one pose every joint of a branch is a function of ψ built from
:math:`M(\psi) = A\sin\psi + B\cos\psi + C` (:mod:`qpik.analytic.srs`):

- tan-type (θ1, θ5: :math:`n = M_{12}, d = M_{02}`; θ3, θ7: :math:`n = M_{21}, d = -M_{20}`):
  :math:`\theta = \mathrm{atan2}(\sigma n, \sigma d)`. It equals a value L (or L ± π) iff
  :math:`n\cos L - d\sin L = 0`, i.e.

  .. math:: (a_n\cos L - a_d\sin L)\sin\psi + (b_n\cos L - b_d\sin L)\cos\psi + (c_n\cos L - c_d\sin L) = 0,

  solved by :func:`qpik.analytic.trig.solve_cos_sin`. Taking L = q_min, q_max
  gives every limit crossing; L = π gives the wraps through ±π, needed only for
  a joint whose limits reach ±π (otherwise the joint is outside its limits on
  both sides of a wrap, so a wrap changes nothing). For a loaded arm these levels
  are mapped to the table's angles (:meth:`~qpik.analytic.solver.AnalyticSolver.levels`). A singular
  point (n = d = 0, Shimizu et al. 2008: :math:`a_t^2 + b_t^2 = c_t^2`), where θ jumps by π,
  solves this equation for every L, so it is a root too.
- cos-type (θ2, θ6): :math:`\cos\theta = M_{22}(\psi)`; θ = ±L iff :math:`M_{22}(\psi) = \cos L`.
- θ4 does not depend on ψ. Where it lies outside the limits for both elbow signs, no ψ puts any branch inside
  them: the breakpoint function's ``valid`` is then 0 and every set empty, with no gap to classify
  (:meth:`PsiIntervals.fixed_joints_within`; at a margin above the elbow's this is the common case).

θ is continuous in ψ between consecutive roots and crosses no limit there, so
the roots are all the breakpoints: :class:`qpik.analytic.intervals.SetAssembler`
classifies each gap by one evaluation of every branch at its midpoint (the
compiled IK itself with its in-limits test); the breakpoints of all branches are pooled, since a breakpoint
that changes nothing only splits a gap. The equations are formed and solved, and the singular values
below found, in one compiled CasADi function of the pose (:meth:`PsiIntervals.expressions`).

**With a margin** m > 0 the limits are the shrunk ones, :math:`[l_j + m\rho_j,\ u_j - m\rho_j]`,
:math:`\rho_j = (u_j - l_j)/2` (:func:`qpik.analytic.intervals.shrunk_limits`): the sets are then the ψ where the
joint-limit margin :math:`\mu = \min_j \min(q_j - l_j, u_j - q_j)/\rho_j` (:class:`qpik.objectives.JointLimitMargin`)
is at least m. The equations above are the same with L the shrunk limits: a second compiled function takes them
as inputs (``q_min``, ``q_max``) and forms cos L and sin L symbolically (:meth:`PsiIntervals.shrunk_levels`), so
one compilation serves every margin; the gaps are classified by the IK's limit test with the same shrunk limits.
Its cos-type equations are not merged numerically (the levels are symbols), only where the two limits' cos L
agree at every margin (symmetric limits). Above m = 1 the shrunk limits are empty and so is every set.

With a C compiler the sets are one C call (:class:`~qpik.analytic.arm_sets.PsiSetsCall`: ``srs_intervals.c``,
compiled with ``intervals.c``): the breakpoint function and the classification of the gaps by the IK, which reads
the same pose and limit buffers, with no numpy in between (:meth:`PsiIntervals.native_sets` hands it to C code
that calls it in a loop); the singular values are then read from the breakpoint function's output. Without one,
the same steps run in numpy (the compiled breakpoint function, then the SetAssembler).

The singular values listed per branch are the ψ where :math:`|M_{22}| = 1` for
the shoulder or the wrist (θ2 or θ6 = 0 or π): the maximum :math:`c + \sqrt{a^2+b^2}`
of :math:`M_{22}` is at ψ = atan2(a, b), the minimum at atan2(−a, −b) (Shimizu et al. 2008,
:math:`\psi_0 = 2\arctan(a_t/(b_t - c_t))`), listed when within ``TOUCH_TOL``
of ±1 (:math:`|\sin\theta| \lesssim 1.5 \cdot 10^{-6}`). A joint that is singular for every ψ (stretched elbow
with the tool along the forearm) is flagged by ``ik`` and not listed here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, NamedTuple

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Scalar
from qpik.analytic import trig
from qpik.analytic.arm_sets import NONE, PsiSetsCall
from qpik.analytic.intervals import FeasibleIntervals, SetAssembler, shrunk_limits, wrap
from qpik.analytic.native_sets import NativeSets
from qpik.analytic.srs_geometry import arm_setup, branch_signs
from qpik.native.compiled import Compiled

if TYPE_CHECKING:
    from qpik.analytic.srs import SRSSolver

TOUCH_TOL = 1e-12
r""":math:`\bigl|1 - |M_{22}|\bigr|` at the extremum below which a shoulder/wrist singular ψ is reported."""
MIRRORED = 1e-14
""":math:`|s(l + u) + 2c|` (wrapped, rad) below which a joint's two limit levels have the same cosine at
every margin."""

_NO = (np.zeros(0), np.zeros(0))  # no singular ψ for either elbow sign
_ANGLE_JOINTS = ((0, 1, 2), (4, 5, 6))  # joints of the (shoulder, wrist) ZYZ triples (a, b, c)


def _pairs(levels: list[float]) -> list[tuple[float, float]]:
    """``(cos L, sin L)`` of the constant levels L (rad), as Python floats (a numpy float would take an SX operand)."""
    return [(float(np.cos(L)), float(np.sin(L))) for L in levels]


class JointLevels(NamedTuple):
    """The levels L (table angles) of one joint: ``(cos L, sin L)`` of each, for the tan-type equations, and the
    distinct values of cos L, for the cos-type one; floats, or CasADi SX of the shrunk limits."""

    pairs: list[tuple[Scalar, Scalar]]
    cosines: list[Scalar]


class PsiIntervals:
    """Feasible ψ intervals of every branch of one S-R-S solver; call with a (4, 4) pose and a margin."""

    proved = True

    def __init__(self, solver: SRSSolver):
        self._solver = solver
        self.branch = np.array(solver.branch_ids)
        self.levels = [solver.levels(j) for j in range(solver.robot.dof)]  # in the table's angles
        fixed = [JointLevels(_pairs(x), np.unique(np.cos(x)).tolist()) for x in self.levels]
        self._fixed = self._compile("srs_breakpoints", [], fixed)
        signs = np.array([branch_signs(k) for k in solver.branch_ids])
        self._i_elbow = signs[:, 1]

    @cached_property
    def _shrunk(self) -> _Breakpoints:
        """The breakpoint function of shrunk limits, ``(T, q_min (n,), q_max (n,))`` (rad, the robot's angles), its
        levels symbols (:meth:`shrunk_levels`): compiled on first use, once for every margin."""
        n = self._solver.robot.dof
        lo, hi = ca.SX.sym("q_min", n), ca.SX.sym("q_max", n)
        levels = [self.shrunk_levels(j, lo[j], hi[j]) for j in range(n)]
        return self._compile("srs_breakpoints_margin", [lo, hi], levels)

    @cached_property
    def _assemble(self) -> SetAssembler:
        """The gaps' classification of the path without the one C call."""
        return SetAssembler(self._solver, rows=len(self.branch))

    def _compile(self, name: str, inputs: list[ca.SX], levels: list[JointLevels]) -> _Breakpoints:
        """The breakpoint function ``name`` of the pose T (4, 4) and ``inputs`` (the symbols of ``levels``):
        ``(breaks, singular, valid)`` of :meth:`expressions`, and its one C call."""
        T = ca.SX.sym("T", 4, 4)
        robot = self._solver.robot
        limits = inputs or [ca.DM(robot.q_min), ca.DM(robot.q_max)]
        breaks, singular, valid = self.expressions(T, levels)
        out = [ca.vertcat(*breaks), ca.vertcat(*singular), valid * self.fixed_joints_within(T, *limits)]
        fn = Compiled(ca.Function(name, [T, *inputs], out))
        return _Breakpoints(fn, PsiSetsCall.build(fn, self._solver, len(self.branch)))

    def native_sets(self) -> NativeSets | None:
        """The sets under limits given at run time as one C call (the shrunk limits' function), None without a
        compiler."""
        native = self._shrunk.native
        return None if native is None else native.sets()

    def shrunk_levels(self, j: int, lo: ca.SX, hi: ca.SX) -> JointLevels:
        r"""The levels of joint j for its limits shrunk to ``[lo, hi]`` (rad, symbols; ``margin`` > 0).

        The limits mapped to the table's angles, :math:`L = s x + c`, as
        :meth:`~qpik.analytic.solver.AnalyticSolver.levels` maps constants (only cos L and sin L enter: no
        wrap). The wrap at π is no level: with a margin the shrunk limits of a joint within ±π stay off ±π,
        so the joint is outside them on both sides of the wrap. A joint whose limits reach past ±π also has the
        levels of its limits l, u themselves and of π (its representative :math:`q + 2\pi k` switches there, see
        :class:`~qpik.analytic.solver.AnalyticSolver`: with a range of 2π or more, from outside the shrunk limits
        to inside). The cos-type equation of the two limits is one when :math:`\cos L` of both is the same for every
        margin: :math:`s(l + u) + 2c \equiv 0` (mod 2π), as for symmetric limits.
        """
        robot, joint_map = self._solver.robot, self._solver.joint_map
        s, c = (1.0, 0.0) if joint_map is None else (float(joint_map.sign[j]), float(joint_map.shift[j]))
        angles = [s * x + c for x in (lo, hi)]
        pairs = [(ca.cos(L), ca.sin(L)) for L in angles]
        l, u = float(robot.q_min[j]), float(robot.q_max[j])
        mirrored = abs(float(wrap(s * (l + u) + 2.0 * c))) < MIRRORED
        cosines = [pairs[0][0]] if mirrored else [x for x, _ in pairs]
        if l < -np.pi or u > np.pi:
            fixed = [s * x + c for x in (l, u, np.pi)]
            pairs += _pairs(fixed)
            cosines += np.unique(np.cos(fixed)).tolist()
        return JointLevels(pairs, cosines)

    def fixed_joints_within(self, T: ca.SX, lo: ca.SX | ca.DM, hi: ca.SX | ca.DM) -> ca.SX:
        """1 where some branch has its joints that do not depend on ψ (θ4) inside ``[lo, hi]`` ((n,) rad), else 0:
        then no ψ puts any branch inside the limits and every set is empty, with no gap to classify (a margin above
        the elbow's, the common last call of :mod:`qpik.nlp.levelset`). The same expressions and test as the IK's."""
        psi = ca.SX.sym("psi")
        Q = self._solver.casadi_function(T, psi)[0][: len(self.branch), :]
        fixed = [j for j in range(Q.shape[1]) if not ca.depends_on(Q[:, j], psi)]
        alive = ca.SX(0.0)
        for r in range(Q.shape[0]):
            inside = ca.SX(1.0)
            for j in fixed:
                inside = inside * (Q[r, j] >= lo[j]) * (Q[r, j] <= hi[j])
            alive = ca.fmax(alive, inside)
        return alive if fixed else ca.SX(1.0)

    def expressions(self, T: ca.SX, levels: list[JointLevels]) -> tuple[list, list, ca.SX]:
        """For the pose T (4, 4) and the levels of every joint: the breakpoints (two per equation and elbow sign,
        0 where there is none: a breakpoint that is always there, harmless), the singular ψ (per elbow sign,
        two per joint group, ``NONE`` where there is none) and ``valid`` (the pose is reachable), as CasADi SX.
        The compiled function's ``valid`` is this times :meth:`fixed_joints_within`."""
        ops = sy.CASADI
        R, p = sy.frame_of_batch(T)
        setup = arm_setup(R, p, self._solver.geometry, ops)
        breaks, singular = [], []
        for e in range(2):
            groups = setup.coefficients(e)  # (shoulder, wrist), each (A, B, C): M = A sin ψ + B cos ψ + C
            for g, (ja, jb, jc) in enumerate(_ANGLE_JOINTS):
                A, B, C = groups[g]
                # tan-type: n cos L − d sin L = 0 for the levels L (limits, and π where a limit reaches it)
                eqs = []
                for j, (ni, nj), (di, dj), sign in ((ja, (1, 2), (0, 2), 1.0), (jc, (2, 1), (2, 0), -1.0)):
                    for cos_l, sin_l in levels[j].pairs:
                        cl, sl = cos_l, sy.mul(-sign, sin_l)
                        a, b, c = (sy.lin((cl, X[ni][nj]), (sl, X[di][dj])) for X in (A, B, C))
                        eqs.append((a, b, c, 0.0))
                # cos-type: M22 = cos L
                for cos_l in levels[jb].cosines:
                    eqs.append((A[2][2], B[2][2], C[2][2], cos_l))
                for a, b, c, rhs in eqs:  # a sin ψ + b cos ψ = rhs − c
                    plus, minus, ok = trig.solve_cos_sin(b, a, rhs - c, ops)
                    breaks += [ops.where(ok, ops.wrap(plus), 0.0), ops.where(ok, ops.wrap(minus), 0.0)]
                # M22 = a sin ψ + b cos ψ + c reaches ±1 at its extrema
                a, b, c = A[2][2], B[2][2], C[2][2]
                r = ops.sqrt(a * a + b * b)
                top = (ops.fabs(c + r - 1.0) < TOUCH_TOL) * (r > TOUCH_TOL)
                bottom = (ops.fabs(c - r + 1.0) < TOUCH_TOL) * (r > TOUCH_TOL)
                singular += [ops.where(top, ops.atan2(a, b), NONE), ops.where(bottom, ops.atan2(-a, -b), NONE)]
        return breaks, singular, setup.valid

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """The sets of the pose T (4, 4, world frame) with every joint in its limits shrunk by ``margin`` >= 0
        (:func:`~qpik.analytic.intervals.shrunk_limits`; 0: the limits themselves, above 1: every set empty)."""
        if margin == 0.0:
            fn, limits = self._fixed, None
        else:
            robot = self._solver.robot
            fn, limits = self._shrunk, shrunk_limits(robot.q_min, robot.q_max, margin)
        if fn.native is not None:
            intervals, singular, valid = fn.native(T, limits)
        else:
            breaks, singular, valid = fn.fn(T, *(() if limits is None else limits))
        n = len(self.branch)
        if valid[0] < 0.5:
            return FeasibleIntervals("psi", self.branch.copy(), [[] for _ in range(n)], [[] for _ in range(n)])
        sing = _singular(singular)
        if fn.native is None:  # the singular ψ are breakpoints too
            intervals, _ = self._assemble(T, np.concatenate([breaks, *sing]), _NO[0], limits)
        return FeasibleIntervals("psi", self.branch.copy(), intervals, [sing[e].tolist() for e in self._i_elbow])


def _singular(singular: np.ndarray) -> Sequence[np.ndarray]:
    """The singular ψ (rad, sorted, distinct) per elbow sign from the breakpoint function's output (8,) (``NONE``
    where one does not exist)."""
    found = singular != NONE  # rare: only at singular poses
    if not found.any():
        return _NO
    return [np.unique(x[f]) for x, f in zip(singular.reshape(2, -1), found.reshape(2, -1))]


@dataclass(frozen=True)
class _Breakpoints:
    """A compiled breakpoint function (of the pose, and of the limits for the shrunk limits') and its one C call
    (None without a compiler)."""

    fn: Compiled
    native: PsiSetsCall | None
