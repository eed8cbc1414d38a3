r"""Closed-form IK of an S-R-S arm (KUKA iiwa type) in the arm angle ψ: 8 branches.

Method of Shimizu et al. 2008, written for the DH table of the catalog arm ``iiwa14``
(standard DH, a = 0, α = (−π/2, π/2, π/2, −π/2, −π/2, π/2, 0), d = (d_bs, 0,
d_se, 0, d_ew, 0, d_wt)). For this table the chain factors as

.. math::

    R = M_s\,R_y(-\theta_4)\,M_w,\qquad M_s = R_z(\theta_1)R_y(\theta_2)R_z(\theta_3) = {}^0R_3\,R_x(\pi/2)^T,
    \qquad M_w = R_z(\theta_5)R_y(\theta_6)R_z(\theta_7) = {}^4R_7,

    x_{sw} = W - S = M_s\,(-d_{ew}\sin\theta_4,\ 0,\ d_{se} + d_{ew}\cos\theta_4)^T,

with shoulder :math:`S = (0, 0, d_{bs})`, wrist :math:`W = p - d_{wt} R e_z`,
elbow :math:`E = S + M_s (0, 0, d_{se})`, all in DH frame 0 (a world pose is
first mapped through the chain's constant ``base`` and ``tool`` transforms). Both spherical joints
are ZYZ Euler triples; the elbow is a rotation about the y axis.

**Elbow.** :math:`\cos\theta_4 = (|x_{sw}|^2 - d_{se}^2 - d_{ew}^2)/(2 d_{se} d_{ew})`,
two signs. Computed from :math:`k(1 - \cos\theta_4) = (d_{se} + d_{ew})^2 - |x_{sw}|^2` and
:math:`k(1 + \cos\theta_4) = |x_{sw}|^2 - (d_{se} - d_{ew})^2` (:math:`k = 2 d_{se} d_{ew}`), which keep
their precision near the stretched and folded elbow where :math:`\cos\theta_4` itself rounds to ±1.

**Reference plane and arm angle.** The reference configuration is the
*virtual* one with θ3 = 0 that reaches the same wrist point with the same θ4 and
has joint 1 turned toward the wrist: :math:`\theta_1^0 = \mathrm{atan2}(y_{sw}, x_{sw})`,
:math:`\theta_2^0 = \mathrm{atan2}(\sqrt{x_{sw}^2 + y_{sw}^2}, z_{sw})
- \mathrm{atan2}(-d_{ew}\sin\theta_4, d_{se} + d_{ew}\cos\theta_4)`,
:math:`M_s^0 = R_z(\theta_1^0) R_y(\theta_2^0)`. Its arm plane is the vertical
plane through S and W (the plane of :math:`u_{sw}` and the base z axis); the
elbow lies on the side of the S–W line toward +z for θ4 < 0 and away from it
for θ4 > 0. The arm angle ψ rotates the whole arm about
:math:`u_{sw} = x_{sw}/|x_{sw}|` (right hand):

.. math::

    M_s(\psi) = R_\psi M_s^0 = A_s\sin\psi + B_s\cos\psi + C_s,\quad
    A_s = [u]_\times M_s^0,\ B_s = -[u]_\times^2 M_s^0,\ C_s = u u^T M_s^0,

    M_w(\psi) = R_y(\theta_4) M_s(\psi)^T R = A_w\sin\psi + B_w\cos\psi + C_w,\quad
    A_w = R_y(\theta_4) A_s^T R \text{ (same for } B, C).

:meth:`SRSSolver.branches` evaluates :math:`R_\psi` by Rodrigues' formula; the
coefficient form (Shimizu et al. 2008) serves the feasible intervals (:mod:`qpik.analytic.srs_intervals`).

Equivalently, ψ is the signed angle about :math:`u_{sw}` from the horizontal
normal of the reference plane, :math:`n^0 = M_s^0 e_y = (-\sin\theta_1^0, \cos\theta_1^0, 0)`,
to the joint-4 axis direction :math:`n = M_s e_y` (the normal of the arm plane
S–E–W); this is how :meth:`SRSSolver.parameter` computes it. Because it uses the
joint-4 axis and not the elbow point, ψ stays defined when the elbow is
stretched (θ4 = 0), and the two elbow branches then coincide.

**Joints.** From :math:`M = R_z(a) R_y(b) R_z(c)` (:func:`zyz`):
tan-type :math:`a = \mathrm{atan2}(\sigma M_{12}, \sigma M_{02})` (θ1, θ5) and
:math:`c = \mathrm{atan2}(\sigma M_{21}, -\sigma M_{20})` (θ3, θ7); cos-type
:math:`\cos b = M_{22}` (θ2, θ6), b of the sign σ. In code c is taken from the
remainder :math:`R_z(a)^T M = R_y(b) R_z(c)` (row 1 is :math:`(\sin c, \cos c, 0)`),
which equals the tan form but stays exact near a singularity.

**Branches** (public ids 0–7)::

    branch = 4·[θ2 < 0] + 2·[θ4 < 0] + [θ6 < 0]

so bit 2 is the shoulder sign, bit 1 the elbow sign, bit 0 the wrist sign
(branch 0: θ2, θ4, θ6 ≥ 0). The shoulder pair differs by
(θ1 + π, −θ2, θ3 + π), the wrist pair by (θ5 + π, −θ6, θ7 + π).

**Singular cases** (defined results, ``singular`` flag set, every valid
branch still reaches the pose):

- *shoulder*, :math:`|\sin\theta_2|` < ``SINGULAR_TOL``: only θ1 ± θ3 is determined. θ1 is
  set to its limit as ψ increases through the singular value,
  :math:`\theta_1 = \mathrm{atan2}(\sigma\,\partial_\psi M_{12}, \sigma\,\partial_\psi M_{02})`
  (0 if that vanishes too), and θ3 takes the rest (remainder formula).
- *wrist*, :math:`|\sin\theta_6|` < ``SINGULAR_TOL``: the same for θ5 (limit) and θ7 (rest).
- *wrist centre on the base z axis* (:math:`\sqrt{x_{sw}^2+y_{sw}^2} < ` ``SINGULAR_TOL``
  :math:`|x_{sw}|`): the reference plane is undefined and ψ jumps with the
  azimuth of :math:`x_{sw}`. The formulas above are kept (they hold for any
  nonzero azimuth, however small); only an exactly vertical :math:`x_{sw}` uses
  the fallback :math:`\theta_1^0 = 0` (reference plane = base x–z plane).
- *elbow stretched or folded*, :math:`1 \mp \cos\theta_4 <` ``ELBOW_TOL`` (the rounding of the pose
  alone reaches that): θ4 := 0 (π), the two elbow branches coincide; ψ is still defined
  (joint-4 axis, above).

An unreachable pose (:math:`|x_{sw}| > d_{se} + d_{ew}` or
:math:`< |d_{se} - d_{ew}|`) gives ``valid = 0`` on every branch; cos θ4 is
clamped so that q stays finite (1 ∓ cos θ4 at 0).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.solver import AnalyticSolver, Branches

if TYPE_CHECKING:
    from qpik.analytic.intervals import ParameterSets
    from qpik.robots.robot import Robot

from qpik.analytic.srs_geometry import (
    SRSGeometry,
    arm_setup,
    branch_signs,
    either,
    flip,
    reference_azimuth,
    rot_y,
    rotation_about,
    zyz,
)


class SRSSolver(AnalyticSolver):
    """Closed-form IK of an S-R-S arm (``iiwa14``) in the arm angle ψ; see the module docstring.

    Branch ids 0–7: ``branch = 4·[θ2 < 0] + 2·[θ4 < 0] + [θ6 < 0]``.
    """

    kind = "srs"
    param_name = "psi"
    branch_ids = tuple(range(8))

    def __init__(self, robot: Robot, sets: Callable[[AnalyticSolver], ParameterSets] | None = None):
        super().__init__(robot, sets)
        self.geometry = SRSGeometry.from_chain(self.table)

    def table_branches(self, R: Mat, p: Vec, param: Scalar, ops: Ops) -> Branches:
        r"""All 8 branches at arm angle ``param`` (rad) for the pose ``(R, p)`` (world frame).

        :math:`M_s = R_\psi M_s^0`, :math:`M_w = R_y(\theta_4) M_s^T R`; the ψ-derivatives
        used at singular points are :math:`\partial_\psi M_s = [u]_\times M_s` and
        :math:`\partial_\psi M_w e_z = -R_y(\theta_4) M_s^T (u \times R e_z)`.
        """
        setup = arm_setup(R, p, self.geometry, ops)
        u = setup.u
        Rpsi = rotation_about(u, ops.sin(param), ops.cos(param))
        u_x_z = sy.cross(u, sy.col(setup.R, 2))
        per_elbow = []
        for e, (t4, c4, s4, M0) in enumerate(setup.elbows):
            Ms = sy.matmul(Rpsi, M0)
            Mw = setup.wrist(e, Ms)
            ds = sy.cross(u, sy.col(Ms, 2))
            dw = sy.matvec(rot_y(c4, s4), sy.matvec(sy.transpose(Ms), u_x_z))
            *shoulder, s_sing = zyz(Ms, (ds[0], ds[1]), ops)
            *wrist, w_sing = zyz(Mw, (sy.neg(dw[0]), sy.neg(dw[1])), ops)
            both = (tuple(shoulder), flip(*shoulder, ops)), (tuple(wrist), flip(*wrist, ops))
            per_elbow.append((t4, *both, either(s_sing, w_sing, ops)))
        q, valid, singular = [], [], []
        for k in self.branch_ids:
            i_s, i_e, i_w = branch_signs(k)
            t4, shoulder, wrist, sing = per_elbow[i_e]
            q.append([*shoulder[i_s], t4, *wrist[i_w]])
            valid.append(setup.valid)
            singular.append(either(sing, setup.singular, ops))
        return Branches(q, valid, singular)

    def table_parameter_expr(self, q: list[Scalar], ops: Ops) -> tuple[Scalar, Scalar]:
        r"""Arm angle ψ (rad) and branch id of the configuration ``q`` (7 scalars) of the table.


        ψ = signed angle about :math:`u_{sw}` from :math:`n^0` to the joint-4 axis
        :math:`n = M_s e_y` (module docstring), so that ``ik(fk(q), ψ)`` holds q in
        branch ``4·[θ2<0] + 2·[θ4<0] + [θ6<0]``.
        """
        g = self.geometry
        C, S = [ops.cos(x) for x in q[:4]], [ops.sin(x) for x in q[:4]]
        Ms = sy.matmul(sy.matmul(sy.rot_z(C[0], S[0]), rot_y(C[1], S[1])), sy.rot_z(C[2], S[2]))
        x_sw = sy.matvec(Ms, (-g.d_ew * S[3], 0.0, g.d_se + g.d_ew * C[3]))
        c1, s1, _ = reference_azimuth(x_sw, ops)
        n0 = (-s1, c1, 0.0)
        n = sy.col(Ms, 1)
        sin_psi = sy.dot(x_sw, sy.cross(n0, n)) / ops.sqrt(sy.dot(x_sw, x_sw))
        psi = ops.wrap(ops.atan2(sin_psi, sy.dot(n0, n)))
        branch = sum(ops.where(q[j] < 0, float(w), 0.0) for j, w in ((1, 4), (3, 2), (5, 1)))
        return psi, branch
