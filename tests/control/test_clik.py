"""CLIK baselines and the QP on the tracking problem of Zheng et al. 2019 (zheng7, eq. 19), integrated at dt = 1 ms."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import fd, random_q

import qpik
from qpik.control import (
    ConfigurationLimit,
    Controller,
    DampedLeastSquares,
    DampingTask,
    FrameTask,
    GradientProjection,
    PseudoInverseCLIK,
    VelocityLimit,
    VelocityOnly,
    pose_error,
)
from qpik.problems.files import find_problem, load

DT = 0.001
# Along the "relative" reading of eq. (19) the arm nears a singularity at t ≈ 6.3 s
# (manipulability 0.21 -> 0.04): every method loses the path there. Track up to 5.5 s.
DURATION = 5.5
TRANSIENT = 1.0


@pytest.fixture(scope="module")
def problem():
    return load(find_problem("zheng2019_clik"))


def track(problem, ctrl) -> np.ndarray:
    """Position error (m) along the path, q_{k+1} = q_k + v_k dt with the path's pose and twist at t_k."""
    path, robot = problem.path, problem.robot
    q = np.array(path.q0, dtype=float)
    steps = int(DURATION / DT)
    err = np.empty(steps + 1)
    for k in range(steps):
        t = k * DT
        err[k] = np.linalg.norm(path.position(np.array([t]))[0] - robot.fk(q)[:3, 3])
        q = q + ctrl.step(q, target=path.pose(t), twist=path.twist(t)) * DT
    err[steps] = np.linalg.norm(path.position(np.array([DURATION]))[0] - robot.fk(q)[:3, 3])
    return err


def test_qp_tracks_to_1e_5(problem):
    kp = float(problem.solver["kp_position"])
    ctrl = Controller(
        problem.robot,
        [FrameTask(None, kp, kp, 1.0, 1.0), DampingTask(1e-8)],
        [ConfigurationLimit(), VelocityLimit()],
        dt=DT,
    )
    err = track(problem, ctrl)
    assert err[int(TRANSIENT / DT) :].max() <= 1e-5


def test_pd_clik_tracks_and_velocity_only_drifts(problem):
    err_pd = track(problem, PseudoInverseCLIK(problem.robot, 50.0, 50.0, kd=0.5, dt=DT))
    assert err_pd[int(TRANSIENT / DT) :].max() <= 1e-5
    err_v = track(problem, VelocityOnly(problem.robot, dt=DT))
    after = err_v[int(TRANSIENT / DT) :]
    assert after[-1] > 1e-4 and after[-1] > 10 * err_pd[-1]  # Fig. 3a: the error accumulates
    assert after[-1] > after[0]


@pytest.mark.parametrize("name", ["iiwa14", "zheng7"])
def test_baselines_match_their_formulas(name):
    """Each law, checked against its formula written with independent pieces (lstsq, FD Jacobian)."""
    robot = qpik.load_robot(name)
    rng = np.random.default_rng(4)
    for q in random_q(robot, 5, 2, margin=0.2):
        target = robot.fk(q + rng.normal(scale=0.05, size=7))
        twist = rng.normal(size=6)
        J = robot.jacobian(q)
        b = twist + 30.0 * pose_error(target, robot.fk(q))
        v_pinv = np.linalg.lstsq(J, b, rcond=None)[0]  # minimum-norm solution = J⁺ b
        np.testing.assert_allclose(PseudoInverseCLIK(robot, 30.0, 30.0).step(q, target, twist), v_pinv, atol=1e-9)
        np.testing.assert_allclose(
            VelocityOnly(robot).step(q, target, twist), np.linalg.lstsq(J, twist, rcond=None)[0], atol=1e-9
        )
        lam = 0.05  # DLS = argmin ‖J v − b‖² + λ²‖v‖²
        v_dls = np.linalg.lstsq(np.vstack([J, lam * np.eye(7)]), np.r_[b, np.zeros(7)], rcond=None)[0]
        np.testing.assert_allclose(DampedLeastSquares(robot, 30.0, 30.0, lam).step(q, target, twist), v_dls, atol=1e-9)
        # gradient projection: task part as pinv, null part along ∇m (FD) projected onto ker J
        v_gp = GradientProjection(robot, 30.0, 30.0, null_gain=2.0).step(q, target, twist)
        grad = fd(robot.manipulability, q)
        N = np.eye(7) - np.linalg.pinv(J) @ J
        np.testing.assert_allclose(v_gp, v_pinv + 2.0 * N @ grad, atol=1e-6)
        np.testing.assert_allclose(J @ (v_gp - v_pinv), 0.0, atol=1e-9)


def test_pd_term_uses_the_previous_command():
    """K_d (ẋ_d − J q̇_{k−1}): with a previous command that already gives ẋ_d, the D term vanishes."""
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home
    target, twist = robot.fk(q), np.array([0.05, 0.0, 0.02, 0.0, 0.1, 0.0])
    ctrl = PseudoInverseCLIK(robot, 10.0, 10.0, kd=0.7)
    v0 = ctrl.step(q, target, twist)  # previous command 0: D term = 0.7 ẋ_d
    np.testing.assert_allclose(robot.jacobian(q) @ v0, 1.7 * twist, atol=1e-9)
    v1 = ctrl.step(q, target, twist)  # previous command gave 1.7 ẋ_d: D term = −0.49 ẋ_d
    np.testing.assert_allclose(robot.jacobian(q) @ v1, (1 - 0.49) * twist, atol=1e-9)


def test_clik_bad_input():
    robot = qpik.load_robot("zheng7")
    ctrl = PseudoInverseCLIK(robot)
    with pytest.raises(qpik.InputError, match="target"):
        ctrl.step(robot.q_home)
    q = robot.q_home.copy()
    q[0] = np.inf
    with pytest.raises(qpik.InputError):
        ctrl.step(q, target=robot.fk(robot.q_home))
