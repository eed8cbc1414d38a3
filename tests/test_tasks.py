"""Tasks of the QP: cost pieces vs direct evaluation, SO(3)/SE(3) log vs scipy/mink, gradients vs finite differences."""

from __future__ import annotations

import casadi as ca
import mink
import numpy as np
import pytest
from conftest import ARMS, SEEDS, fd, random_q
from hypothesis import given, settings
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

import qpik
from qpik.control import DampingTask, FrameTask, ManipulabilityTask, PostureTask, State, pose_error, so3_log
from qpik.control.tasks import se3_ljacinv_expr, se3_log_expr

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


def _quadratic(P: np.ndarray, c: np.ndarray, V: np.ndarray) -> np.ndarray:
    """½ vᵀPv + cᵀv for each row of V (N, n)."""
    return 0.5 * np.einsum("ni,ij,nj->n", V, P, V) + V @ c


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_frame_task_cost_equals_weighted_residual(seed):
    rng = np.random.default_rng(seed)
    robot = qpik.load_robot(ARMS[seed % len(ARMS)])
    q, q_t = random_q(robot, 2, seed)
    twist = rng.normal(size=6)
    gains, weights = rng.uniform(0.5, 80, 2), rng.uniform(0.01, 3, 2)
    task = FrameTask(robot.fk(q_t), *gains, *weights, twist=twist)
    state = State(robot, q, 0.001)
    P, c = task.compute(state)
    # direct: ‖J v − (v_ff + K e)‖²_W with e from the poses, J from finite differences of FK
    J = robot.jacobian(q)
    e = np.concatenate(
        [
            robot.fk(q_t)[:3, 3] - robot.fk(q)[:3, 3],
            Rotation.from_matrix(robot.fk(q_t)[:3, :3] @ robot.fk(q)[:3, :3].T).as_rotvec(),
        ]
    )
    b = twist + np.repeat(gains, 3) * e
    W = np.repeat(weights, 3)
    V = rng.normal(size=(50, 7))
    direct = ((V @ J.T - b) ** 2 * W).sum(axis=1)
    const = (b**2 * W).sum()
    np.testing.assert_allclose(_quadratic(P, c, V) + const, direct, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(P, P.T, atol=1e-12)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_posture_and_damping_cost(seed):
    rng = np.random.default_rng(seed)
    robot = qpik.load_robot("panda")
    q, q_ref = random_q(robot, 2, seed)
    k, w, lam = rng.uniform(0.1, 10), rng.uniform(1e-4, 1), rng.uniform(1e-6, 1)
    state = State(robot, q, 0.01)
    V = rng.normal(size=(30, 7))
    P, c = PostureTask(q_ref, k, w).compute(state)
    b = k * (q_ref - q)
    np.testing.assert_allclose(_quadratic(P, c, V) + w * b @ b, w * ((V - b) ** 2).sum(1), rtol=1e-10)
    P, c = DampingTask(lam).compute(state)
    np.testing.assert_allclose(_quadratic(P, c, V), lam * (V**2).sum(1), rtol=1e-12)


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


def _mink_error(target: np.ndarray, current: np.ndarray) -> np.ndarray:
    """The reference body-frame error log(T⁻¹ T*) (6,) from mink's SE3."""
    return (mink.SE3.from_matrix(current).inverse() @ mink.SE3.from_matrix(target)).log()


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_frame_task_se3_cost_from_finite_differences(seed):
    """error="se3": the cost is ‖A v − (f + K e)‖²_W with e = log(T⁻¹T*) (mink's SE3), A = −∂e/∂q and the
    feed-forward f = ∂e/∂t of a target moving with the twist [v*; ω*] (base frame), both by finite differences."""
    rng = np.random.default_rng(seed)
    robot = qpik.load_robot(ARMS[seed % len(ARMS)])
    q, q_t = random_q(robot, 2, seed)
    q_t = q + rng.uniform(0.05, 1.0) * (q_t - q) / np.linalg.norm(q_t - q)
    target, twist = robot.fk(q_t), rng.normal(size=6)
    gains, weights = rng.uniform(0.5, 80, 2), rng.uniform(0.01, 3, 2)
    task = FrameTask(target, *gains, *weights, twist=twist, error="se3")
    P, c = task.compute(State(robot, q, 0.001))

    def moved(t: float) -> np.ndarray:  # the target after t seconds: ṗ* = v*, Ṙ* = [ω*]× R*
        T = target.copy()
        T[:3, 3] += t * twist[:3]
        T[:3, :3] = Rotation.from_rotvec(t * twist[3:]).as_matrix() @ target[:3, :3]
        return T

    e = _mink_error(target, robot.fk(q))
    np.testing.assert_allclose(task.error(State(robot, q, 0.001)), e, atol=1e-12)
    A = -fd(lambda x: _mink_error(target, robot.fk(x)), q)
    f = fd(lambda t: _mink_error(moved(t[0]), robot.fk(q)), np.zeros(1))[:, 0]
    b = f + np.repeat(gains, 3) * e
    W = np.repeat(weights, 3)
    V = rng.normal(size=(50, robot.dof))
    direct = ((V @ A.T - b) ** 2 * W).sum(axis=1)
    np.testing.assert_allclose(_quadratic(P, c, V) + (b**2 * W).sum(), direct, rtol=1e-7, atol=1e-6)


@pytest.mark.parametrize("name", ARMS)
def test_pose_error_rate_is_minus_jacobian(name):
    """ė = −J q̇ for a fixed target: the world-frame error is the one the geometric Jacobian moves."""
    robot = qpik.load_robot(name)
    q, q_t = random_q(robot, 2, 3)
    q_t = q + 0.3 * (q_t - q) / np.linalg.norm(q_t - q)
    target = robot.fk(q_t)
    de = fd(lambda x: pose_error(target, robot.fk(x)), q)
    # translation part exactly −J_v; rotation part −(dlog) J_ω, = −J_ω at zero error: check at the target
    np.testing.assert_allclose(de[:3], -robot.jacobian(q)[:3], atol=1e-8)
    de_t = fd(lambda x: pose_error(target, robot.fk(x)), q_t)
    np.testing.assert_allclose(de_t, -robot.jacobian(q_t), atol=1e-8)


@pytest.mark.parametrize("name", ARMS)
@pytest.mark.parametrize("translational", [False, True])
def test_manipulability_task_gradient_matches_fd(name, translational):
    robot = qpik.load_robot(name)
    task = ManipulabilityTask(weight=0.7, translational=translational)
    for q in random_q(robot, 5, 11, margin=0.1):
        P, c = task.compute(State(robot, q, 0.001))
        g = fd(lambda x: robot.manipulability(x, translational), q)
        assert np.all(P == 0)
        np.testing.assert_allclose(c, -0.7 * g, atol=1e-7)


def test_frame_task_without_target_and_bad_input():
    robot = qpik.load_robot("iiwa14")
    with pytest.raises(ValueError, match="target"):
        FrameTask().compute(State(robot, robot.q_home, 0.001))
    T = robot.fk(robot.q_home)
    T[0, 0] = np.nan
    with pytest.raises(qpik.InputError):
        FrameTask(T)
    with pytest.raises(qpik.InputError):
        FrameTask(robot.fk(robot.q_home), twist=np.ones(5))
    with pytest.raises(ValueError, match="error"):
        FrameTask(robot.fk(robot.q_home), error="body")
