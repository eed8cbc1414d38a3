"""The geometry of an S-R-S arm shared by its closed form (:mod:`qpik.analytic.srs`) and its feasible sets
(:mod:`qpik.analytic.srs_intervals`): the arm's lengths, the elbow and the reference plane of a pose
(Shimizu et al. 2008), and the numbering of the 8 branches."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic import trig
from qpik.analytic.trig import EPS
from qpik.core.errors import NoClosedFormError
from qpik.robots.recognize import PATTERNS

if TYPE_CHECKING:
    from qpik.robots.dh import DHChain

SINGULAR_TOL = 1e-10
r"""A sine below this (:math:`|\sin\theta_i|`, i = 2, 4, 6; horizontal/total length of x_sw) marks a singular case."""
ELBOW_TOL = 1e-13
"""Where ``1 ∓ cos θ4`` is below this the elbow is stretched (folded): θ4 := 0 (π) and ``singular`` is set.

θ4 near 0 goes as the square root of :math:`d_{se} + d_{ew} - |x_{sw}|`: the rounding of a pose
(~1e-16 m in :math:`|x_{sw}|^2`) alone moves it by ~1e-8 rad there, so a sine test cannot tell a
stretched elbow from a bent one; this tolerance (θ4 below ~4.5e-7 rad) covers that rounding."""

ALPHA = PATTERNS["srs"].alpha
"""The DH twist pattern the closed form is written for."""

_TINY = 1e-300  # guards exact zeros only (atan2(0, 0) and its derivative)


@dataclass(frozen=True)
class SRSGeometry:
    """Link lengths (m) and the constant base/tool frames of an S-R-S chain."""

    d_bs: float
    d_se: float
    d_ew: float
    d_wt: float
    base_inv: sy.Frame
    tool_inv: sy.Frame

    @classmethod
    def from_chain(cls, chain: DHChain) -> SRSGeometry:
        """Read d_bs = d[0], d_se = d[2], d_ew = d[4], d_wt = d[6]; raise if the table is not this S-R-S form."""
        problems = []
        if chain.dof != 7 or chain.convention != "standard":
            problems.append(f"need 7 joints in the standard convention, got {chain.dof} ({chain.convention})")
        else:
            if any(abs(x) > 1e-12 for x in chain.a):
                problems.append(f"a must be 0, got {chain.a}")
            if any(abs(chain.d[i]) > 1e-12 for i in (1, 3, 5)):
                problems.append(f"d[1], d[3], d[5] must be 0, got {chain.d}")
            if any(abs(x - y) > 1e-12 for x, y in zip(chain.alpha, ALPHA)):
                problems.append(f"alpha must be (-pi/2, pi/2, pi/2, -pi/2, -pi/2, pi/2, 0), got {chain.alpha}")
            if any(abs(x) > 1e-12 for x in chain.offset):
                problems.append(f"joint offsets must be 0, got {chain.offset}")
            if chain.d[2] <= 0 or chain.d[4] <= 0:
                problems.append(f"d_se = d[2] and d_ew = d[4] must be positive, got {chain.d[2]}, {chain.d[4]}")
        if problems:
            raise NoClosedFormError("S-R-S closed form does not apply: " + "; ".join(problems))
        return cls(
            d_bs=float(chain.d[0]),
            d_se=float(chain.d[2]),
            d_ew=float(chain.d[4]),
            d_wt=float(chain.d[6]),
            base_inv=sy.frame_of(np.linalg.inv(chain.base)),
            tool_inv=sy.frame_of(np.linalg.inv(chain.tool)),
        )


@dataclass
class ArmSetup:
    r"""Everything that depends on the pose only (chain frame).

    Attributes:
        R: end-effector rotation.
        u: unit shoulder-to-wrist vector :math:`u_{sw}`.
        elbows: per elbow sign (θ4 >= 0, then θ4 <= 0): ``(θ4, cos θ4, sin θ4, M_s^0)``.
        valid: 1 where the wrist centre is reachable.
        singular: 1 where the reference plane is undefined or the elbow is stretched/folded.
    """

    R: Mat
    u: Vec
    elbows: tuple[tuple[Scalar, Scalar, Scalar, Mat], ...]
    valid: Scalar
    singular: Scalar

    def wrist(self, e: int, Ms: Mat) -> Mat:
        r""":math:`M_w = R_y(\theta_4) M_s^T R` for elbow sign ``e``."""
        _, c4, s4, _ = self.elbows[e]
        return sy.matmul(rot_y(c4, s4), sy.matmul(sy.transpose(Ms), self.R))

    def coefficients(self, e: int) -> tuple[tuple[Mat, Mat, Mat], tuple[Mat, Mat, Mat]]:
        r"""``((A_s, B_s, C_s), (A_w, B_w, C_w))`` of elbow sign ``e``: :math:`M(\psi) = A\sin\psi + B\cos\psi + C`.

        :math:`A_s = [u]_\times M_s^0`, :math:`B_s = -[u]_\times^2 M_s^0`, :math:`C_s = u u^T M_s^0`
        (the expansion of :math:`R_\psi M_s^0`), and :math:`A_w = R_y(\theta_4) A_s^T R`, etc.
        """
        M0 = self.elbows[e][3]
        K = skew(self.u)
        A_s = sy.matmul(K, M0)
        B_s = mscale(-1.0, sy.matmul(K, A_s))
        C_s = sy.matmul(outer(self.u), M0)
        shoulder = (A_s, B_s, C_s)
        return shoulder, tuple(self.wrist(e, X) for X in shoulder)  # type: ignore[return-value]


# ---- small rotation helpers -------------------------------------------------


def rot_y(c: Scalar, s: Scalar) -> Mat:
    return ((c, 0.0, s), (0.0, 1.0, 0.0), (sy.neg(s), 0.0, c))


def skew(u: Vec) -> Mat:
    return ((0.0, sy.neg(u[2]), u[1]), (u[2], 0.0, sy.neg(u[0])), (sy.neg(u[1]), u[0], 0.0))


def outer(u: Vec) -> Mat:
    return tuple(tuple(sy.mul(u[i], u[j]) for j in range(3)) for i in range(3))  # type: ignore[return-value]


def mscale(s: Scalar, M: Mat) -> Mat:
    return tuple(tuple(sy.mul(s, x) for x in row) for row in M)  # type: ignore[return-value]


def rotation_about(u: Vec, s: Scalar, c: Scalar) -> Mat:
    r"""Rodrigues: :math:`R_\psi = c\,I + s\,[u]_\times + (1 - c)\,u u^T` (s = sin ψ, c = cos ψ)."""
    K, U, d = skew(u), outer(u), 1.0 - c
    return tuple(
        tuple(sy.add(sy.lin((s, K[i][j]), (d, U[i][j])), c if i == j else 0.0) for j in range(3)) for i in range(3)
    )  # type: ignore[return-value]


def either(a: Scalar, b: Scalar, ops: Ops) -> Scalar:
    """Logical or of two 0/1 flags."""
    return ops.fmax(a, b)


# ---- the pose-dependent part ------------------------------------------------


def reference_azimuth(x_sw: Vec, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    r"""``(cos θ1⁰, sin θ1⁰, singular)``: joint 1 of the reference configuration faces the wrist.

    :math:`\theta_1^0 = \mathrm{atan2}(y_{sw}, x_{sw})`; an exactly vertical
    :math:`x_{sw}` uses θ1⁰ = 0. ``singular`` is 1 where the horizontal part of
    :math:`x_{sw}` is below ``SINGULAR_TOL`` times its length.
    """
    x, y, z = x_sw
    h2 = x * x + y * y
    flat = h2 < _TINY
    xs = ops.where(flat, 1.0, x)
    ys = ops.where(flat, 0.0, y)
    h = ops.sqrt(xs * xs + ys * ys)
    singular = h2 < SINGULAR_TOL**2 * (h2 + z * z)
    return xs / h, ys / h, singular


def arm_setup(R: Mat, p: Vec, geo: SRSGeometry, ops: Ops) -> ArmSetup:
    """θ4 and the reference shoulder rotation of both elbow signs, for a pose ``(R, p)`` in the world frame."""
    R, p = sy.compose(sy.compose(geo.base_inv, (R, p)), geo.tool_inv)
    w = sy.vsub(p, sy.vscale(geo.d_wt, sy.col(R, 2)))
    x_sw = (w[0], w[1], sy.sub(w[2], geo.d_bs))
    r2 = sy.dot(x_sw, x_sw)
    u = sy.vscale(1.0 / ops.sqrt(ops.fmax(r2, _TINY)), x_sw)
    # 1 ∓ cos θ4 from the distances themselves (not from a rounded cos θ4 near ±1), snapped to 0 within rounding
    k = 2.0 * geo.d_se * geo.d_ew
    stretch = (geo.d_se + geo.d_ew) ** 2 - r2  # k (1 − cos θ4)
    fold = r2 - (geo.d_se - geo.d_ew) ** 2  # k (1 + cos θ4)
    valid = (stretch >= -EPS * k) * (fold >= -EPS * k)
    stretch = ops.where(stretch < ELBOW_TOL * k, 0.0, stretch)
    fold = ops.where(fold < ELBOW_TOL * k, 0.0, fold)
    total = stretch + fold  # = 2k before the snap
    c4, s4 = (fold - stretch) / total, 2.0 * ops.sqrt(stretch * fold) / total
    t4 = ops.atan2(s4, c4)
    c1, s1, ref_singular = reference_azimuth(x_sw, ops)
    # elevation of x_sw from the vertical, in the plane of azimuth θ1⁰
    hz = sy.lin((c1, x_sw[0]), (s1, x_sw[1]))
    rz = ops.sqrt(ops.fmax(hz * hz + x_sw[2] * x_sw[2], _TINY))
    sa, ca_ = hz / rz, x_sw[2] / rz
    Rz1 = sy.rot_z(c1, s1)
    elbows = []
    for sign in (1.0, -1.0):
        s4e = sy.mul(sign, s4)
        v0, v1 = sy.mul(-geo.d_ew, s4e), sy.add(geo.d_se, sy.mul(geo.d_ew, c4))
        nv = ops.sqrt(ops.fmax(v0 * v0 + v1 * v1, _TINY))
        sp, cp = v0 / nv, v1 / nv
        # θ2⁰ = atan2(hz, z) - atan2(v0, v1)
        M0 = sy.matmul(Rz1, rot_y(ca_ * cp + sa * sp, sa * cp - ca_ * sp))
        elbows.append((sy.mul(sign, t4), c4, s4e, M0))
    elbow_singular = ops.fabs(s4) < SINGULAR_TOL
    return ArmSetup(R, u, tuple(elbows), valid, either(ref_singular, elbow_singular, ops))


# ---- the ψ-dependent part ---------------------------------------------------


def zyz(M: Mat, dcol: tuple[Scalar, Scalar], ops: Ops) -> tuple[Scalar, Scalar, Scalar, Scalar]:
    r"""ZYZ angles ``(a, b, c, singular)`` of :math:`M = R_z(a) R_y(b) R_z(c)` with b ∈ [0, π].

    ``dcol`` is :math:`\partial_\psi (M_{02}, M_{12})`: where
    :math:`|\sin b| < ` ``SINGULAR_TOL`` it gives a its limit for increasing ψ
    (0 if it vanishes too). b and c follow from a:
    :math:`b = \mathrm{atan2}(\cos a\,M_{02} + \sin a\,M_{12}, M_{22})`,
    :math:`c = \mathrm{atan2}(\cos a\,M_{10} - \sin a\,M_{00}, \cos a\,M_{11} - \sin a\,M_{01})`.
    """
    x, y = M[0][2], M[1][2]
    singular = x * x + y * y < SINGULAR_TOL**2
    x, y = ops.where(singular, dcol[0], x), ops.where(singular, dcol[1], y)
    flat = x * x + y * y < _TINY
    x, y = ops.where(flat, 1.0, x), ops.where(flat, 0.0, y)
    h = ops.sqrt(x * x + y * y)
    ca_, sa = x / h, y / h
    a = trig.angle(y, x, ops)
    b = trig.angle(ca_ * M[0][2] + sa * M[1][2], M[2][2], ops)
    c = trig.angle(ca_ * M[1][0] - sa * M[0][0], ca_ * M[1][1] - sa * M[0][1], ops)
    return a, b, c, singular


def flip(a: Scalar, b: Scalar, c: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    """The other sign of a ZYZ triple: (a + π, −b, c + π), all in (−π, π]."""
    return trig.flip(a, ops), ops.where(b < np.pi, -b, b), trig.flip(c, ops)


def branch_signs(k: int) -> tuple[int, int, int]:
    """(shoulder, elbow, wrist) indices 0 (angle >= 0) or 1 (angle < 0) of public branch ``k``."""
    return (k >> 2) & 1, (k >> 1) & 1, k & 1
