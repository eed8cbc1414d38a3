r"""SO(3) and SE(3) logarithms, pose errors and their Jacobians, as CasADi expressions.

Shared by the QP tasks (:mod:`qpik.control.tasks`) and the NLPs: each is written once
as an SX expression; :func:`so3_log` and :func:`pose_error` are their compiled numeric forms.

Conventions: rotation vectors in rad (θ ∈ [0, π]); twists ``[ρ; ω]`` (m; rad), translation
first, as mink's SE3; the world-frame pose error is :math:`[p^* - p;\ \log(R^* R^T)]`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from qpik.core.validate import finite_array, single_pose
from qpik.native.compiled import Compiled


def log_expr(R: ca.SX) -> ca.SX:
    r"""Rotation vector :math:`\omega = \theta u` (3,) of an SX rotation matrix ``R`` (3, 3), with θ ∈ [0, π].

    :math:`\sin\theta\,u = \mathrm{vee}(R - R^T)/2` and :math:`c = \cos\theta = (\mathrm{tr} R - 1)/2`.
    Away from π (c > −0.9) the vector is :math:`\mathrm{vee}\cdot g(c)` with
    :math:`g(c) = \arccos c/\sqrt{1 - c^2} = \theta/\sin\theta`, below x = 1 − c = 1e-4 its series
    :math:`1 + x/3 + 2x^2/15 + 2x^3/35` (error < 1e-17): written through c, not through :math:`|\mathrm{vee}|`, so that
    it is smooth at θ = 0 to every order (the NLPs and the QP differentiate the pose error at its
    solution; a square root of :math:`|\mathrm{vee}|^2` there has a 0/0 derivative and second derivatives of order
    1/θ). Near π, where vee loses its digits, :math:`\theta = \mathrm{atan2}(\|\mathrm{vee}\|, c)` and
    the axis comes from the symmetric part :math:`(R + R^T)/2 - c\,I = (1 - c)\,u u^T` (its largest
    diagonal column) with the sign of vee. The branches are selections (both are evaluated, and a
    selection's derivative multiplies the unselected branch's by 0, so that one must be finite too):
    the square roots of the near-π branch are taken of their argument's maximum with a bound that
    changes no value where it is selected (1e-300 for :math:`|\mathrm{vee}|^2`, 1 for the axis' scale), and its first
    and second derivatives stay finite at θ = 0.
    """
    w = 0.5 * ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    x = 1.0 - c
    series = 1.0 + x * (1.0 / 3.0 + x * (2.0 / 15.0 + x * 2.0 / 35.0))
    scale = ca.if_else(x < 1e-4, series, ca.acos(ca.fmax(c, -1.0)) / ca.sqrt(ca.fmax(1.0 - c * c, 1e-300)))
    theta = ca.atan2(ca.sqrt(ca.fmax(ca.dot(w, w), 1e-300)), c)
    B = 0.5 * (R + R.T) - c * ca.SX.eye(3)
    b0, b1, b2 = B[0, 0], B[1, 1], B[2, 2]
    first = ca.logic_and(b0 >= b1, b0 >= b2)
    col = ca.if_else(first, B[:, 0], ca.if_else(b1 >= b2, B[:, 1], B[:, 2]))
    bkk = ca.if_else(first, b0, ca.if_else(b1 >= b2, b1, b2))
    u = col / ca.sqrt(ca.fmax(bkk * (1.0 - c), 1.0))  # ≥ (1 − c)²/3 > 1.2 where the branch is selected
    u = ca.if_else(ca.dot(u, w) < 0.0, -u, u)
    return ca.if_else(c > -0.9, w * scale, theta * u)


_SERIES_BELOW = 0.2  # rad: below it the coefficients of the SO(3)/SE(3) Jacobians are Taylor series in θ²


def _coefficient(theta: ca.SX, series: tuple[float, ...], exact: ca.SX) -> ca.SX:
    r"""``exact`` (a function of θ with a removable singularity at 0), or below :data:`_SERIES_BELOW`
    its series :math:`\sum_k a_k \theta^{2k}` (``series`` = a_0..a_4: the θ¹⁰ term is < 1e-16 there)."""
    t2 = theta * theta
    poly = series[-1]
    for a in reversed(series[:-1]):
        poly = a + t2 * poly
    return ca.if_else(theta < _SERIES_BELOW, poly, exact)


def so3_ljacinv_expr(w: ca.SX) -> ca.SX:
    r"""Inverse left Jacobian of SO(3) (3, 3) at the rotation vector ``w`` (3,), rad, :math:`|w| = \theta \le \pi`.

    :math:`J_l^{-1}(\omega) = I - \tfrac12 [\omega]_\times + \beta [\omega]_\times^2`,
    :math:`\beta = (1 - \tfrac{\theta}{2}\cot\tfrac{\theta}{2}) / \theta^2` (smooth up to θ = π, where
    cot = 0). It is :math:`\partial \log(\exp(\delta) R) / \partial \delta` at :math:`\log R = \omega`, and
    the inverse of the SE(3) log's :math:`V` (:func:`se3_log_expr`).
    """
    theta = ca.sqrt(ca.dot(w, w))
    half = 0.5 * theta
    beta = _coefficient(
        theta,
        (1 / 12, 1 / 720, 1 / 30240, 1 / 1209600, 1 / 47900160),
        (1.0 - half * ca.cos(half) / ca.sin(half)) / (theta * theta),
    )
    W = ca.skew(w)
    return ca.SX.eye(3) - 0.5 * W + beta * ca.mtimes(W, W)


def se3_log_expr(T: ca.SX) -> ca.SX:
    r"""Twist :math:`\xi = [\rho; \omega]` (6,) (m; rad) with :math:`\exp(\hat\xi) = T`, of an SX pose ``T`` (≥3, 4).

    :math:`\omega = \log R` (:func:`log_expr`, θ ∈ [0, π]) and :math:`\rho = J_l^{-1}(\omega)\, t`
    (:func:`so3_ljacinv_expr`; ``t`` the translation). Tangent order [translation; rotation], as mink's SE3.
    """
    w = log_expr(T[:3, :3])
    return ca.vertcat(ca.mtimes(so3_ljacinv_expr(w), T[:3, 3]), w)


def se3_ljacinv_expr(xi: ca.SX) -> ca.SX:
    r"""Inverse left Jacobian of SE(3) (6, 6) at the twist ``xi`` = [ρ; ω] (6,), :math:`|\omega| \le \pi`.

    :math:`J_l^{-1}(\xi) = \partial \log(\exp(\delta) \exp(\xi)) / \partial\delta` at δ = 0, and
    the inverse right Jacobian :math:`J_r^{-1}(\xi) = J_l^{-1}(-\xi) = \partial \log(\exp(\xi)\exp(\delta))
    / \partial\delta` (mink's ``jlog`` of the pose exp(ξ)). With :math:`J_l^{-1}(\omega)` of SO(3),
    :math:`J_l^{-1}(\xi) = \begin{bmatrix} J_l^{-1} & -J_l^{-1} Q J_l^{-1} \\ 0 & J_l^{-1} \end{bmatrix}`,
    with Barfoot's (State Estimation for Robotics, eq. 7.86), :math:`V = [\rho]_\times`,
    :math:`W = [\omega]_\times`:
    :math:`Q = \tfrac12 V + B (WV + VW + WVW) + C (WWV + VWW - 3 WVW) + D (WVWW + WWVW)`,
    :math:`B = (\theta - \sin\theta)/\theta^3`, :math:`C = (\theta^2 + 2\cos\theta - 2)/(2\theta^4)`,
    :math:`D = (2\theta - 3\sin\theta + \theta\cos\theta)/(2\theta^5)` (series near 0).
    """
    rho, w = xi[:3], xi[3:]
    theta = ca.sqrt(ca.dot(w, w))
    s, c, t2 = ca.sin(theta), ca.cos(theta), theta * theta
    B = _coefficient(theta, (1 / 6, -1 / 120, 1 / 5040, -1 / 362880, 1 / 39916800), (theta - s) / (t2 * theta))
    C = _coefficient(
        theta, (1 / 24, -1 / 720, 1 / 40320, -1 / 3628800, 1 / 479001600), (t2 + 2.0 * c - 2.0) / (2.0 * t2 * t2)
    )
    D = _coefficient(
        theta,
        (1 / 120, -1 / 2520, 1 / 120960, -1 / 9979200, 1 / 1245404160),
        (2.0 * theta - 3.0 * s + theta * c) / (2.0 * t2 * t2 * theta),
    )
    V, W = ca.skew(rho), ca.skew(w)
    WV, VW = ca.mtimes(W, V), ca.mtimes(V, W)
    WVW = ca.mtimes(WV, W)
    Q = 0.5 * V + B * (WV + VW + WVW) + C * (ca.mtimes(W, WV) + ca.mtimes(VW, W) - 3.0 * WVW)
    Q = Q + D * (ca.mtimes(WVW, W) + ca.mtimes(W, WVW))
    Ji = so3_ljacinv_expr(w)
    return ca.vertcat(ca.horzcat(Ji, -ca.mtimes([Ji, Q, Ji])), ca.horzcat(ca.SX.zeros(3, 3), Ji))


def pose_error_expr(T: ca.SX, pose_: ca.SX) -> ca.SX:
    r"""World-frame pose error :math:`[p^* - p;\ \log(R^* R^T)]` (6,) of ``pose_`` toward ``T`` (SX, (≥3, 4) each)."""
    return ca.vertcat(T[:3, 3] - pose_[:3, 3], log_expr(ca.mtimes(T[:3, :3], pose_[:3, :3].T)))


_NUMERIC: dict[str, Compiled] = {}


def _numeric(name: str) -> Compiled:
    """The compiled numeric form of :func:`log_expr` (``"log"``) or :func:`pose_error_expr` (``"pose_error"``)."""
    fn = _NUMERIC.get(name)
    if fn is None:
        if name == "log":
            R = ca.SX.sym("R", 3, 3)
            fn = Compiled(ca.Function("so3_log", [R], [log_expr(R)]))
        else:
            T, C = ca.SX.sym("T", 4, 4), ca.SX.sym("C", 4, 4)
            fn = Compiled(ca.Function("pose_error", [T, C], [pose_error_expr(T, C)]))
        _NUMERIC[name] = fn
    return fn


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) of a rotation matrix ``R`` (3, 3): :func:`log_expr`, compiled.

    Raises:
        InputError: not a (3, 3) finite array; :class:`~qpik.core.errors.RotationError` if not a rotation.
    """
    T = np.eye(4)
    T[:3, :3] = finite_array(R, "R", (3, 3))
    return _numeric("log")(single_pose(T, "R")[:3, :3].copy())[0].copy()


def pose_error(target: np.ndarray, current: np.ndarray) -> np.ndarray:
    r"""World-frame pose error :math:`[p^* - p;\ \log(R^* R^T)]` (6,) of ``current`` toward ``target`` (4, 4).

    Raises:
        InputError: a pose that is not a (4, 4) homogeneous pose with a rotation block (``qpik.core.validate.pose``).
    """
    return _numeric("pose_error")(single_pose(target, "target"), single_pose(current, "current"))[0].copy()


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Angle (rad, in [0, π]) of rotation matrices R (..., 3, 3)."""
    s = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    return np.arctan2(np.linalg.norm(s, axis=-1), np.trace(R, axis1=-2, axis2=-1) - 1.0)


def tracking_errors(pose: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Position error :math:`\lVert p_d - p \rVert` (m) and orientation error :math:`\angle(R_d^\top R)` (rad, in
    [0, π], :func:`rotation_angle`) of poses (..., 4, 4) against targets (..., 4, 4)."""
    e_pos = np.linalg.norm(target[..., :3, 3] - pose[..., :3, 3], axis=-1)
    M = np.swapaxes(target[..., :3, :3], -1, -2) @ pose[..., :3, :3]
    return e_pos, rotation_angle(M)
