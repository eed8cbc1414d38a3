"""Tasks of the QP: cost pieces vs direct evaluation, errors and gradients vs mink and finite differences."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import ARMS, SEEDS, fd, random_q
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

import qpik
from qpik.control import DampingTask, FrameTask, ManipulabilityTask, PostureTask, State, pose_error


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


def test_posture_set_target_changes_the_reference_not_the_form():
    robot = qpik.load_robot("iiwa14")
    task = PostureTask(robot.q_home, 2.0, 0.5)
    q = random_q(robot, 1, 3)[0]
    task.set_target(robot.q_home + 0.1)
    _, c = task.compute(State(robot, q, 0.001))
    np.testing.assert_allclose(c, -2 * 0.5 * 2.0 * (robot.q_home + 0.1 - q), atol=1e-14)
    assert task.structure() == ()
    with pytest.raises(qpik.InputError, match="q_ref"):
        task.set_target(np.zeros(6))


@pytest.mark.parametrize("name", ["iiwa14", "panda"])
def test_objective_task_is_the_weighted_gradient(name):
    """c = w ∇f for the objectives of qpik.objectives (finite differences of their values, from numpy distances)."""
    from qpik.control import ObjectiveTask
    from qpik.geometry import Sphere, distances
    from qpik.objectives import Clearance, JointLimitMargin, ReferenceDistance

    robot = qpik.load_robot(name)
    ball = [Sphere((0.4, 0.2, 0.7), 0.1)]
    objective = JointLimitMargin(smooth=True) + 2.0 * Clearance(smooth=True, cap=0.5) + ReferenceDistance()

    def value(q):
        half = 0.5 * (robot.q_max - robot.q_min)
        g = np.concatenate([(q - robot.q_min) / half, (robot.q_max - q) / half])
        moving = ~robot.fixed_capsules  # the clearance objectives read the capsules a joint moves
        d = distances(robot.capsule_segments(q)[moving], robot.capsule_radii[moving], ball).d.ravel()
        soft = np.log(np.exp(-20 * g).sum()) / 20 + 2 * np.log(np.exp(-100 * np.r_[d, 0.5]).sum()) / 100
        return soft + 0.5 * np.sum((q - robot.q_home) ** 2)

    task = ObjectiveTask(robot, objective, weight=0.3, q_ref=robot.q_home, obstacles=ball)
    for q in random_q(robot, 4, 12, margin=0.1):
        if distances(robot.capsule_segments(q), robot.capsule_radii, ball).d.min() < 0.01:
            continue
        P, c = task.compute(State(robot, q, 0.001))
        assert np.all(P == 0)
        np.testing.assert_allclose(c, 0.3 * fd(value, q), atol=2e-7)
