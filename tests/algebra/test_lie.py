"""qpik.algebra.lie: SO(3)/SE(3) logs against scipy and mink, their Jacobians against finite differences."""

from __future__ import annotations

import casadi as ca
import mink
import numpy as np
from conftest import SEEDS, fd
from hypothesis import given, settings
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from qpik.algebra.lie import se3_ljacinv_expr, se3_log_expr, so3_log

_X, _XI = ca.SX.sym("X", 4, 4), ca.SX.sym("xi", 6)
SE3_LOG = ca.Function("se3_log", [_X], [se3_log_expr(_X)])
SE3_LJACINV = ca.Function("se3_ljacinv", [_XI], [se3_ljacinv_expr(_XI)])


def se3_log(T: np.ndarray) -> np.ndarray:
    """qpik's SE(3) log (6,) of a pose (4, 4), evaluated."""
    return np.asarray(SE3_LOG(T)).ravel()


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """The reference exponential: scipy's matrix exponential of the twist [ρ; ω] as a 4 × 4 matrix."""
    H = np.zeros((4, 4))
    H[:3, :3] = [[0.0, -xi[5], xi[4]], [xi[5], 0.0, -xi[3]], [-xi[4], xi[3], 0.0]]
    H[:3, 3] = xi[:3]
    return expm(H)


# rotation angles of the twists drawn for the SE(3) tests: 0, the series/closed-form switch at 0.2, near π
ANGLES = (0.0, 1e-12, 1e-8, 1e-5, 1e-3, 0.05, 0.2 - 1e-9, 0.2, 0.2 + 1e-9, 0.5, 1.0, 2.0, 3.0, np.pi - 1e-3)
NEAR_PI = (np.pi - 1e-7, np.pi - 1e-10, np.pi)


def _twists(seed: int, angles: tuple[float, ...]) -> np.ndarray:
    """(N, 6) twists [ρ; θ u]: per angle 3 random axes u and translations ρ (|ρ| up to ~2 m), plus 10 uniform."""
    rng = np.random.default_rng(seed)
    theta = np.concatenate([np.repeat(angles, 3), rng.uniform(0.0, np.pi, 10)])
    u = rng.normal(size=(theta.size, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return np.hstack([rng.normal(size=(theta.size, 3)), theta[:, None] * u])


def test_so3_log_matches_scipy_everywhere():
    rng = np.random.default_rng(7)
    rots = list(Rotation.random(3000, random_state=1).as_matrix())
    # near 0, near π (both sides) and exactly π
    for theta in (0.0, 1e-12, 1e-8, 1e-5, 1e-3, np.pi - 1e-3, np.pi - 1e-7, np.pi - 1e-10, np.pi):
        for _ in range(20):
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            rots.append(Rotation.from_rotvec(theta * u).as_matrix())
    for R in rots:
        got = so3_log(R)
        want = Rotation.from_matrix(R).as_rotvec()
        theta = np.linalg.norm(want)
        if theta > np.pi - 1e-6:  # ±π u are the same rotation: compare the rotations and the angle
            np.testing.assert_allclose(Rotation.from_rotvec(got).as_matrix(), R, atol=1e-9)
            assert abs(np.linalg.norm(got) - theta) < 1e-9
        else:
            np.testing.assert_allclose(got, want, atol=1e-12)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_se3_log_inverts_expm_and_matches_mink(seed):
    """log(expm(ξ^)) = ξ for |ω| < π (the principal log), = mink's SE3.log; near and at π: expm(log T) = T."""
    for xi in _twists(seed, ANGLES):
        T = se3_exp(xi)
        got = se3_log(T)
        np.testing.assert_allclose(
            got, xi, atol=1e-12 * (1.0 + np.linalg.norm(xi[:3])) / (np.pi - np.linalg.norm(xi[3:]))
        )
        np.testing.assert_allclose(got, mink.SE3.from_matrix(T).log(), atol=1e-11)
    for xi in _twists(seed, NEAR_PI)[: 3 * len(NEAR_PI)]:  # ±π u are the same rotation: compare the poses
        T = se3_exp(xi)
        got = se3_log(T)
        assert abs(np.linalg.norm(got[3:]) - np.linalg.norm(xi[3:])) < 1e-9
        np.testing.assert_allclose(se3_exp(got), T, atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_se3_ljacinv_matches_finite_differences(seed):
    """Jl⁻¹(ξ) = ∂ log(exp(δ) exp(ξ))/∂δ and Jr⁻¹(ξ) = Jl⁻¹(−ξ) = ∂ log(exp(ξ) exp(δ))/∂δ at δ = 0 (mink's
    ``jlog`` of exp(ξ) is the latter), by central differences of the log (checked above) with scipy's expm."""
    for xi in _twists(seed, ANGLES):
        T = se3_exp(xi)
        left = fd(lambda d, T=T: se3_log(se3_exp(d) @ T), np.zeros(6))
        right = fd(lambda d, T=T: se3_log(T @ se3_exp(d)), np.zeros(6))
        scale = 1.0 + np.linalg.norm(xi[:3])
        np.testing.assert_allclose(np.asarray(SE3_LJACINV(xi)), left, atol=1e-8 * scale)
        np.testing.assert_allclose(np.asarray(SE3_LJACINV(-xi)), right, atol=1e-8 * scale)
