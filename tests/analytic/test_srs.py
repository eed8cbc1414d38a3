"""S-R-S closed form (iiwa14, arm angle ψ): checked by FK, by ssik's independent model, by finite differences.

Random configurations are drawn inside the joint limits, five hypothesis seeds
of 2,000 each (10,000 per property), every batch in one call.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS, random_q
from hypothesis import given, settings
from ssik.prebuilt.kuka import iiwa14_ik

import qpik
from qpik.analytic.api import closed_form_for
from qpik.core.errors import NoClosedFormError
from qpik.robots.dh import DHChain

BATCH = 2000
PROPERTY = settings(max_examples=5, deadline=None)
ROBOT = qpik.load_robot("iiwa14")
SOLVER = closed_form_for(ROBOT)
PROBLEM = Path(__file__).resolve().parents[2] / "problems" / "shimizu2008_iiwa.toml"


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a − b| on the circle (rad)."""
    return np.abs((np.asarray(a) - b + np.pi) % (2 * np.pi) - np.pi)


def pose_error(robot: qpik.Robot, Q: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """FK of Q (..., 7) against T (..., 4, 4) broadcast: (position error m, rotation entry error) per row."""
    F = robot.fk(Q.reshape(-1, 7)).reshape(*Q.shape[:-1], 4, 4)
    T = np.broadcast_to(T, F.shape)
    return np.abs(F[..., :3, 3] - T[..., :3, 3]).max(-1), np.abs(F[..., :3, :3] - T[..., :3, :3]).max((-2, -1))


def assert_reaches(robot: qpik.Robot, sols: qpik.IKSolutions, T: np.ndarray, tol: float = 1e-9) -> None:
    """Every valid branch reaches T by FK (position in m, rotation entries ~ rad)."""
    T = T[:, None] if T.ndim == 3 else T
    dp, dr = pose_error(robot, sols.q, T)
    assert np.all(np.isfinite(sols.q))
    assert dp[sols.valid].max(initial=0) < tol
    assert dr[sols.valid].max(initial=0) < tol


def config(**fixed: float) -> np.ndarray:
    """A random configuration inside the limits with some joints fixed (``q2=0.0`` sets θ2)."""
    q = random_q(ROBOT, 1, 7)[0]
    for k, v in fixed.items():
        q[int(k[1:]) - 1] = v
    return q


# ---- every branch reaches the pose -----------------------------------------


@PROPERTY
@given(seed=SEEDS)
def test_every_branch_reaches_the_pose(seed):
    q = random_q(ROBOT, BATCH, seed)
    T = ROBOT.fk(q)
    psi = np.random.default_rng(seed).uniform(-np.pi, np.pi, BATCH)
    sols = qpik.ik(ROBOT, T, psi)
    assert sols.valid.all()
    assert_reaches(ROBOT, sols, T)
    assert np.all(np.abs(sols.q) <= np.pi)
    # the public branch number is the sign pattern 4·[θ2<0] + 2·[θ4<0] + [θ6<0]
    Q = sols.q
    ids = 4 * (Q[..., 1] < 0) + 2 * (Q[..., 3] < 0) + (Q[..., 5] < 0)
    assert np.array_equal(ids, np.broadcast_to(sols.branch, ids.shape))


@PROPERTY
@given(seed=SEEDS)
def test_generating_configuration_is_a_branch_at_its_own_psi(seed):
    q = random_q(ROBOT, BATCH, seed)
    psi, branch = qpik.redundancy_parameter(ROBOT, q)
    sols = qpik.ik(ROBOT, ROBOT.fk(q), psi)
    assert np.all(angle_diff(sols.q[np.arange(BATCH), branch], q) < 1e-8)
    assert not sols.singular.any()


@PROPERTY
@given(seed=SEEDS)
def test_redundancy_parameter_inverts_ik(seed):
    rng = np.random.default_rng(seed)
    T = ROBOT.fk(random_q(ROBOT, BATCH // 8, seed))
    psi = rng.uniform(-np.pi, np.pi, len(T))
    sols = qpik.ik(ROBOT, T, psi)
    back, branch = qpik.redundancy_parameter(ROBOT, sols.q.reshape(-1, 7))
    assert np.all(angle_diff(back.reshape(-1, 8), psi[:, None]) < 1e-8)
    assert np.array_equal(branch.reshape(-1, 8), np.broadcast_to(np.arange(8), (len(T), 8)))


def test_psi_zero_is_the_reference_plane():
    """ψ = 0: θ3 = 0 on one shoulder sign, with joint 1 toward the wrist; the home configuration is there."""
    assert qpik.redundancy_parameter(ROBOT, ROBOT.q_home)[0] == pytest.approx(0.0, abs=1e-12)
    T = ROBOT.fk(random_q(ROBOT, 200, 3))
    Q = qpik.ik(ROBOT, T, 0.0).q
    W = T[:, :3, 3] - ROBOT.chain.d[6] * T[:, :3, 2]
    zero3 = np.abs(Q[..., 2]) < 1e-9
    assert np.array_equal(zero3.sum(axis=1), np.full(len(T), 4))
    az = np.broadcast_to(np.arctan2(W[:, 1], W[:, 0])[:, None], zero3.shape)
    assert np.all(angle_diff(Q[..., 0][zero3], az[zero3]) < 1e-9)


# ---- an independent model: ssik ---------------------------------------------


@settings(max_examples=2, deadline=None)
@given(seed=SEEDS)
def test_branches_reach_the_pose_in_ssik_model(seed):
    q = random_q(ROBOT, 100, seed)
    T = ROBOT.fk(q)
    sols = qpik.ik(ROBOT, T, np.random.default_rng(seed).uniform(-np.pi, np.pi, len(T)))
    for n in range(len(T)):
        for k in np.flatnonzero(sols.valid[n]):
            F = iiwa14_ik.fk(sols.q[n, k])
            assert np.abs(F - T[n]).max() < 1e-9


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_ssik_solution_is_one_of_our_branches(seed):
    T = ROBOT.fk(random_q(ROBOT, 1, seed, margin=0.3)[0])
    found = [s.q for s in iiwa14_ik.solve(T)]
    assert found, "ssik found no solution for a reachable pose"
    Qs = np.array(found)
    psi, branch = qpik.redundancy_parameter(ROBOT, Qs)
    ours = qpik.ik(ROBOT, np.broadcast_to(T, (len(Qs), 4, 4)), psi)
    assert np.all(angle_diff(ours.q[np.arange(len(Qs)), branch], Qs) < 1e-7)


# ---- three evaluations agree; exact derivatives -----------------------------


def test_batched_single_and_casadi_agree():
    rng = np.random.default_rng(11)
    T = ROBOT.fk(random_q(ROBOT, 100, 11))
    psi = rng.uniform(-np.pi, np.pi, len(T))
    batch = qpik.ik(ROBOT, T, psi)
    for n in range(len(T)):
        one = qpik.ik(ROBOT, T[n], psi[n])
        Q, valid, singular = (np.array(x) for x in SOLVER.casadi_function(ca.DM(T[n]), psi[n]))
        np.testing.assert_allclose(one.q, batch.q[n], atol=1e-12, rtol=0)
        np.testing.assert_allclose(Q, batch.q[n], atol=1e-12, rtol=0)
        assert np.array_equal(one.valid, batch.valid[n]) and np.array_equal(valid.ravel() > 0.5, batch.valid[n])
        assert np.array_equal(singular.ravel() > 0.5, batch.singular[n])


def test_casadi_derivative_in_psi_matches_finite_differences():
    Ts, ps = ca.SX.sym("T", 4, 4), ca.SX.sym("psi")
    Q = SOLVER.casadi_function(Ts, ps)[0]
    dq = ca.Function("dq", [Ts, ps], [ca.jacobian(ca.vec(Q), ps)])
    rng = np.random.default_rng(5)
    T = ROBOT.fk(random_q(ROBOT, 50, 5))
    psi, h = rng.uniform(-3.0, 3.0, len(T)), 1e-6
    for n in range(len(T)):
        J = np.array(dq(T[n], psi[n])).reshape(7, 8).T  # column-major vec of (8, 7)
        up, down = (qpik.ik(ROBOT, T[n], psi[n] + s).q for s in (h, -h))
        fd = ((up - down + np.pi) % (2 * np.pi) - np.pi) / (2 * h)
        np.testing.assert_allclose(J, fd, atol=1e-5, rtol=1e-5)


# ---- singular cases: a defined result that still reaches the pose ----------


@pytest.mark.parametrize("joint", ["q2", "q6"])
@pytest.mark.parametrize("value", [0.0, 1e-13, -1e-11, 1e-9, -1e-6])
def test_shoulder_and_wrist_singularities(joint, value):
    q = config(**{joint: value})
    T = ROBOT.fk(q)
    psi0, branch = qpik.redundancy_parameter(ROBOT, q)
    psis = np.concatenate([[psi0], np.linspace(-np.pi, np.pi, 41)])
    sols = qpik.ik(ROBOT, np.broadcast_to(T, (len(psis), 4, 4)), psis)
    assert sols.valid.all()
    assert_reaches(ROBOT, sols, np.broadcast_to(T, (len(psis), 4, 4)))
    if value == 0.0:
        assert sols.singular[0, branch]
        # the coupled pair: the first angle is its limit as ψ increases, the last takes the rest
        j = 0 if joint == "q2" else 4
        right = qpik.ik(ROBOT, T, psi0 + 1e-7).q[branch, j]
        assert angle_diff(sols.q[0, branch, j], right) < 1e-5


@pytest.mark.parametrize("value", [0.0, 1e-12, 1e-9, 1e-6, -1e-6])
def test_elbow_stretched(value):
    q = config(q4=value)
    T = ROBOT.fk(q)
    psis = np.linspace(-np.pi, np.pi, 41)
    sols = qpik.ik(ROBOT, np.broadcast_to(T, (len(psis), 4, 4)), psis)
    assert_reaches(ROBOT, sols, np.broadcast_to(T, (len(psis), 4, 4)))
    assert sols.valid.all()
    # the elbow pairs (branch k and k ^ 2) coincide as θ4 -> 0
    assert np.all(angle_diff(sols.q, sols.q[:, np.arange(8) ^ 2]) < 1e-5)


@pytest.mark.parametrize("theta3", [0.0, np.pi])
@pytest.mark.parametrize("theta4", [-1.0, 0.4])
def test_wrist_straight_above_or_below_shoulder(theta3, theta4):
    """x_sw vertical: the reference plane is undefined; defined result, flag set, pose reached."""
    d_se, d_ew = ROBOT.chain.d[2], ROBOT.chain.d[4]
    t2 = np.arctan2(d_ew * np.sin(theta4), d_se + d_ew * np.cos(theta4))
    for sign in (1.0, -1.0):  # above (θ2 small), below (θ2 + π is outside the limits but still solved)
        q = config(q3=theta3, q4=theta4)
        q[1] = (t2 if theta3 == 0.0 else -t2) + (0.0 if sign > 0 else np.pi)
        T = ROBOT.fk(q)
        W = T[:3, 3] - ROBOT.chain.d[6] * T[:3, 2]
        assert np.hypot(W[0], W[1]) < 1e-12
        psis = np.linspace(-np.pi, np.pi, 37)
        sols = qpik.ik(ROBOT, np.broadcast_to(T, (len(psis), 4, 4)), psis)
        assert sols.valid.all() and sols.singular.all()
        assert_reaches(ROBOT, sols, np.broadcast_to(T, (len(psis), 4, 4)))
        assert np.isfinite(qpik.redundancy_parameter(ROBOT, q)[0])


def test_everything_singular_at_once():
    """q = 0: arm straight up (elbow stretched, wrist on the base axis, θ2 = θ6 = 0 for every ψ)."""
    T = ROBOT.fk(np.zeros(7))
    psis = np.linspace(-np.pi, np.pi, 13)
    sols = qpik.ik(ROBOT, np.broadcast_to(T, (len(psis), 4, 4)), psis)
    assert sols.valid.all() and sols.singular.all()
    assert_reaches(ROBOT, sols, np.broadcast_to(T, (len(psis), 4, 4)))


# ---- the problem file -------------------------------------------------------


def test_shimizu_problem_configuration_is_recovered():
    if PROBLEM.exists():
        from qpik.problems import load

        problem = load(PROBLEM)
        robot, q, T, psis = problem.robot, problem.q_targets[0], problem.poses[0], problem.params
        tol = float(problem.expected.get("tolerance", 1e-9))
    else:
        robot, q = ROBOT, np.array([0.16, np.pi / 2, 0.5, np.pi / 3, 0.6, np.pi / 6, 0.3])
        T, psis, tol = ROBOT.fk(q), np.linspace(-np.pi, np.pi, 73), 1e-9
    psi, branch = qpik.redundancy_parameter(robot, q)
    assert np.all(angle_diff(qpik.ik(robot, T, psi).q[branch], q) < tol)
    sols = qpik.ik(robot, np.broadcast_to(T, (len(psis), 4, 4)), psis)
    assert sols.valid.all()
    assert_reaches(robot, sols, np.broadcast_to(T, (len(psis), 4, 4)))


# ---- base and tool frames, other chains --------------------------------------


def test_base_and_tool_frames_are_honoured():
    base, tool = np.eye(4), np.eye(4)
    base[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ np.diag([1.0, -1.0, -1.0])
    base[:3, 3] = (0.3, -0.2, 1.1)
    tool[:3, 3] = (0.01, 0.02, 0.15)
    chain = dataclasses.replace(ROBOT.chain, base=base, tool=tool)
    robot = dataclasses.replace(ROBOT, chain=chain)
    q = random_q(robot, 500, 8)
    T = robot.fk(q)
    psi, branch = qpik.redundancy_parameter(robot, q)
    sols = qpik.ik(robot, T, psi)
    assert_reaches(robot, sols, T)
    assert np.all(angle_diff(sols.q[np.arange(len(q)), branch], q) < 1e-8)


@pytest.mark.parametrize(
    "change",
    [
        {"alpha": (np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, np.pi / 2, 0.0)},
        {"a": (0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0)},
        {"d": (0.36, 0.0, 0.42, 0.05, 0.40, 0.0, 0.126)},
        {"offset": (0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0)},
        {"convention": "modified"},
    ],
)
def test_other_chains_are_refused(change):
    robot = dataclasses.replace(ROBOT, chain=dataclasses.replace(ROBOT.chain, **change))
    with pytest.raises(NoClosedFormError, match="S-R-S"):
        qpik.ik(robot, ROBOT.fk(ROBOT.q_home), 0.0)


def test_seven_joint_chain_of_another_family_is_refused():
    panda = dataclasses.replace(qpik.load_robot("panda"), closed_form="srs")
    with pytest.raises(NoClosedFormError):
        qpik.ik(panda, np.eye(4), 0.0)
    assert isinstance(ROBOT.chain, DHChain)


# ---- bad input ------------------------------------------------------------


@pytest.mark.parametrize("where", [(2.0, 0.0, 0.5), (0.0, 0.0, 0.36), (0.0, 0.01, 0.37)])
def test_unreachable_pose_is_invalid_not_an_error(where):
    T = np.eye(4)
    T[:3, 3] = where
    T[2, 3] += ROBOT.chain.d[6]  # wrist centre at ``where``
    one = qpik.ik(ROBOT, T, 0.5)
    batch = qpik.ik(ROBOT, np.stack([T, T]), np.array([0.5, -2.0]))
    for sols in (one, batch):
        assert not sols.valid.any() and not sols.within_limits.any()
        assert np.all(np.isfinite(sols.q))
    fi = qpik.feasible_intervals(ROBOT, T)
    assert all(iv == [] for iv in fi.intervals)


def test_stretched_elbow_is_flagged_on_every_configuration():
    """θ4 = 0 exactly on 1,000 random configurations: ik(fk(q), ψ(q)) flags q's branch singular, returns θ4 = 0 and
    gives q back. θ4 ∝ sqrt(d_se + d_ew − |x_sw|), so the pose's rounding alone made θ4 ≈ 1.5e-8 (arccos of a cosine
    that rounds to 1) and the sine test flagged 419 of the 1,000."""
    Q = random_q(ROBOT, 1000, 11)
    Q[:, 3] = 0.0
    psi, branch = qpik.redundancy_parameter(ROBOT, Q)
    sols = qpik.ik(ROBOT, ROBOT.fk(Q), psi)
    rows = sols.q[np.arange(len(Q)), branch]
    assert sols.singular[np.arange(len(Q)), branch].all()
    np.testing.assert_array_equal(rows[:, 3], 0.0)
    assert angle_diff(rows, Q).max() < 1e-8
    assert_reaches(ROBOT, sols, ROBOT.fk(Q))
    # a bent elbow just beyond the rounding is not flagged
    Q[:, 3] = 1e-5
    psi, branch = qpik.redundancy_parameter(ROBOT, Q)
    sols = qpik.ik(ROBOT, ROBOT.fk(Q), psi)
    assert not sols.singular[np.arange(len(Q)), branch][np.abs(np.sin(Q[:, [1, 5]])).min(axis=1) > 1e-6].any()
