r"""Closed-form IK of the offset-shoulder arm (Nammoto & Kosuge 2012): 16 branches per δ.

The arm (``nammoto7``) has standard DH parameters (Nammoto & Kosuge 2012, Table 1)

=====  ==============  ======  ======  ======
joint  θ               α       d       a
=====  ==============  ======  ======  ======
1      θ1              π/2     d1      a1
2      θ2              −π/2    0       0
3      θ3              π/2     d3      0
4      θ4 + π/2        −π/2    0       0
5      θ5              π/2     −d5     0
6      θ6 + π          π/2     0       0
7      θ7              0       −d7     0
=====  ==============  ======  ======  ======

Axes 5, 6, 7 meet at the wrist centre :math:`w = p + d_7 b` (eq. 5; ``b`` is the
third column of the end-effector rotation). The redundancy parameter is the
offset angle δ of joint 1 from the azimuth of the wrist centre (eq. 4),

.. math:: \theta_1 = \mathrm{atan2}(w_y, w_x) + \delta \quad(\text{index }1),\qquad
          \theta_1[2] = \theta_1[1] + \pi .

With :math:`w' = A_0^1(\theta_1)\,w = (r\cos\delta - a_1,\; w_z - d_1,\; r\sin\delta)`
(:math:`r = \sqrt{w_x^2 + w_y^2}`; for θ1[2] replace δ by δ + π):

- elbow (eq. 9): :math:`\sin\theta_4 = (|w'|^2 - d_3^2 - d_5^2) / (2 d_3 d_5)`; θ4[1] has
  :math:`\cos\theta_4 \ge 0`, θ4[2] = π − θ4[1]; :math:`|\cos\theta_4| = |(w''_x, w''_y)| / d_5`
  (below), which keeps full precision near the stretched elbow;
- shoulder (eq. 11, atan2 form of Sabharwal 2021): :math:`-\sin\theta_2\, w'_x + \cos\theta_2\, w'_y
  = d_3 + d_5 \sin\theta_4`; θ2[1] is the root with :math:`w''_x \ge 0`, θ2[3] the other;
- θ3 (eq. 13) from :math:`w'' = A_1^2(\theta_2)\,w' = d_5 (\cos\theta_3\cos\theta_4,\;
  \sin\theta_3\cos\theta_4,\; \cdot)`: ``atan2(±w''_y, ±w''_x)`` with the sign of cos θ4;
- wrist: with :math:`M = (R_0^4)^T R`, :math:`M_{:,2} = (-c_5 s_6, -s_5 s_6, c_6)`, so
  θ5[1] = atan2(−M12, −M02) (eq. 24; index 1 has sin θ6 ≥ 0), θ5[2] = θ5[1] − π, and
  with :math:`N = R_5(\theta_5)^T M = R_6 R_7`: θ6 = atan2(−N02, N12),
  θ7 = atan2(N20, N21) (replaces the acos + sign test of eq. 31 by an atan2 of
  rotation entries; same angle).

Branch No. 1–16 follow Nammoto & Kosuge 2012, Table 2, with its row 8 read as θ1[1]
(its Table 4 shows that row with θ1[1] = 1.12): rows 1–8 use θ1[1], rows 9–16 θ1[2];
within each half the (θ2, θ3, θ4) index runs 1, 1, 2, 2, 3, 3, 4, 4 and the (θ5, θ6, θ7)
index 1, 2, 1, 2, ...

Singular cases (flag ``singular``, results defined and finite, never NaN):

- wrist centre on the base z axis (r < ``SINGULAR_TOL``): δ is undefined; atan2(wy, wx) := 0
  there (below ``ZERO``), so δ is then θ1 itself;
- elbow stretched or folded (:math:`|\cos\theta_4|` < ``SINGULAR_TOL``): θ4 is a double root and θ3 does
  not move the wrist; θ3 := 0 (resp. ±π for the π-shifted indices) when
  :math:`|(w''_x, w''_y)| <` ``ZERO``;
- shoulder (:math:`|w''_x|` < ``SINGULAR_TOL``, the wrist in the plane of the joint-2 and joint-3
  axes): θ2 is a double root;
- wrist (:math:`|\sin\theta_6|` < ``SINGULAR_TOL``): θ5 and θ7 turn about the same axis; θ5 keeps the
  value of the continuous formula (0 below ``ZERO``) and θ7 takes the rest, so the
  pose is reproduced exactly.

``valid`` is 0 where :math:`|\sin\theta_4| > 1` or the shoulder equation has no root (beyond 1e-12):
the branch does not reach the pose; its row is then the clamped, finite solution.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.solver import AnalyticSolver, Branches
from qpik.analytic.trig import EPS, angle, flip, solve_cos_sin_cs
from qpik.core.errors import NoClosedFormError
from qpik.robots.recognize import PATTERNS

if TYPE_CHECKING:
    from qpik.analytic.intervals import ParameterSets
    from qpik.robots.robot import Robot

PI = np.pi
SINGULAR_TOL = 1e-7
"""Distance (m, or cosine/sine) to a singular case below which ``singular`` is set."""
ZERO = 1e-13
"""Below this an atan2 argument pair is treated as (0, 0) and the documented default is used."""

ALPHA = PATTERNS["offset_shoulder"].alpha
OFFSET = PATTERNS["offset_shoulder"].offset


@dataclass(frozen=True)
class OffsetShoulderGeometry:
    """Link lengths (m) of Nammoto & Kosuge 2012, Table 3: a1, d1, d3, d5, d7 (DH d5 = −d5, d7 = −d7)."""

    a1: float
    d1: float
    d3: float
    d5: float
    d7: float

    @classmethod
    def of(cls, chain) -> OffsetShoulderGeometry:
        """Read and check the lengths of a :class:`~qpik.robots.dh.DHChain` shaped as in Nammoto & Kosuge 2012."""
        a, d = np.asarray(chain.a, float), np.asarray(chain.d, float)
        ok = (
            chain.convention == "standard"
            and chain.dof == 7
            and np.allclose(chain.alpha, ALPHA, atol=1e-12)
            and np.allclose(chain.offset, OFFSET, atol=1e-12)
            and np.allclose(a[1:], 0.0, atol=1e-12)
            and np.allclose(d[[1, 3, 5]], 0.0, atol=1e-12)
            and a[0] >= 0
            and d[2] > 0
            and -d[4] > 0
            and -d[6] >= 0
        )
        if not ok:
            raise NoClosedFormError(
                "OffsetShoulderSolver: the chain is not the offset-shoulder arm of Nammoto & Kosuge 2012 "
                "(standard DH, alpha = (pi/2, -pi/2, pi/2, -pi/2, pi/2, pi/2, 0), offsets (0, 0, 0, pi/2, 0, pi, 0), "
                "a = (a1, 0, ...), d = (d1, 0, d3, 0, -d5, 0, -d7) with d3, d5 > 0)"
            )
        return cls(float(a[0]), float(d[0]), float(d[2]), float(-d[4]), float(-d[6]))


class OffsetShoulderSolver(AnalyticSolver):
    """All 16 branches of the offset-shoulder arm of Nammoto & Kosuge 2012 at a given δ (rad)."""

    kind = "offset_shoulder"
    param_name = "delta"
    branch_ids = tuple(range(1, 17))

    def __init__(self, robot: Robot, sets: Callable[[AnalyticSolver], ParameterSets] | None = None):
        super().__init__(robot, sets)
        self.geometry = OffsetShoulderGeometry.of(self.table)
        base, tool = np.asarray(self.table.base, float), np.asarray(self.table.tool, float)
        self._base_inv = sy.frame_of(np.linalg.inv(base))  # identity folds away
        self._tool_inv = sy.frame_of(np.linalg.inv(tool))

    def to_flange(self, R: Mat, p: Vec) -> tuple[Mat, Vec]:
        """A world pose of the end effector (R, p) as the flange's pose in the chain's frame 0."""
        return sy.compose(sy.compose(self._base_inv, (R, p)), self._tool_inv)

    # ---- the one source -----------------------------------------------------

    def table_branches(self, R: Mat, p: Vec, param: Scalar, ops: Ops) -> Branches:
        """Eqs. (4)–(32) of Nammoto & Kosuge 2012 for the world pose (R, p) and δ = ``param`` (rad).

        Rotations are applied from cosines and sines (the only trig calls are
        cos δ, sin δ and one atan2 per output angle): :math:`M = R_4^T R_3^T R_2^T R_1^T R`
        is built joint by joint, each partial product shared by the branches
        that share those joints.
        """
        R, p = self.to_flange(R, p)
        w = sy.vadd(p, sy.vscale(self.geometry.d7, sy.col(R, 2)))  # eq. (5)
        r = ops.sqrt(w[0] * w[0] + w[1] * w[1])
        far = r > ZERO
        rs = ops.fmax(r, ZERO)
        cw, sw = ops.where(far, w[0] / rs, 1.0), ops.where(far, w[1] / rs, 0.0)  # atan2(wy, wx) := 0 on the axis
        cd, sd = ops.cos(param), ops.sin(param)
        c1, s1 = cw * cd - sw * sd, sw * cd + cw * sd  # θ1[1] = atan2(wy, wx) + δ (eq. 6)
        th1 = ops.wrap(ops.where(far, ops.atan2(w[1], w[0]), 0.0) + param)
        on_axis = r < SINGULAR_TOL
        q, valid, singular = [], [], []
        for th1_k, c1_k, s1_k in ((th1, c1, s1), (flip(th1, ops), -c1, -s1)):  # θ1[2] = θ1[1] + π (eq. 7)
            A1 = self._back(0, c1_k, s1_k, R)
            for th2, th3, th4, M, ok, arm_sing in self._arm(w, A1, c1_k, s1_k, ops):
                for th5, th6, th7, wrist_sing in self._wrist(M, ops):
                    q.append([th1_k, th2, th3, th4, th5, th6, th7])
                    valid.append(ok)
                    singular.append(ops.fmax(ops.fmax(on_axis, arm_sing), wrist_sing))
        return Branches(q, valid, singular)

    def _back(self, i: int, c: Scalar, s: Scalar, A: Mat) -> Mat:
        """:math:`R_i^T A` with :math:`R_i = R_z(\theta + o_i) R_x(\alpha_i)` of DH joint i (0-based) from cos/sin θ."""
        co, so = sy.snap(np.cos(OFFSET[i])), sy.snap(np.sin(OFFSET[i]))
        cz, sz = sy.sub(sy.mul(c, co), sy.mul(s, so)), sy.add(sy.mul(s, co), sy.mul(c, so))
        Ri = sy.matmul(sy.rot_z(cz, sz), sy.rot_x(sy.snap(np.cos(ALPHA[i])), sy.snap(np.sin(ALPHA[i]))))
        return sy.matmul(sy.transpose(Ri), A)

    def _arm(self, w: Vec, A1: Mat, c1: Scalar, s1: Scalar, ops: Ops) -> list[tuple]:
        """(θ2, θ3, θ4, M = R_4^T..R_1^T R, valid, singular) for indices 1–4 (eqs. 8–22) given θ1."""
        g = self.geometry
        wx1 = c1 * w[0] + s1 * w[1] - g.a1  # w' = A_0^1 w (eq. 8)
        wy1 = w[2] - g.d1
        wz1 = s1 * w[0] - c1 * w[1]
        s4 = (wx1 * wx1 + wy1 * wy1 + wz1 * wz1 - g.d3**2 - g.d5**2) / (2.0 * g.d3 * g.d5)  # eq. (9)
        ok4 = ops.fabs(s4) <= 1.0 + EPS
        s4 = ops.fmin(ops.fmax(s4, -1.0), 1.0)
        # eq. (11) as  −sin θ2 w'x + cos θ2 w'y = d3 + d5 sin θ4 :  θ2[1] (w''x ≥ 0) and θ2[3] (eq. 17)
        roots2 = solve_cos_sin_cs(wy1, -wx1, g.d3 + g.d5 * s4, ops)
        ok = roots2[2] * ok4
        out = []
        for (c2, s2), flipped_first in ((roots2[0], False), (roots2[1], True)):
            A2 = self._back(1, c2, s2, A1)
            wx2 = c2 * wx1 + s2 * wy1  # w'' = A_1^2 w' = d5 (c3 c4, s3 c4, ·) (eq. 12)
            wy2 = -wz1
            rho = ops.sqrt(wx2 * wx2 + wy2 * wy2)  # = d5 |cos θ4|
            big = rho > ZERO
            # θ4[1] (cos ≥ 0), θ4[2] = π − θ4[1] (eqs. 9, 16): |cos θ4| from the lateral wrist offset
            # rather than sqrt(1 − sin²), which loses half the digits near the stretched elbow
            c4 = rho / self.geometry.d5
            th4_1, th4_2 = angle(s4, c4, ops), angle(s4, -c4, ops)
            elbow = c4 < SINGULAR_TOL
            k = 1.0 / ops.fmax(rho, ZERO)
            c3, s3 = ops.where(big, wx2 * k, 1.0), ops.where(big, wy2 * k, 0.0)
            th3 = ops.where(big, angle(wy2, wx2, ops), 0.0)  # eq. (13); θ3 := 0 at the elbow singularity
            sing = ops.fmax(elbow, ops.fabs(wx2) < SINGULAR_TOL)
            th2 = angle(s2, c2, ops)
            # cos θ4 ≥ 0: (θ3, θ4[1]); cos θ4 ≤ 0: (θ3 − π, π − θ4[1]) (eqs. 15, 16, 18, 19, 21, 22)
            pair = [(th3, c3, s3, th4_1, c4), (flip(th3, ops), -c3, -s3, th4_2, -c4)]
            for th3_k, c3_k, s3_k, th4_k, c4_k in pair[::-1] if flipped_first else pair:
                M = self._back(3, c4_k, s4, self._back(2, c3_k, s3_k, A2))
                out.append((th2, th3_k, th4_k, M, ok, sing))
        return out

    def _wrist(self, M: Mat, ops: Ops) -> list[tuple]:
        """(θ5, θ6, θ7, singular) for indices 1 and 2 (eqs. 23–32) from :math:`M = (R_0^4)^T R`."""
        s6 = ops.sqrt(M[0][2] * M[0][2] + M[1][2] * M[1][2])  # |sin θ6|
        big = s6 > ZERO
        k = 1.0 / ops.fmax(s6, ZERO)
        c5, s5 = ops.where(big, -M[0][2] * k, 1.0), ops.where(big, -M[1][2] * k, 0.0)
        th5 = ops.where(big, angle(-M[1][2], -M[0][2], ops), 0.0)  # eq. (24); index 1: sin θ6 ≥ 0
        N02 = c5 * M[0][2] + s5 * M[1][2]  # N = R5(θ5)ᵀ M = R6 R7: N02 = −sin θ6, N12 = M22 = cos θ6
        N20 = s5 * M[0][0] - c5 * M[1][0]  # N20 = sin θ7, N21 = cos θ7
        N21 = s5 * M[0][1] - c5 * M[1][1]
        th7 = angle(N20, N21, ops)
        sing = s6 < SINGULAR_TOL
        return [
            (th5, angle(-N02, M[2][2], ops), th7, sing),
            (flip(th5, ops), angle(N02, M[2][2], ops), flip(th7, ops), sing),  # eqs. (26, 27, 32)
        ]

    # ---- inverse map --------------------------------------------------------

    def table_parameter_expr(self, q: list[Scalar], ops: Ops) -> tuple[Scalar, Scalar]:
        r"""δ (rad) and branch No. (1–16) of the configuration ``q`` (7 scalars) of the table.


        Every configuration has two descriptions, (δ, k) and (δ + π, k ± 8), because
        θ1[2](δ) = θ1[1](δ + π). This returns the one with δ in (−π/2, π/2]: rows 1–8
        when the shoulder offset a1 points toward the wrist side
        (:math:`\cos(\theta_1 - \mathrm{atan2}(w_y, w_x)) > 0`), else rows 9–16.
        The (θ2, θ3, θ4) index follows from the signs of cos θ3 and cos θ4:
        (+, +) → 1, (−, −) → 2, (+, −) → 3, (−, +) → 4 (``w''_x = d5 cos θ3 cos θ4``
        is ≥ 0 for indices 1, 2); the (θ5, θ6, θ7) index is 1 where θ6 ≥ 0.
        """
        Rb, tb = self._base_inv
        t = sy.vadd(sy.matvec(Rb, self.table.frames_expr(q, ops)[5][1]), tb)  # wrist centre (frame 0)
        r = ops.sqrt(t[0] * t[0] + t[1] * t[1])
        phi_w = ops.where(r > ZERO, ops.atan2(t[1], t[0]), 0.0)
        d0 = ops.wrap(q[0] - phi_w)
        second = ops.where(d0 <= -PI / 2, 1.0, ops.where(d0 > PI / 2, 1.0, 0.0))
        delta = ops.where(second > 0.5, ops.wrap(d0 - PI), d0)
        c3, c4 = ops.cos(q[2]) >= 0, ops.cos(q[3]) >= 0
        arm = ops.where(c3, ops.where(c4, 0.0, 2.0), ops.where(c4, 3.0, 1.0))
        branch = 8.0 * second + 2.0 * arm + ops.where(q[5] < 0, 1.0, 0.0) + 1.0
        return delta, branch
