"""Locked-q7 closed form (Franka Panda): on the catalog table and on example-robot-data's Panda URDF (checked by
MuJoCo's FK of that file), the catalog's twin, the S-R-S iiwa with q7 locked; example-robot-data's xArm7, a near
member (its ideal chain's closed form polished on the file's); feasible q7 sets against dense sampling.

Random configurations are drawn inside the joint limits, three hypothesis seeds of 2,000 per arm.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import LARGE, SEEDS, model_robot, mujoco_poses, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.algebra import symbolic as sy
from qpik.analytic.api import closed_form_for
from qpik.analytic.intervals import shrunk_limits
from qpik.analytic.locked_joint import MAX_ROUNDS, SCALE, correction_rounds
from qpik.analytic.polish import RESIDUAL_TOL
from qpik.core.errors import InputError

BATCH = 2000
DENSE = 20_000
NEAR_END = 1e-9
"""rad: a near member's set ends are moved onto the file's chain to this (qpik.analytic.set_ends)..."""
FOLD_END = 1e-6
"""rad: ... but for an end where the file's branch stops being valid (a fold of its chain, where two of its solutions
meet): there the polish's residual decides the branch's validity, which flickers within about 1e-7 of the fold."""
PROPERTY = settings(max_examples=3, deadline=None)
PANDA = qpik.load_robot("panda")


def arm(key: str) -> qpik.Robot:
    return PANDA if key == "panda" else model_robot(key)


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a − b| on the circle (rad)."""
    return np.abs((np.asarray(a) - b + np.pi) % (2 * np.pi) - np.pi)


def assert_holds(robot: qpik.Robot, q: np.ndarray, found: np.ndarray) -> None:
    """``found`` (N, 7) is q (N, 7) to 1e-9 rad, or to 1e-14/σ_min where the 6-R chain of joints 1-6 is that close to
    singular (σ_min: its Jacobian's smallest singular value; the pose's rounding alone moves the answer that far)."""
    err = angle_diff(found, q).max(axis=1)
    sigma = np.linalg.svd(robot.jacobian(q)[:, :, :6], compute_uv=False)[:, -1]
    assert np.all((err < 1e-9) | (err * sigma < 1e-14)), (err.max(), sigma[err.argmax()])


def test_the_panda_is_recognised_with_its_offsets_in_the_notes():
    for robot in (PANDA, model_robot("erd_panda"), model_robot("pybullet_panda")):
        assert robot.closed_form == "locked_joint"
        assert "q7 locked" in robot.notes and "3-4 82.5 mm, 4-5 82.5 mm, 6-7 88 mm" in robot.notes
        assert "qpik.analytic.locked_joint" in robot.notes


@PROPERTY
@given(seed=SEEDS)
@pytest.mark.parametrize("key", ["panda", "erd_panda"])
def test_ik_at_its_own_q7_contains_q_and_every_branch_reaches_the_pose(key, seed):
    """``ik(fk(q), q7)`` holds q as branch ``redundancy_parameter(q)``, within limits; every valid branch reaches
    the pose to 1e-10 by MuJoCo's FK of the model (the twin's for the catalog arm).

    "Holds q" is to 1e-9 rad, or, where the 6-R chain of joints 1-6 is so close to singular that no method can
    (the pose's own rounding, ~1e-16, moves the exact answer by ~1e-16/σ_min of its Jacobian: near both the
    shoulder singularity and the stretched elbow σ_min reaches 1e-8), to within 1e-14/σ_min."""
    robot = arm(key)
    q = random_q(robot, BATCH, seed)
    T = mujoco_poses(robot, q)
    np.testing.assert_allclose(robot.fk(q), T, atol=1e-12)
    param, branch = qpik.redundancy_parameter(robot, q)
    assert np.array_equal(param, q[:, 6])
    sols = qpik.ik(robot, T, param)
    rows = np.arange(BATCH)
    assert_holds(robot, q, sols.q[rows, branch])
    assert sols.valid[rows, branch].all() and sols.within_limits[rows, branch].all()
    assert np.isfinite(sols.q).all()
    valid = sols.q[sols.valid]
    F = mujoco_poses(robot, valid)
    assert np.abs(F - np.repeat(T, sols.valid.sum(1), axis=0)).max() < 1e-10


@PROPERTY
@given(seed=SEEDS)
def test_redundancy_parameter_inverts_ik(seed):
    """Every valid branch at a random q7 maps back to that q7 and its own branch id."""
    rng = np.random.default_rng(seed)
    T = PANDA.fk(random_q(PANDA, BATCH // 8, seed))
    q7 = rng.uniform(-np.pi, np.pi, len(T))
    sols = qpik.ik(PANDA, T, q7)
    back, branch = qpik.redundancy_parameter(PANDA, sols.q[sols.valid])
    assert np.all(angle_diff(back, np.repeat(q7, sols.valid.sum(1))) < 1e-12)
    assert np.array_equal(branch, np.broadcast_to(np.arange(8), sols.valid.shape)[sols.valid])


def test_branch_numbering_on_the_panda():
    """The module docstring's numbering: 4·[q2 < 0] + 2·[q4 > −0.4670] + [cos q5 > 0] on Franka's q4 range."""
    q = random_q(PANDA, BATCH, 7)
    _, branch = qpik.redundancy_parameter(PANDA, q)
    expected = 4 * (q[:, 1] < 0) + 2 * (q[:, 3] > closed_form_for(PANDA).phi - np.pi) + (np.cos(q[:, 4]) > 0)
    assert np.array_equal(branch, expected)


def test_batch_single_and_casadi_agree():
    solver = closed_form_for(PANDA)
    rng = np.random.default_rng(11)
    T = PANDA.fk(random_q(PANDA, 100, 11))
    q7 = rng.uniform(-np.pi, np.pi, len(T))
    batch = qpik.ik(PANDA, T, q7)
    for n in range(len(T)):
        one = qpik.ik(PANDA, T[n], q7[n])
        Q, valid, singular = (np.array(x) for x in solver.casadi_function(ca.DM(T[n]), q7[n]))
        assert np.array_equal(one.valid, batch.valid[n]) and np.array_equal(valid.ravel() > 0.5, batch.valid[n])
        ok = batch.valid[n]  # the rows of invalid branches are meaningless (a polish that went nowhere)
        # near the stretched elbow (q4 ≈ 2.74) the polish's last step amplifies the paths' different round-off
        np.testing.assert_allclose(one.q[ok], batch.q[n][ok], atol=1e-10, rtol=0)
        np.testing.assert_allclose(Q[ok], batch.q[n][ok], atol=1e-10, rtol=0)
        assert np.array_equal(one.within_limits, batch.within_limits[n])
        assert np.array_equal(singular.ravel() > 0.5, batch.singular[n])


def test_the_catalog_panda_and_its_urdf_twin_give_the_same_branches():
    """example-robot-data's Panda to its flange (panda_link8) has the catalog's joint angles: same q per branch."""
    twin = qpik.load_robot(model_robot("erd_panda").model.path, tip="panda_link8")
    assert twin.closed_form == "locked_joint"
    q = random_q(PANDA, 200, 3)
    mine = qpik.ik(PANDA, PANDA.fk(q), q[:, 6])
    theirs = qpik.ik(twin, twin.fk(q), q[:, 6])
    assert np.array_equal(mine.valid, theirs.valid)
    assert angle_diff(mine.q[mine.valid], theirs.q[theirs.valid]).max() < 1e-9


def test_an_unreachable_pose_gives_finite_invalid_branches():
    T = PANDA.fk(PANDA.q_home)
    T[:3, 3] = (2.0, 0.0, 0.5)
    sols = qpik.ik(PANDA, T, 0.3)
    assert not sols.valid.any() and np.isfinite(sols.q).all()


@pytest.mark.parametrize("q2", [0.0, 1e-12, 1e-9])
def test_shoulder_singularity_still_reaches_the_pose(q2):
    q = PANDA.q_home.copy()
    q[1] = q2
    T = PANDA.fk(q)
    sols = qpik.ik(PANDA, T, q[6])
    F = PANDA.fk(sols.q[sols.valid])
    assert np.abs(F - T).max() < 1e-10
    if q2 == 0.0:
        assert sols.singular[qpik.redundancy_parameter(PANDA, q)[1]]


# ---- recognition and the override -------------------------------------------


def test_redundancy_override():
    """``redundancy="q7"`` puts the S-R-S iiwa file in the locked-q7 family, where it is complete too."""
    iiwa = qpik.load_robot(model_robot("pybullet_iiwa").model.path, redundancy="q7")
    assert iiwa.closed_form == "locked_joint" and "offsets between axes none" in iiwa.notes
    q = random_q(iiwa, 500, 1)
    sols = qpik.ik(iiwa, iiwa.fk(q), q[:, 6])
    _, branch = qpik.redundancy_parameter(iiwa, q)
    assert_holds(iiwa, q, sols.q[np.arange(len(q)), branch])
    panda_file = model_robot("erd_panda").model.path
    assert qpik.load_robot(panda_file, redundancy="psi").closed_form is None
    assert "not srs" in qpik.load_robot(panda_file, redundancy="psi").notes
    with pytest.raises(InputError, match="redundancy"):
        qpik.load_robot("iiwa14", redundancy="q7")
    with pytest.raises(InputError, match="redundancy"):
        qpik.load_robot(panda_file, redundancy="q4")


def test_the_xarm7_file_is_a_near_member_with_its_miss_in_the_notes():
    """example-robot-data's xArm7 has the Panda's structure up to its rounded angles (rpy 1.5708): axis 3 misses the
    point where axes 1-2 meet by ~1 µm. It gets the closed form of its ideal chain, whose axes meet exactly."""
    robot = model_robot("erd_xarm7")
    assert robot.closed_form == "locked_joint" and not robot.canonical.exact
    h, o = robot.chain.axes(np.zeros(7))
    w = o[0] - o[1]  # the foot on axis 1 of the common normal of axes 1 and 2, then its distance from axis 3
    n = np.cross(h[0], h[1])
    S = o[0] + (np.cross(h[1], n) @ w) / (n @ n) * h[0]
    miss = np.linalg.norm(np.cross(S - o[2], h[2]))
    assert 1e-7 < miss < 1e-5
    assert f"axis 3 passes {1e6 * miss:.4g} µm from the shoulder point" in robot.notes
    assert "polished by Newton on the file's chain" in robot.notes and "feasible sets not proved" in robot.notes
    ideal = robot.canonical.table
    hi, oi = ideal.axes(np.zeros(7))
    np.testing.assert_allclose(hi, h, atol=1e-15)
    assert np.linalg.norm(np.cross(S - oi[2], hi[2])) < 1e-12
    q = random_q(robot, 200, 0)
    assert 0 < np.abs(ideal.fk(q) - robot.fk(q)).max() < 10 * miss


@pytest.mark.parametrize("seed", range(3))
def test_ik_of_the_xarm7_holds_q_and_every_valid_branch_reaches_the_pose_by_mujoco(seed):
    """The polished branches are answers on the file's own chain: every valid one reaches the pose to 1e-10 by
    MuJoCo's FK of the URDF, and the branch ``redundancy_parameter(q)`` holds q: to 1e-9 rad, or to RESIDUAL_TOL/σ_min
    (σ_min: the smallest singular value of the Jacobian of joints 1-6; the polish's residual moves the answer that
    far), unless that chain is near singular (σ_min < 1e-4). There the file's answers lie ~miss/σ_min from the
    ideal chain's, beyond the polish's reach: it may reach the twin of q (another answer, still valid) or neither
    (the branch then flagged invalid, never returned wrong). The completeness counted on these fixed seeds: q is
    missed for at most 0.5% of the configurations."""
    robot = model_robot("erd_xarm7")
    q = random_q(robot, BATCH, seed)
    T = mujoco_poses(robot, q)
    param, branch = qpik.redundancy_parameter(robot, q)
    assert angle_diff(param, q[:, 6]).max() < 1e-15  # q7's limits are ±2π: the parameter is q7 wrapped
    sols = qpik.ik(robot, T, param)
    err = np.where(sols.valid, angle_diff(sols.q, q[:, None]).max(axis=2), np.inf)  # (N, 8)
    sigma = np.linalg.svd(robot.jacobian(q)[:, :, :6], compute_uv=False)[:, -1]
    own = err[np.arange(BATCH), branch]
    held = (own < 1e-9) | (own * sigma < RESIDUAL_TOL)
    assert np.all(held | (sigma < 1e-4)), (own[~held], sigma[~held])
    assert (~held).sum() <= BATCH // 200
    inside = robot.within_limits(sols.q.reshape(-1, 7)).reshape(BATCH, 8)
    assert np.isfinite(sols.q).all() and np.array_equal(sols.within_limits, sols.valid & inside)
    F = mujoco_poses(robot, sols.q[sols.valid])
    assert np.abs(F - np.repeat(T, sols.valid.sum(1), axis=0)).max() < 1e-10


NEAR_SETS = [(key, margin) for key in ("erd_xarm7", "robosuite_gen3") for margin in (0.0, 0.3)]
"""The Gen3 file's sets at margin 0 (the xArm7's cover margin 0, the Gen3's margin 0.3) in the large run only: each
case takes half a minute with the tests' unoptimised libraries."""


@pytest.mark.parametrize("key, margin", NEAR_SETS if LARGE else [c for c in NEAR_SETS if c != ("robosuite_gen3", 0.0)])
def test_a_near_members_sets_claim_no_proof_and_match_dense_sampling_of_its_file_to_1e_9(key, margin):
    """A near member's sets (the ideal chain's breakpoints, the gaps classified by the polished IK, the ends moved
    onto the file's chain) are not proved; every one of DENSE random parameters farther than NEAR_END from a set end
    (FOLD_END from an end where the branch stops being valid) is in the set iff the compiled IK's branch is valid with
    every joint inside the limits shrunk by ``margin``, and so are the parameters 10 NEAR_END either side of every
    end, also near the file's folds that its ideal chain does not have (where the polished branch stops being valid
    near a singular configuration: :func:`qpik.analytic.set_ends.resample`); every valid branch reaches the pose by
    the file's FK to 1e-10. One pose per arm and margin (four in the large run)."""
    robot = model_robot(key)
    solver = closed_form_for(robot)
    assert not solver.sets_proved
    lo, hi = shrunk_limits(robot.q_min, robot.q_max, margin)
    dense = np.random.default_rng(3).uniform(-np.pi, np.pi, DENSE)
    q = np.random.default_rng(20).uniform(lo, hi, (4 if LARGE else 1, 7))  # inside the shrunk limits
    for T, param, branch in zip(robot.fk(q), *qpik.redundancy_parameter(robot, q)):
        fi = qpik.feasible_intervals(robot, T, margin=margin)
        assert not fi.proved and fi.contains(int(branch), param)
        every = np.array([x for k in range(8) for iv in fi[k] for x in iv])
        beside = np.concatenate([every - 10 * NEAR_END, every + 10 * NEAR_END])
        x = np.concatenate([dense, beside[np.abs(beside) < np.pi]])
        sols = [solver.solve_one(T, v) for v in x]
        Q, valid = np.stack([s.q for s in sols]), np.stack([s.valid for s in sols])
        assert np.abs(robot.fk(Q[valid]) - T).max() < 1e-10
        inside = valid & np.all((lo <= Q) & (hi >= Q), axis=-1)
        for k in range(8):
            ends = np.array([v for iv in fi[k] for v in iv])
            fold = [solver.solve_one(T, e - FOLD_END).valid[k] != solver.solve_one(T, e + FOLD_END).valid[k]
                    for e in ends]  # fmt: skip
            width = np.where(fold, FOLD_END, NEAR_END)
            near = (np.abs(x[:, None] - ends[None, :]) < width[None, :]).any(axis=1)
            wrong = (fi.contains(k, x) != inside[:, k]) & ~near
            assert not wrong.any(), f"branch {k}: {fi[k]} at {x[wrong][:5]}"


@pytest.mark.parametrize("key", ["erd_xarm7", "robosuite_gen3"])
def test_a_near_members_sets_follow_its_files_folds_where_its_ideal_chain_nearly_folds(key):
    """Where a branch's validity on the ideal chain is small, in [0, ``thin``) (two solutions of a subproblem close
    together), the file's chain may have none (it folds where the ideal one does not): the sets follow the file's
    polished branches there too. Per pose, 2,000 of the parameters of a grid of 400,001 where some branch's ideal
    validity is that small (the ideal chain's validity in numpy, not the search's): each branch's state by the
    compiled IK against the sets, but within FOLD_END of an end. Over four poses at least one sample must be such a
    fold (the ideal chain's branch valid, the polished one not)."""
    robot = model_robot(key)
    solver = closed_form_for(robot)
    ideal = getattr(solver, "inner", solver)  # the Gen3 is read from the flange: its inner solver at T⁻¹
    grid = np.linspace(-np.pi, np.pi, 400_001)
    rng = np.random.default_rng(7)
    folds = 0
    for T in robot.fk(np.random.default_rng(20).uniform(robot.q_min, robot.q_max, (4, 7))):
        Ts = T if ideal is solver else np.linalg.inv(T)
        v = np.array(ideal.validity(Ts[:3, :3], Ts[:3, 3], grid, sy.NUMPY))
        thin = (v >= 0.0) & (v < ideal.thin)
        x = rng.choice(grid[thin.any(axis=0)], min(int(thin.any(axis=0).sum()), 2000), replace=False)
        fi = qpik.feasible_intervals(robot, T)
        sols = solver.solve_many(T, x)
        ideal_valid = np.array(ideal.validity(Ts[:3, :3], Ts[:3, 3], x, sy.NUMPY)) >= 0.0
        folds += int((ideal_valid.T & ~sols.valid).sum())
        for k in range(8):
            ends = np.array([e for iv in fi[k] for e in iv])
            near = (np.abs(x[:, None] - ends[None, :]) < FOLD_END).any(axis=1)
            wrong = (fi.contains(k, x) != sols.within_limits[:, k]) & ~near
            assert not wrong.any(), f"branch {k}: {fi[k]} at {x[wrong][:5]}"
    assert folds > 0


@pytest.mark.parametrize("key", ["erd_xarm7", "robosuite_gen3"])
def test_a_near_members_set_ends_where_its_branch_stops_being_valid_are_singular(key):
    """An end of a near member's set where the compiled IK's branch is valid on one side (2·FOLD_END away) and not on
    the other is a fold of the file's chain: it is listed among the branch's singular values (to 1e-9 rad), which
    solve_best's search samples closely (a Gen3 pose's best margin lay 1 mrad inside such an end, unsampled while the
    moved end was not listed). Over 8 poses there is at least one such end."""
    robot = model_robot(key)
    solver = closed_form_for(robot)
    listed = 0
    for T in robot.fk(np.random.default_rng(21).uniform(robot.q_min, robot.q_max, (8, 7))):
        fi = qpik.feasible_intervals(robot, T)
        for k in range(8):
            ends = np.array([e for iv in fi[k] for e in iv if abs(e) < np.pi])
            if not ends.size:
                continue
            valid = solver.solve_many(T, np.concatenate([ends - 2 * FOLD_END, ends + 2 * FOLD_END])).valid[:, k]
            fold = ends[valid[: len(ends)] != valid[len(ends) :]]
            sing = np.array(fi.singular[k])
            for e in fold:
                assert sing.size and np.abs(sing - e).min() < 1e-9, (k, e, sing)
            listed += len(fold)
    assert listed > 0


@pytest.mark.parametrize("key", ["erd_xarm7", "robosuite_gen3"])
def test_a_near_members_sets_match_its_answers_on_many_poses(key):
    """Poses 40-63 of 200 configurations inside the limits (all 200 in the large run), 2,000 random parameters each:
    every branch is in its set iff the compiled IK's branch is valid and inside the limits, but within FOLD_END of an
    end of its set. Among them the Gen3's pose 60, where one gap of the breakpoints held a thin stretch of branches
    2-5 (the file's chain folding over 0.04 rad) around its middle, where it was classified: those branches' sets
    were empty, the branches valid on the rest of the circle."""
    robot = model_robot(key)
    solver = closed_form_for(robot)
    q = np.random.default_rng(99).uniform(robot.q_min, robot.q_max, (200, 7))
    for n, T in zip(range(200) if LARGE else range(40, 64), robot.fk(q if LARGE else q[40:64])):
        fi = qpik.feasible_intervals(robot, T)
        x = np.random.default_rng(n).uniform(-np.pi, np.pi, 2000)
        inside = solver.solve_many(T, x).within_limits
        for k in range(8):
            ends = np.array([e for iv in fi[k] for e in iv])
            near = (np.abs(x[:, None] - ends[None, :]) < FOLD_END).any(axis=1) if ends.size else np.zeros(2000, bool)
            wrong = (fi.contains(k, x) != inside[:, k]) & ~near
            assert not wrong.any(), f"pose {n}, branch {k}: {fi[k]} at {x[wrong][:5]}"


@pytest.mark.parametrize("key, locked", [("erd_xarm7", 6), ("robosuite_gen3", 0)])
def test_a_polished_near_members_batch_single_and_casadi_agree(key, locked):
    """The polish is in the one source: the compiled single pose, the CasADi function and numpy agree (the xArm7
    with q7 locked, the Gen3 read from the flange with q1 locked)."""
    robot = model_robot(key)
    solver = closed_form_for(robot)
    q = random_q(robot, 30, 5)
    T = robot.fk(q)
    batch = qpik.ik(robot, T, q[:, locked])
    for n in range(len(T)):
        one = qpik.ik(robot, T[n], q[n, locked])
        Q, valid, _ = (np.array(x) for x in solver.casadi_function(ca.DM(T[n]), q[n, locked]))
        assert np.array_equal(one.valid, batch.valid[n]) and np.array_equal(valid.ravel() > 0.5, batch.valid[n])
        ok = batch.valid[n]  # the rows of invalid branches are meaningless (a polish that went nowhere)
        # near the stretched elbow (q4 ≈ 2.74) the polish's last step amplifies the paths' different round-off
        np.testing.assert_allclose(one.q[ok], batch.q[n][ok], atol=1e-10, rtol=0)
        np.testing.assert_allclose(Q[ok], batch.q[n][ok], atol=1e-10, rtol=0)


@pytest.mark.parametrize("key", ["erd_xarm7", "robosuite_gen3"])
def test_an_unreachable_pose_of_a_polished_near_member_gives_finite_invalid_branches(key):
    robot = model_robot(key)
    T = robot.fk(robot.q_home)
    T[:3, 3] = (2.0, 0.0, 0.5)
    sols = qpik.ik(robot, T, 0.3)
    assert not sols.valid.any() and np.isfinite(sols.q).all()


def test_an_arm_beyond_the_near_tolerance_has_no_closed_form():
    """The xArm7 with axis 3 moved 1 mm (twice NEAR_TOL) is refused, with the miss in the reason (it is served by
    the 1-D search, qpik.analytic.locked_search)."""
    robot = model_robot("xarm7_offset")
    assert robot.closed_form == "locked_search"
    assert "not the locked-q7 closed form: axes 2-3 do not meet (1 mm apart)" in robot.notes


# ---- feasible q7 sets --------------------------------------------------------


@pytest.mark.parametrize("margin", [0.0, 0.2])
@pytest.mark.parametrize("seed", range(6))
def test_feasible_sets_match_dense_sampling(seed, margin):
    """Every sampled q7 more than 1e-9 rad from a set end is classified as the compiled IK's limit test says."""
    robot = PANDA
    lo, hi = shrunk_limits(robot.q_min, robot.q_max, margin)
    q = random_q(robot, 1, seed, margin=0.05)[0]
    T = robot.fk(q)
    fi = qpik.feasible_intervals(robot, T, margin=margin)
    assert fi.param_name == "q7"
    if margin == 0.0:
        k = qpik.redundancy_parameter(robot, q)[1]
        assert fi.contains(k, q[6])
    q7 = np.random.default_rng(seed).uniform(-np.pi, np.pi, DENSE)
    sols = qpik.ik(robot, np.broadcast_to(T, (DENSE, 4, 4)), q7)
    inside = sols.valid & np.all((sols.q >= lo) & (sols.q <= hi), axis=-1)
    for k in range(8):
        ends = np.array([x for iv in fi[k] for x in iv])
        near = np.abs(q7[:, None] - ends[None, :]).min(axis=1, initial=np.inf) < 1e-9
        assert np.array_equal(fi.contains(k, q7)[~near], inside[~near, k]), f"branch {k}: {fi[k]}"


@settings(max_examples=200, deadline=None)
@given(st.floats(-14.0, 0.0), st.floats(-14.0, 0.0))
def test_the_correction_rounds_grow_with_the_deviation_and_reach_the_residual_at_the_scale(e1, e2):
    """At least one round, more for a larger deviation D (10^-14 to 1 m), and the fewest such that D (D/SCALE)^k
    reaches the polish's residual unless capped."""
    lo, hi = sorted((10.0**e1, 10.0**e2))
    k_lo, k_hi = correction_rounds(lo), correction_rounds(hi)
    assert 1 <= k_lo <= k_hi <= MAX_ROUNDS
    if k_hi < MAX_ROUNDS and hi > 0:
        assert hi * (hi / SCALE) ** k_hi <= RESIDUAL_TOL * (1 + 1e-9)
        assert k_hi == 1 or hi * (hi / SCALE) ** (k_hi - 1) > RESIDUAL_TOL * (1 - 1e-9)
