r"""Exact feasible δ sets of the offset-shoulder arm (Nammoto & Kosuge 2012) under joint limits.

For a fixed pose every joint of every branch is a function of δ. A branch's
feasibility (valid, every joint inside ``[q_min, q_max]``) can only change where

- a joint equals a limit L (or ±π where a limit reaches ±π, the wrap),
- the branch stops being valid: :math:`\sin\theta_4 = \pm 1` or the shoulder
  equation's discriminant vanishes (these are also the elbow and shoulder
  singularities, where θ3 and θ2 can jump),
- a wrist angle jumps by π at :math:`\sin\theta_6 = 0` (a root of the θ5 and θ7
  equations below, for every L).

All those δ are found analytically for the branches with θ1[1] (rows 1–8); rows
9–16 are the same functions shifted by π (θ1[2](δ) = θ1[1](δ + π)). With
:math:`c = \cos\delta`, :math:`s = \sin\delta`, :math:`w' = (rc - a_1, h, rs)`
(:math:`h = w_z - d_1`), :math:`E = w_x'^2 + h^2`, :math:`Z = d_3 + d_5\sin\theta_4`,
:math:`\sin\theta_4 = k_1 + k_2 c` and :math:`D = E - Z^2`:

- θ1 = L: :math:`\delta = L - \mathrm{atan2}(w_y, w_x)`;
- θ4 = L: :math:`k_1 + k_2 c = \sin L`; validity: :math:`k_1 + k_2 c = \pm 1`, :math:`D(c) = 0` (and
  where the solver's tolerant validity tests switch, :math:`k_1 + k_2 c = \pm(1 + \epsilon)`,
  :math:`D = -\epsilon` and :math:`D = -\epsilon E`, ε = :data:`qpik.analytic.trig.EPS`: near a
  tangency they are up to ~1e-9 rad from the exact roots);
- θ2 = L: :math:`-\sin L\,(rc - a_1) + \cos L\, h = Z(c)` (linear in c);
- θ3 = L: :math:`\sin L\, w''_x = \cos L\, w''_y` with :math:`w''_x = \pm\sqrt D`,
  :math:`w''_y = -rs`; squared: :math:`\sin^2 L\, D(c) = \cos^2 L\, r^2 (1 - c^2)` (quadratic in c);
- θ5, θ6, θ7 through the frame-1 unit vector of the upper arm
  :math:`u = (Z\hat w + \sigma\sqrt D\,\hat w_\perp)/E` (:math:`\hat w = (w'_x, h, 0)`,
  :math:`\hat w_\perp = (-h, w'_x, 0)`) and :math:`z_4 = (d_3 u - w')/d_5`:
  θ6 = L ⇔ :math:`z_4\cdot b = \cos L`; θ7 = L (mod π) ⇔
  :math:`z_4\cdot(\sin L\, n + \cos L\, t) = 0`; θ5 = L (mod π) ⇔
  :math:`\sin L\,(u + s_4 z_4)\cdot b - \cos L\,(z_4\times u)\cdot b = 0` (the frame-4
  axes times cos θ4: :math:`c_4 x_4 = u + s_4 z_4`, :math:`c_4 y_4 = z_4 \times u`).
  Multiplied by :math:`d_5 E` each is :math:`P + \sigma\sqrt{D}\,Q` with P, Q polynomials
  in (c, s); :math:`F = P^2 - D Q^2 = 0` wherever either σ solves it. Reduced with
  :math:`s^2 = 1 - c^2`, :math:`F = A(c) + s\,B(c)` (A of degree 8 for θ5, 6 for θ6 and θ7):
  its real roots come from :func:`qpik.analytic.polyroots.trig_roots` (a polynomial in
  :math:`\tan(\delta/2)`, compiled root finder).

All the coefficients (the quadratics, A and B) and the candidates of the quadratics
come from one compiled CasADi function of the pose, traced from the CasADi
expressions in :meth:`DeltaIntervals.expressions`.

A margin m > 0 asks for the δ where every joint lies in the shrunk limits
:math:`[l_j + m\rho_j,\ u_j - m\rho_j]`, :math:`\rho_j = (u_j - l_j)/2`
(:func:`qpik.analytic.intervals.shrunk_limits`): the joint-limit margin is at least m there.
A level L enters the equations above only as :math:`L - \mathrm{atan2}(w_y, w_x)` (θ1) and
through sin L and cos L, so the same expressions with L a symbol give a second compiled
function, of the pose and the shrunk limits ``(T, q_min, q_max)`` (the robot's angles, mapped to
the table's by the joint map's sign and shift inside it), built once on first use and called
for every margin. Each shrunk limit has its own equations (with the robot's limits, the θ5 and
θ7 equations of levels equal mod π and the θ6 equations of equal cos L are written once); a
joint whose limits reach past ±π keeps the levels of its limits and π too, where its
representative q + 2πk jumps (an extra breakpoint only splits a gap). The gaps are
classified by the IK's limit test against the shrunk limits, and rows 9–16 are still rows
1–8 moved by π (the same configurations, under the same shrunk limits). Margin 0 is the
robot's limits' function.

Squaring (θ3 and the σ product) and the ±acos of c add spurious candidates; they
only split a gap in two, and merging the gaps joins it again. Rows 9–16 are rows 1–8
shifted by π, so only rows 1–8 are classified: one evaluation of those 8 branches
at every gap midpoint (:class:`qpik.analytic.intervals.SetAssembler`), and
rows 9–16's sets are rows 1–8's moved by π.

With a C compiler all of it is one C call (:class:`~qpik.analytic.arm_sets.DeltaSetsCall`:
``offset_shoulder_intervals.c``, compiled with ``polyroots.c`` and ``intervals.c``): the breakpoint function,
the wrist roots, the common-root test and the classification of the gaps, with no numpy in between; without one,
the same steps run in numpy (:meth:`DeltaIntervals.breakpoints`, then the SetAssembler).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Ops, Scalar
from qpik.analytic.arm_sets import NONE, DeltaSetsCall
from qpik.analytic.intervals import FeasibleIntervals, SetAssembler, shrunk_limits
from qpik.analytic.native_sets import NativeSets
from qpik.analytic.polyroots import trig_roots
from qpik.analytic.trig import EPS, acos2
from qpik.core.errors import QpikError
from qpik.native.compiled import Compiled

if TYPE_CHECKING:
    from qpik.analytic.offset_shoulder import OffsetShoulderSolver

PI = np.pi
ZERO = 1e-13
"""Wrist-centre distance (m) from the base axis below which its azimuth is taken as 0 (as the solver does)."""
COMMON_TOL = 1e-6
"""θ5 and θ7 roots closer than this (rad) are a common root: a wrist singularity (sin θ6 = 0)."""
COEFFS = 9
"""Coefficients of each wrist polynomial A and B in c (degree 8 at most), padded with zeros."""

Poly = list  # coefficients of a polynomial in c = cos δ, lowest first (scalars: floats or CasADi SX)
CSPoly = tuple[Poly, Poly]  # A(c) + sin δ · B(c)


class DeltaIntervals:
    """Feasible δ intervals of every branch of one offset-shoulder solver; call with a (4, 4) pose and a margin."""

    proved = True

    def __init__(self, solver: OffsetShoulderSolver):
        self._solver = solver
        self.branch = np.array(solver.branch_ids)
        self.levels = [solver.levels(j) for j in range(solver.robot.dof)]  # in the table's angles
        self._limits = (np.asarray(solver.robot.q_min, float), np.asarray(solver.robot.q_max, float))
        self._fixed = self._compile("os_breakpoints", [], self.levels)
        self._assemble = SetAssembler(solver, rows=8, shift=True)

    @cached_property
    def _shrunk(self) -> _Breakpoints:
        """The breakpoint function of shrunk limits, ``(T, q_min (n,), q_max (n,))`` (rad, the robot's angles):
        compiled on first use, once for every margin."""
        n = self._solver.robot.dof
        lo, hi = ca.SX.sym("q_min", n), ca.SX.sym("q_max", n)
        levels = [self._shrunk_levels(j, lo[j], hi[j]) for j in range(n)]
        return self._compile("os_breakpoints_shrunk", [lo, hi], levels)

    def _shrunk_levels(self, j: int, lo: Scalar, hi: Scalar) -> list[Scalar]:
        r"""The levels of joint j's shrunk limits ``lo``, ``hi`` (rad, the robot's angles, symbolic) in the table's
        angles, :math:`s x + c` (:attr:`~qpik.analytic.solver.AnalyticSolver.joint_map`: a level enters only
        through its sine and cosine and through θ1 = L, which is wrapped).

        A joint whose limits l, u reach past ±π also has the levels l, u and π: its representative
        :math:`q + 2\pi k` (:class:`~qpik.analytic.solver.AnalyticSolver`) jumps there, into or out of the shrunk
        limits. A joint within ±π needs no wrap level: the shrunk limits stay off ±π, so it is outside them on
        both sides of the wrap."""
        l, u = float(self._limits[0][j]), float(self._limits[1][j])
        out = [lo, hi, l, u, PI] if l < -PI or u > PI else [lo, hi]
        joints = self._solver.joint_map
        if joints is None:
            return out
        s, c = float(joints.sign[j]), float(joints.shift[j])
        return [sy.add(sy.mul(s, x), c) for x in out]

    def _compile(self, name: str, inputs: list, levels: list[list[Scalar]]) -> _Breakpoints:
        """The breakpoint function ``name`` of the pose T (4, 4) and ``inputs`` (the symbols of ``levels``, per
        joint): candidates and singular candidates (δ, :data:`NONE` where one does not exist), the wrist
        equations' A and B (COEFFS, K)."""
        T = ca.SX.sym("T", 4, 4)
        cand, sing, polys, kinds = self.expressions(T, sy.CASADI, levels)
        out = [ca.vertcat(*[ca.if_else(ok, sy.CASADI.wrap(x), NONE) for x, ok in pairs]) for pairs in (cand, sing)]
        # (COEFFS, K) outputs: their transposes are C-contiguous (K, COEFFS) views of the column-major buffers
        FA, FB = (ca.horzcat(*[ca.vertcat(*_pad(x, COEFFS)) for x in xs]) for xs in zip(*polys))
        # the rows of the θ7 and θ5 equations are consecutive (expressions lists them joint by joint): row ranges
        wrist_rows = np.array([k for j in (7, 5) for k in _row_range(kinds, j)])
        fn = Compiled(ca.Function(name, [T, *inputs], [*out, FA, FB]))
        return _Breakpoints(fn, wrist_rows, DeltaSetsCall.build(fn, self._solver, wrist_rows, COEFFS, COMMON_TOL))

    def native_sets(self) -> NativeSets | None:
        """The sets under limits given at run time as one C call (the shrunk limits' path), None without a compiler."""
        native = self._shrunk.native
        return None if native is None else native.sets()

    def expressions(self, T, ops: Ops, levels: list[list[Scalar]]) -> tuple[list, list, list[Poly], list[int]]:
        """The breakpoint equations of rows 1–8 for the world pose T (4, 4) and the levels (rad, the table's angles)
        of each joint: floats (:attr:`levels`; the θ5, θ6 and θ7 equations of equal levels mod π or equal cos L
        are written once) or symbols (every level has its equations).

        Returns ``(candidates, singular, polys, kinds)``: (δ, exists) pairs found in closed form
        (limit crossings of θ1–θ4 and the validity boundaries), the (δ, ok) pairs where a
        branch turns singular (elbow, shoulder), the wrist equations F = A + sin δ · B as (A, B)
        (polynomials in c = cos δ) and the joint of each (5, 6 or 7, 1-based).
        """
        g = self._solver.geometry
        R, p = sy.frame_of_batch(T)
        R, p = self._solver.to_flange(R, p)
        n, t, b = sy.col(R, 0), sy.col(R, 1), sy.col(R, 2)
        w = sy.vadd(p, sy.vscale(g.d7, b))
        r = ops.sqrt(w[0] * w[0] + w[1] * w[1])
        far = r > ZERO
        rs = ops.fmax(r, ZERO)
        cphi, sphi = ops.where(far, w[0] / rs, 1.0), ops.where(far, w[1] / rs, 0.0)
        phi = ops.where(far, ops.atan2(w[1], w[0]), 0.0)
        h = w[2] - g.d1
        k1 = (r * r + g.a1**2 + h * h - g.d3**2 - g.d5**2) / (2 * g.d3 * g.d5)
        k2 = -g.a1 * r / (g.d3 * g.d5)
        z0, z1 = g.d3 + g.d5 * k1, g.d5 * k2

        # ---- equations quadratic in c: rows (A, B, C) of A c² + B c + C = 0
        dA, dB, dC = r * r - z1 * z1, -2 * g.a1 * r - 2 * z0 * z1, g.a1**2 + h * h - z0 * z0  # D(c)
        rows = [(0.0, k2, k1 - 1.0), (0.0, k2, k1 + 1.0), (dA, dB, dC)]  # validity: sin θ4 = ±1, D = 0
        # where the solver's tolerant tests switch (|sin θ4| <= 1 + EPS, D >= -EPS max(E, 1); trig.EPS):
        # near a tangency these lie up to ~1e-9 rad from the exact roots above
        rows += [(0.0, k2, k1 - 1.0 - EPS), (0.0, k2, k1 + 1.0 + EPS), (dA, dB, dC + EPS)]
        rows.append((dA + EPS * r * r, dB - 2 * EPS * g.a1 * r, dC + EPS * (g.a1**2 + h * h)))
        for L in levels[1]:  # θ2
            sL, cL = _sin_cos(L, ops)
            rows.append((0.0, r * (g.a1 / g.d3 - sL), sL * g.a1 + cL * h - z0))
        for L in levels[2]:  # θ3 (squared)
            sL, cL = _sin_cos(L, ops)
            s2, c2 = sL * sL, cL * cL
            rows.append((s2 * dA + c2 * r * r, s2 * dB, s2 * dC - c2 * r * r))
        for L in levels[3]:  # θ4
            rows.append((0.0, k2, k1 - _sin_cos(L, ops)[0]))
        roots = [_quadratic_roots(*row, ops) for row in rows]
        cand = [pair for rr in roots for pair in _acos_pairs(rr, ops)]
        cand += [(L - phi, 1.0) for L in levels[0]]
        sing = [pair for rr in roots[:3] for pair in _acos_pairs(rr, ops)]

        # ---- θ5, θ6, θ7: F = P² − D Q² = A(c) + s B(c)
        C, S = ([0.0, 1.0], []), ([], [1.0])  # cos δ and sin δ as CS-polynomials
        c1, s1 = _cs_lin((cphi, C), (-sphi, S)), _cs_lin((sphi, C), (cphi, S))
        wx = _cs_lin((r, C), (-g.a1, _one()))
        wz = _cs_lin((r, S))
        E = _cs_lin((1.0, _cs_mul(wx, wx)), (h * h, _one()))
        s4 = _cs_lin((k1, _one()), (k2, C))
        Z = _cs_lin((z0, _one()), (z1, C))
        D = _cs_lin((1.0, E), (-1.0, _cs_mul(Z, Z)))

        def frame1(v) -> tuple[CSPoly, ...]:
            """(v'x, v'z, ŵ·v', ŵ⊥·v', (w − o1)·v) of a world vector v seen in frame 1."""
            vx = _cs_lin((v[0], c1), (v[1], s1))
            vz = _cs_lin((v[0], s1), (-v[1], c1))
            gv = _cs_lin((sy.dot(w, v) - g.d1 * v[2], _one()), (-g.a1, vx))
            return vx, vz, _cs_lin((1.0, _cs_mul(wx, vx)), (h * v[2], _one())), _cs_lin((-h, vx), (v[2], wx)), gv

        def z4_dot(v) -> tuple[CSPoly, CSPoly]:
            """d5 E z4·v = P + σ√D Q."""
            _, _, wv, wpv, gv = frame1(v)
            return _cs_lin((g.d3, _cs_mul(Z, wv)), (-1.0, _cs_mul(E, gv))), _cs_lin((g.d3, wpv))

        polys, kinds = [], []
        Pb, Qb = z4_dot(b)
        for cL in _distinct_cos(levels[5], ops):  # θ6
            polys.append(_clear(_cs_lin((1.0, Pb), (-g.d5 * cL, E)), Qb, D))
            kinds.append(6)
        Pn, Qn = z4_dot(n)
        Pt, Qt = z4_dot(t)
        for L in _mod_pi(levels[6]):  # θ7
            sL, cL = _sin_cos(L, ops)
            polys.append(_clear(_cs_lin((sL, Pn), (cL, Pt)), _cs_lin((sL, Qn), (cL, Qt)), D))
            kinds.append(7)
        _, bz, wb, wpb, gb = frame1(b)
        f = _cs_lin((g.d5, _one()), (g.d3, s4))  # d5 + d3 s4
        XP = _cs_lin((1.0, _cs_mul(_cs_mul(f, Z), wb)), (-1.0, _cs_mul(_cs_mul(s4, E), gb)))
        XQ = _cs_mul(f, wpb)
        YP = _cs_lin((-1.0, _cs_mul(_cs_mul(Z, wz), wpb)))
        YQ = _cs_lin((1.0, _cs_mul(wz, wb)), (-1.0, _cs_mul(E, bz)))
        for L in _mod_pi(levels[4]):  # θ5
            sL, cL = _sin_cos(L, ops)
            polys.append(_clear(_cs_lin((sL, XP), (-cL, YP)), _cs_lin((sL, XQ), (-cL, YQ)), D))
            kinds.append(5)
        return cand, sing, polys, kinds

    def breakpoints(
        self, T: np.ndarray, limits: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every δ (rad) where a row 1–8 can change feasibility, and those where one can turn singular, under the
        robot's limits or ``limits`` ``(q_min, q_max)`` ((n,) rad each, such as
        :func:`~qpik.analytic.intervals.shrunk_limits`)."""
        if limits is None:
            return self._fixed.breakpoints(T)
        return self._shrunk.breakpoints(T, *limits)

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """The feasible sets of the pose T (4, 4) with every joint in the limits shrunk by ``margin`` (>= 0; 0: the
        robot's limits; see :func:`~qpik.analytic.intervals.shrunk_limits`)."""
        if margin == 0.0:
            fn, limits = self._fixed, None
        else:
            fn, limits = self._shrunk, shrunk_limits(*self._limits, margin)
        if fn.native is not None:
            intervals, singular = fn.native(T, limits)
        else:  # rows 1–8, then 9–16: row 8 + k at δ is row k at δ + π
            args = () if limits is None else limits
            intervals, singular = self._assemble(T, *fn.breakpoints(T, *args), limits=limits)
        return FeasibleIntervals(self._solver.param_name, self.branch.copy(), intervals, singular)


@dataclass(frozen=True)
class _Breakpoints:
    """A compiled breakpoint function of rows 1–8 (of the pose, and of the limits for the shrunk limits'), the row
    ranges ``(a7, b7, a5, b5)`` of its θ7 and θ5 wrist equations and its one-C-call path (None without a compiler)."""

    fn: Compiled
    wrist_rows: np.ndarray
    native: DeltaSetsCall | None

    def breakpoints(self, T: np.ndarray, *limits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The breakpoints and singular candidates (δ, rad) of the pose T (4, 4) (and the limits, as the function's
        inputs): the closed-form ones, the wrist roots and the θ5 roots common with a θ7 root."""
        cand, sing, FAt, FBt = self.fn(T, *limits)  # values that do not exist are NONE
        cand, sing = cand[cand != NONE], sing[sing != NONE]
        wrist, owner = trig_roots(FAt.T, FBt.T)
        # sin θ6 = 0 zeroes every θ5 and θ7 equation: their common roots (owner is ascending)
        a7, b7, a5, b5 = np.searchsorted(owner, self.wrist_rows).tolist()
        r5, r7 = wrist[a5:b5], wrist[a7:b7]
        if r5.size and r7.size:  # cos d > 1 − tol²/2 ⇔ |d| < tol on the circle (offset_shoulder_intervals.c: same)
            close = (np.cos(r5[:, None] - r7[None, :]) > 1.0 - 0.5 * COMMON_TOL**2).any(axis=1)
            sing = np.concatenate([sing, r5[close]])
        return np.concatenate([cand, wrist]), sing


def _row_range(kinds: list[int], joint: int) -> tuple[int, int]:
    """First and one-past-last row of ``joint``'s equations (consecutive in ``kinds``), (0, 0) when it has none."""
    rows = [k for k, j in enumerate(kinds) if j == joint]
    if rows and rows != list(range(rows[0], rows[-1] + 1)):
        raise QpikError(f"the equations of joint {joint} are not consecutive")
    return (rows[0], rows[-1] + 1) if rows else (0, 0)


def _mod_pi(levels: list[Scalar]) -> list[Scalar]:
    """Float levels up to π (an equation 'θ = L (mod π)' serves L and L ± π); symbolic levels as they are."""
    if not all(isinstance(L, float) for L in levels):
        return levels
    return sorted({round(float(np.mod(L, PI)), 15) for L in levels})


def _distinct_cos(levels: list[Scalar], ops: Ops) -> list[Scalar]:
    """cos L of float levels, each value once (an equation 'cos θ = cos L' serves ±L); of symbolic levels, each."""
    if not all(isinstance(L, float) for L in levels):
        return [ops.cos(L) for L in levels]
    return sorted({round(float(np.cos(L)), 15) for L in levels})


def _sin_cos(L: Scalar, ops: Ops) -> tuple[Scalar, Scalar]:
    """sin L and cos L: floats for a float level (folded into the equations' constants), else ``ops``'."""
    return (np.sin(L), np.cos(L)) if isinstance(L, float) else (ops.sin(L), ops.cos(L))


def _quadratic_roots(A: Scalar, B: Scalar, C: Scalar, ops: Ops) -> list[tuple[Scalar, Scalar]]:
    """(c, ok) for the real roots c ∈ [−1, 1] of A c² + B c + C = 0 (``A == 0.0``: linear); c clipped to [−1, 1].

    Numerically stable form :math:`m = -(B + \\mathrm{sign}(B)\\sqrt{B^2 - 4AC})/2`, roots m/A and C/m;
    a discriminant above −1e-12 scale² counts as a tangency (the double root).
    """
    scale = ops.fmax(ops.fmax(ops.fabs(A), ops.fabs(B)), ops.fabs(C)) + 1e-300
    lin = ops.fabs(A) <= 1e-14 * scale
    has_b = ops.fabs(B) > 1e-14 * scale
    linear = -C / ops.where(has_b, B, 1.0)
    if isinstance(A, float) and A == 0.0:
        out = [(linear, has_b)]
    else:
        disc = B * B - 4.0 * A * C
        real = disc >= -1e-12 * scale * scale
        sq = ops.safe_sqrt(disc)
        m = -0.5 * (B + ops.where(B >= 0, sq, -sq))
        big = ops.fabs(m) > 0
        first = ops.where(lin, linear, m / ops.where(lin, 1.0, A))
        second = C / ops.where(big, m, 1.0)
        out = [(first, ops.where(lin, has_b, real)), (second, (1 - lin) * real * big)]
    return [(ops.fmin(ops.fmax(c, -1.0), 1.0), ok * (ops.fabs(c) <= 1.0 + 1e-9)) for c, ok in out]


def _acos_pairs(roots: list[tuple[Scalar, Scalar]], ops: Ops) -> list[tuple[Scalar, Scalar]]:
    """(±acos c, ok) for every (c, ok)."""
    out = []
    for c, ok in roots:
        plus, minus, _ = acos2(c, ops)
        out += [(plus, ok), (minus, ok)]
    return out


# ---- polynomials in (c, s) with s² = 1 − c²: (A, B) means A(c) + s B(c), coefficients lowest first


def _one() -> CSPoly:
    return [1.0], []


def _padd(a: Poly, b: Poly) -> Poly:
    out = list(a) + [0.0] * (len(b) - len(a))
    for i, x in enumerate(b):
        out[i] = sy.add(out[i], x)
    return out


def _pmul(a: Poly, b: Poly) -> Poly:
    if not a or not b:
        return []
    out: Poly = [0.0] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] = sy.add(out[i + j], sy.mul(x, y))
    return out


def _pscale(k: Scalar, a: Poly) -> Poly:
    return [sy.mul(k, x) for x in a]


ONE_MINUS_C2 = [1.0, 0.0, -1.0]  # s² = 1 − c²


def _cs_mul(f: CSPoly, g: CSPoly) -> CSPoly:
    """(A1 + s B1)(A2 + s B2) = A1 A2 + (1 − c²) B1 B2 + s (A1 B2 + B1 A2)."""
    (a1, b1), (a2, b2) = f, g
    return _padd(_pmul(a1, a2), _pmul(ONE_MINUS_C2, _pmul(b1, b2))), _padd(_pmul(a1, b2), _pmul(b1, a2))


def _cs_lin(*terms: tuple[Scalar, CSPoly]) -> CSPoly:
    """Σ k · f over (k, f)."""
    A: Poly = []
    B: Poly = []
    for k, (a, b) in terms:
        A, B = _padd(A, _pscale(k, a)), _padd(B, _pscale(k, b))
    return A, B


def _clear(P: CSPoly, Q: CSPoly, D: CSPoly) -> CSPoly:
    """F = P² − D Q² = A + s B: zero wherever P + σ√D Q = 0 for σ = +1 or −1."""
    return _cs_lin((1.0, _cs_mul(P, P)), (-1.0, _cs_mul(D, _cs_mul(Q, Q))))


def _pad(a: Poly, n: int) -> Poly:
    if len(a) > n:
        raise QpikError(f"polynomial of degree {len(a) - 1} > {n - 1}")
    return list(a) + [0.0] * (n - len(a))
