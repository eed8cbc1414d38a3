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
- θ4 does not depend on ψ.

θ is continuous in ψ between consecutive roots and crosses no limit there, so
the roots are all the breakpoints: :class:`qpik.analytic.intervals.Assembler`
classifies each gap by one evaluation of every branch at its midpoint (the
compiled IK itself with its in-limits test); the breakpoints of all branches are pooled, since a breakpoint
that changes nothing only splits a gap. The equations are formed and solved, and the singular values
below found, in one compiled CasADi function of the pose (:meth:`PsiIntervals.expressions`).

The singular values listed per branch are the ψ where :math:`|M_{22}| = 1` for
the shoulder or the wrist (θ2 or θ6 = 0 or π): the maximum :math:`c + \sqrt{a^2+b^2}`
of :math:`M_{22}` is at ψ = atan2(a, b), the minimum at atan2(−a, −b) (Shimizu et al. 2008,
:math:`\psi_0 = 2\arctan(a_t/(b_t - c_t))`), listed when within ``TOUCH_TOL``
of ±1 (|sin θ| ≲ 1.5e-6). A joint that is singular for every ψ (stretched elbow
with the tool along the forearm) is flagged by ``ik`` and not listed here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik import symbolic as sy
from qpik.analytic import trig
from qpik.analytic.intervals import Assembler, FeasibleIntervals
from qpik.analytic.srs import arm_setup, branch_signs
from qpik.compiled import Compiled

if TYPE_CHECKING:
    from qpik.analytic.srs import SRSSolver

TOUCH_TOL = 1e-12
"""|1 − |M22|| at the extremum below which a shoulder/wrist singular ψ is reported."""
NONE = 10.0
"""Stands for a singular ψ that does not exist in the compiled function's output (outside [−π, π])."""

_NO = (np.zeros(0), np.zeros(0))  # no singular ψ for either elbow sign
_ANGLE_JOINTS = ((0, 1, 2), (4, 5, 6))  # joints of the (shoulder, wrist) ZYZ triples (a, b, c)


class PsiIntervals:
    """Feasible ψ intervals of every branch of one S-R-S solver; call with a (4, 4) pose."""

    def __init__(self, solver: SRSSolver):
        self._solver = solver
        self.branch = np.array(solver.branch_ids)
        self.levels = [solver.levels(j) for j in range(solver.robot.dof)]  # in the table's angles
        T = ca.SX.sym("T", 4, 4)
        breaks, singular, valid = self.expressions(T)
        out = [ca.vertcat(*breaks), ca.vertcat(*singular), valid]
        self._fn = Compiled(ca.Function("srs_breakpoints", [T], out))
        signs = np.array([branch_signs(k) for k in solver.branch_ids])
        self._i_elbow = signs[:, 1]
        self._assemble = Assembler(solver, rows=len(self.branch))

    def expressions(self, T: ca.SX) -> tuple[list, list, ca.SX]:
        """For the pose T (4, 4): the breakpoints (two per equation and elbow sign, 0 where there is
        none: a breakpoint that is always there, harmless), the singular ψ (per elbow sign, two per joint
        group, ``NONE`` where there is none) and ``valid`` (the pose is reachable), as CasADi SX."""
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
                    for L in self.levels[j]:
                        cl, sl = float(np.cos(L)), float(-sign * np.sin(L))
                        a, b, c = (sy.lin((cl, X[ni][nj]), (sl, X[di][dj])) for X in (A, B, C))
                        eqs.append((a, b, c, 0.0))
                # cos-type: M22 = cos L
                for cos_l in np.unique(np.cos(self.levels[jb])):
                    eqs.append((A[2][2], B[2][2], C[2][2], float(cos_l)))
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

    def __call__(self, T: np.ndarray) -> FeasibleIntervals:
        breaks, singular, valid = self._fn(T)
        n = len(self.branch)
        if valid[0] < 0.5:
            return FeasibleIntervals("psi", self.branch.copy(), [[] for _ in range(n)], [[] for _ in range(n)])
        found = singular != NONE  # rare: only at singular poses
        sing = [np.unique(x[f]) for x, f in zip(singular.reshape(2, -1), found.reshape(2, -1))] if found.any() else _NO
        intervals, _ = self._assemble(T, np.concatenate([breaks, *sing]), _NO[0])
        return FeasibleIntervals("psi", self.branch.copy(), intervals, [sing[e].tolist() for e in self._i_elbow])
