r"""Exact feasible arm-angle sets of an S-R-S arm under joint limits (Shimizu 2008, seed 003).

For one pose every joint of a branch is a function of ψ built from
:math:`M(\psi) = A\sin\psi + B\cos\psi + C` (:mod:`qpik.analytic.srs`):

- tan-type (θ1, θ5: :math:`n = M_{12}, d = M_{02}`; θ3, θ7: :math:`n = M_{21}, d = -M_{20}`):
  :math:`\theta = \mathrm{atan2}(\sigma n, \sigma d)`. It equals a value L (or L ± π) iff
  :math:`n\cos L - d\sin L = 0`, i.e.

  .. math:: (a_n\cos L - a_d\sin L)\sin\psi + (b_n\cos L - b_d\sin L)\cos\psi + (c_n\cos L - c_d\sin L) = 0,

  solved by :func:`qpik.analytic.trig.solve_cos_sin`. Taking L = q_min, q_max
  gives every limit crossing; L = π gives the wraps through ±π, needed only for
  a joint whose limits reach ±π (otherwise the joint is outside its limits on
  both sides of a wrap, so a wrap changes nothing). A singular
  point (n = d = 0, seed 003: :math:`a_t^2 + b_t^2 = c_t^2`), where θ jumps by π,
  solves this equation for every L, so it is a root too.
- cos-type (θ2, θ6): :math:`\cos\theta = M_{22}(\psi)`; θ = ±L iff :math:`M_{22}(\psi) = \cos L`.
- θ4 does not depend on ψ.

θ is continuous in ψ between consecutive roots and crosses no limit there, so
the roots are all the breakpoints: :func:`qpik.analytic.intervals.assemble_many`
classifies each gap by one evaluation of every branch at its midpoint, all
gaps in one compiled sweep (:meth:`qpik.analytic.solver.AnalyticSolver.solve_many`,
the IK itself with its in-limits test); the breakpoints of all branches are pooled, since a breakpoint
that changes nothing only splits a gap.

The singular values listed per branch are the ψ where :math:`|M_{22}| = 1` for
the shoulder or the wrist (θ2 or θ6 = 0 or π): the maximum :math:`c + \sqrt{a^2+b^2}`
of :math:`M_{22}` is at ψ = atan2(a, b), the minimum at atan2(−a, −b) (seed 003's
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
from qpik.analytic.intervals import FeasibleIntervals, assemble_many, wrap
from qpik.analytic.srs import arm_setup, branch_signs
from qpik.compiled import Compiled

if TYPE_CHECKING:
    from qpik.analytic.srs import SRSSolver

TOUCH_TOL = 1e-12
"""|1 − |M22|| at the extremum below which a shoulder/wrist singular ψ is reported."""

_ANGLE_JOINTS = ((0, 1, 2), (4, 5, 6))  # joints of the (shoulder, wrist) ZYZ triples (a, b, c)


class PsiIntervals:
    """Feasible ψ intervals of every branch of one S-R-S solver; call with a (4, 4) pose."""

    def __init__(self, solver: SRSSolver):
        self._solver = solver
        self.branch = np.array(solver.branch_ids)
        robot = solver.robot
        self.q_min, self.q_max = np.asarray(robot.q_min, float), np.asarray(robot.q_max, float)
        T = ca.SX.sym("T", 4, 4)
        R, p = sy.frame_of_batch(T)
        setup = arm_setup(R, p, solver.geometry, sy.CASADI)
        entries = [
            X[i][j]
            for e in range(2)
            for group in setup.coefficients(e)
            for X in group
            for i in range(3)
            for j in range(3)
        ]
        self._coefficients = Compiled(ca.Function("srs_coefficients", [T], [ca.vertcat(*entries), setup.valid]))
        # Every breakpoint equation is  w1 m1(ψ) + w2 m2(ψ) = w3  with m1, m2 entries of M_s or M_w
        # (each A sin ψ + B cos ψ + C): tan-type n cos L − d sin L = 0 for L = q_min, q_max (and π
        # where a limit reaches it), cos-type M22 = cos L.
        rows = []  # (group, entry 1, w1, entry 2, w2, w3)
        for g, (ja, jb, jc) in enumerate(_ANGLE_JOINTS):
            for j, n, d, sign in ((ja, (1, 2), (0, 2), 1.0), (jc, (2, 1), (2, 0), -1.0)):
                wraps = self.q_max[j] >= np.pi or self.q_min[j] <= -np.pi
                for L in (self.q_min[j], self.q_max[j], *((np.pi,) if wraps else ())):
                    rows.append((g, n, np.cos(L), d, -sign * np.sin(L), 0.0))
            for cos_l in np.unique(np.cos([self.q_min[jb], self.q_max[jb]])):
                rows.append((g, (2, 2), 1.0, (2, 2), 0.0, cos_l))
        shape = (2, 2, 3, 3, 3)  # elbow, group (shoulder, wrist), (A, B, C), row, column
        e, X = np.arange(2)[:, None, None], np.arange(3)
        g = np.array([r[0] for r in rows])[:, None]
        self._eq_index = [
            np.ravel_multi_index((e, g, X, *np.array([r[k] for r in rows]).T[:, :, None]), shape) for k in (1, 3)
        ]
        self._eq_weight = [np.array([r[k] for r in rows])[:, None] for k in (2, 4)]
        self._eq_rhs = np.array([r[5] for r in rows])
        self._m22 = np.ravel_multi_index((e, np.arange(2)[:, None], X, 2, 2), shape)  # (elbow, group, ABC)
        signs = np.array([branch_signs(k) for k in solver.branch_ids])
        self._i_elbow = signs[:, 1]

    def __call__(self, T: np.ndarray) -> FeasibleIntervals:
        coef, valid = self._coefficients(T)
        n = len(self.branch)
        if valid[0] < 0.5:
            return FeasibleIntervals("psi", self.branch.copy(), [[] for _ in range(n)], [[] for _ in range(n)])
        breaks, singular = self._breakpoints(coef)
        within = self._solver.solve_many  # the branches at the gap midpoints
        intervals = assemble_many(np.concatenate([breaks, *singular]), lambda psi: within(T, psi).within_limits)
        return FeasibleIntervals("psi", self.branch.copy(), intervals, [singular[e].tolist() for e in self._i_elbow])

    def _breakpoints(self, coef: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """The roots of every limit (and wrap) equation, and the singular ψ per elbow sign (coefficients (108,))."""
        (i1, i2), (w1, w2) = self._eq_index, self._eq_weight
        eq = coef[i1] * w1 + coef[i2] * w2  # (elbow, equation, ABC)
        plus, minus, ok = trig.solve_cos_sin(eq[..., 1], eq[..., 0], self._eq_rhs - eq[..., 2], sy.NUMPY)
        ok = ok.astype(bool)
        breaks = np.concatenate([plus[ok], minus[ok]])
        # M22 = a sin ψ + b cos ψ + c reaches ±1 at its extrema
        a, b, c = np.moveaxis(coef[self._m22], -1, 0)  # (elbow, group) each
        r = np.hypot(a, b)
        top = (np.abs(c + r - 1.0) < TOUCH_TOL) & (r > TOUCH_TOL)
        bottom = (np.abs(c - r + 1.0) < TOUCH_TOL) & (r > TOUCH_TOL)
        singular = [np.empty(0), np.empty(0)]
        for e in np.flatnonzero(np.any(top | bottom, axis=1)):
            psi = np.concatenate([np.arctan2(a[e], b[e])[top[e]], np.arctan2(-a[e], -b[e])[bottom[e]]])
            singular[e] = np.unique(wrap(psi))
        return breaks, singular

