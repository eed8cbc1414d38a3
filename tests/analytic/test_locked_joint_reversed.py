"""The locked-joint closed form read from the flange (q1 locked;
qpik.analytic.locked_joint_reversed.ReversedLockedJointSolver)
on robosuite's Kinova Gen3 and Jaco, against MuJoCo's FK of the model files: the Gen3 file itself (a near member: its
axes 5 and 7 pass 0.35 mm apart), the Gen3 file with a spherical wrist and the Jaco file (exact members, proved
feasible sets); and the notes of the Gen3, the Jaco and the Sawyer (no closed form), with their real offsets. 200
configurations per arm and seed by default, 2,000 with QPIK_TESTS_LARGE=1."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, SEEDS, model_robot, mujoco_poses, random_q
from hypothesis import given, settings

import qpik
from qpik.analytic.api import closed_form_for
from qpik.analytic.intervals import shrunk_limits
from qpik.analytic.locked_joint_reversed import ReversedLockedJointSolver
from qpik.analytic.polish import RESIDUAL_TOL
from qpik.core.errors import InputError
from qpik.robots.locked_joint import reversed_chain
from qpik.robots.model_files import MeshOptions

BATCH = 2000 if LARGE else 200
DENSE = 20_000
NEAR_END = 1e-9
"""rad: the Gen3 file's set ends are moved onto the file's chain to this (qpik.analytic.set_ends)."""
PROPERTY = settings(max_examples=3, deadline=None)


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a − b| on the circle (rad)."""
    return np.abs((np.asarray(a) - b + np.pi) % (2 * np.pi) - np.pi)


def sigma_2_7(robot: qpik.Robot, q: np.ndarray) -> np.ndarray:
    """The smallest singular value of the Jacobian of joints 2-7 (the 6-R chain left with q1 locked), (N,)."""
    return np.linalg.svd(robot.jacobian(q)[:, :, 1:], compute_uv=False)[:, -1]


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
@pytest.mark.parametrize("key", ["robosuite_gen3", "robosuite_sawyer", "robosuite_jaco", "erd_panda"])
def test_the_reversed_chain_has_the_inverse_fk(key, seed):
    """FK of the chain read from the flange at the joints reversed is the inverse of the arm's, to 1e-12."""
    robot = model_robot(key)
    q = random_q(robot, 50, seed)
    T = reversed_chain(robot.chain).fk(q[:, ::-1])
    np.testing.assert_allclose(T, np.linalg.inv(mujoco_poses(robot, q)), atol=1e-12, rtol=0)


def test_the_gen3_notes_name_its_offsets_and_the_reversed_closed_form():
    robot = model_robot("robosuite_gen3")
    assert robot.closed_form == "locked_joint" and robot.canonical.reversed and not robot.canonical.exact
    notes = robot.notes
    assert "closed form with q1 locked (the chain read from the flange" in notes
    assert "axes 7-6-5 meet (spherical wrist), axes 3-2 meet" in notes
    assert "axes 1-2, 2-3, 3-4, 4-5, 5-6, 6-7 meet" in notes
    assert "along axis 2 11.75 mm, axis 3 420.8 mm, axis 4 12.75 mm, axis 5 314.4 mm, axis 6 0.3505 mm" in notes
    assert "axis 5 passes 350.5 µm from the wrist point" in notes and "feasible sets not proved" in notes
    assert "(qpik.analytic.locked_joint, qpik.analytic.polish)" in notes and "perpendicular" not in notes
    assert "IK by a certified 1-D search over q4 with q7 locked" in notes
    solver = closed_form_for(robot)
    assert isinstance(solver, ReversedLockedJointSolver) and solver.param_name == "q1"
    exact = model_robot("gen3_spherical")
    assert exact.canonical.reversed and exact.canonical.exact and "axis 6" not in exact.notes
    assert "polish" not in exact.notes and closed_form_for(exact).sets_proved
    jaco = model_robot("robosuite_jaco")
    assert jaco.canonical.reversed and jaco.canonical.exact and "q1 locked" in jaco.notes
    assert "along axis 2 1.6 mm, axis 3 410 mm, axis 4 11.4 mm, axis 5 311.1 mm between" in jaco.notes


def test_the_sawyer_notes_name_its_offsets_and_why_no_closed_form():
    """The Sawyer: axis 1 81 mm from axis 2, every other consecutive pair meets, no three in one point: no closed form,
    served by the 1-D search over q7 with q1 locked (its axes 5-4 and 3-2 meet); asked for q7, the search over q1 with
    q7 locked (its axes 3-4 and 5-6 meet)."""
    robot = model_robot("robosuite_sawyer")
    assert robot.closed_form == "locked_search" and robot.canonical.reversed
    notes = robot.notes
    assert notes.startswith(
        "served by a certified 1-D search over q7 with q1 locked (qpik.analytic.search_geometry.ElbowSearch), no "
        "closed form: "
        "axes 2-3, 3-4, 4-5, 5-6 meet, axes 1-2 81 mm apart"
    )
    assert "along axis 2 192.5 mm, axis 3 400 mm, axis 4 168.5 mm, axis 5 400 mm, axis 6 136.3 mm" in notes
    assert "not the locked-q7 closed form: axes 1-2 do not meet (81 mm apart)" in notes
    assert "not the locked-q1 closed form: axes 7-6-5 do not meet in one point (axis 5 passes 136.3 mm" in notes
    assert "perpendicular" not in notes
    assert "1-D search over q4 with q7 locked" in model_robot("xarm7_offset").notes
    q = random_q(robot, 1, 3)[0]
    assert qpik.ik(robot, robot.fk(q), float(q[0])).param_name == "q1"
    q7 = qpik.load_robot(robot.model.path, redundancy="q7", meshes=MeshOptions(collision_only=True))
    assert q7.closed_form == "locked_search"
    assert "not the locked-q7 closed form: axes 1-2 do not meet (81 mm apart)" in q7.notes
    assert q7.notes.startswith("served by a certified 1-D search over q1 with q7 locked")


def test_the_q1_override():
    """``redundancy="q1"`` asks for the reversed family only; no catalog arm locks q1."""
    path = model_robot("robosuite_gen3").model.path
    gen3 = qpik.load_robot(path, redundancy="q7")
    assert gen3.closed_form == "locked_search" and not gen3.canonical.reversed  # its q7 by the search
    assert "not the locked-q7 closed form: axes 1-2-3 do not meet in one point" in gen3.notes
    assert "locked-q1" not in gen3.notes
    assert qpik.load_robot(path, redundancy="q1").canonical.reversed
    with pytest.raises(InputError, match="redundancy"):
        qpik.load_robot("panda", redundancy="q1")


@PROPERTY
@given(seed=SEEDS)
@pytest.mark.parametrize("key", ["gen3_spherical", "robosuite_jaco", "erd_talos"])
def test_ik_of_an_exact_member_holds_q_and_every_branch_reaches_the_pose(key, seed):
    """The exact members: ``ik(fk(q), q1)`` holds q as branch ``redundancy_parameter(q)`` to 1e-9 rad (or 1e-14/σ_min
    where the 6-R chain of joints 2-7 is that close to singular), within limits; every valid branch reaches the pose
    to 1e-10 by MuJoCo's FK of the file, and its own parameter and branch id are (q1, its id)."""
    robot = model_robot(key)
    q = random_q(robot, BATCH, seed)
    T = mujoco_poses(robot, q)
    param, branch = qpik.redundancy_parameter(robot, q)
    assert angle_diff(param, q[:, 0]).max() < 1e-15
    sols = qpik.ik(robot, T, param)
    rows = np.arange(BATCH)
    err = angle_diff(sols.q[rows, branch], q).max(axis=1)
    sigma = sigma_2_7(robot, q)
    assert np.all((err < 1e-9) | (err * sigma < 1e-14)), (err.max(), sigma[err.argmax()])
    assert sols.valid[rows, branch].all() and sols.within_limits[rows, branch].all()
    assert np.isfinite(sols.q).all() and sols.valid.sum() > 4 * BATCH
    F = mujoco_poses(robot, sols.q[sols.valid])
    assert np.abs(F - np.repeat(T, sols.valid.sum(1), axis=0)).max() < 1e-10
    back, ids = qpik.redundancy_parameter(robot, sols.q[sols.valid])
    assert angle_diff(back, np.repeat(param, sols.valid.sum(1))).max() < 1e-12
    ok = ~sols.singular[sols.valid]  # where two roots coincide either id may come back
    assert np.array_equal(ids[ok], np.nonzero(sols.valid)[1][ok])


@PROPERTY
@given(seed=SEEDS)
def test_ik_of_the_gen3_file_holds_q_and_every_valid_branch_reaches_the_pose_by_mujoco(seed):
    """The file (a near member, corrected and polished): every valid branch reaches the pose to 1e-10 by MuJoCo's FK
    of the file; the branch ``redundancy_parameter(q)`` holds q to 1e-9 rad, or to RESIDUAL_TOL/σ_min, unless the
    chain of joints 2-7 is all but singular (σ_min < 5e-4: the file's answers there lie ~0.35 mm/σ_min from the
    ideal chain's, where the corrections converge slowly). q is missed in its branch for at most 0.5% of the
    configurations (7 of 2,000 on one seed, each at σ_min < 5e-4)."""
    robot = model_robot("robosuite_gen3")
    q = random_q(robot, BATCH, seed)
    T = mujoco_poses(robot, q)
    param, branch = qpik.redundancy_parameter(robot, q)
    assert angle_diff(param, q[:, 0]).max() < 1e-15
    sols = qpik.ik(robot, T, param)
    err = np.where(sols.valid, angle_diff(sols.q, q[:, None]).max(axis=2), np.inf)
    sigma = sigma_2_7(robot, q)
    own = err[np.arange(BATCH), branch]
    held = (own < 1e-9) | (own * sigma < RESIDUAL_TOL)
    assert np.all(held | (sigma < 5e-4)), (own[~held], sigma[~held])
    assert (~held).sum() <= max(2, BATCH // 200)
    inside = robot.within_limits(sols.q.reshape(-1, 7)).reshape(BATCH, 8)
    assert np.isfinite(sols.q).all() and np.array_equal(sols.within_limits, sols.valid & inside)
    F = mujoco_poses(robot, sols.q[sols.valid])
    assert np.abs(F - np.repeat(T, sols.valid.sum(1), axis=0)).max() < 1e-10


def dense_mismatch(robot: qpik.Robot, T: np.ndarray, fi, margin: float, near_end: float) -> int:
    """Every one of DENSE random q1 farther than ``near_end`` from a set end is in the set iff the compiled IK's
    branch is valid with every joint inside the limits shrunk by ``margin``, or (for a near member) the branch is
    invalid there: the polish stopped short of the pose near the wrist singularity, which the sets do not see
    (:mod:`qpik.analytic.locked_joint_intervals`); returns how many of those. Every valid branch reaches the pose by
    the file's FK to 1e-10."""
    solver = closed_form_for(robot)
    lo, hi = shrunk_limits(robot.q_min, robot.q_max, margin)
    q1 = np.random.default_rng(3).uniform(-np.pi, np.pi, DENSE)
    sol = solver.solve_many(T, q1)
    assert np.abs(robot.fk(sol.q[sol.valid]) - T).max() < 1e-10
    inside = sol.valid & np.all((lo <= sol.q) & (hi >= sol.q), axis=-1)
    missed = 0
    for k in range(8):
        ends = np.array([x for iv in fi[k] for x in iv])
        near = np.abs(q1[:, None] - ends[None, :]).min(axis=1, initial=np.inf) < near_end
        wrong = (fi.contains(k, q1) != inside[:, k]) & ~near
        assert not (wrong & (sol.valid[:, k] | fi.proved)).any(), f"branch {k}: {fi[k]}"
        missed += int(wrong.sum())
    return missed


@pytest.mark.parametrize("margin", [0.0, 0.3])
@pytest.mark.parametrize("key", ["gen3_spherical", "robosuite_jaco", "erd_talos", "robosuite_gen3"])
def test_the_feasible_q1_sets_match_dense_sampling(key, margin):
    """The sets of the exact member are proved and exact to 1e-9 rad at their ends; the file's (a near member) are
    not proved, exact away from NEAR_END of their ends (their ends moved onto the file's chain) but where the polished
    branch is invalid (at most 0.1% of the samples). They hold the configuration the pose came from. Two poses per
    margin (six in the large run)."""
    robot = model_robot(key)
    exact = key != "robosuite_gen3"
    lo, hi = shrunk_limits(robot.q_min, robot.q_max, margin)
    q = np.random.default_rng(21).uniform(lo, hi, (6 if LARGE else 2, 7))
    for T, param, branch in zip(robot.fk(q), *qpik.redundancy_parameter(robot, q)):
        fi = qpik.feasible_intervals(robot, T, margin=margin)
        assert fi.param_name == "q1" and fi.proved == exact and fi.contains(int(branch), param)
        assert dense_mismatch(robot, T, fi, margin, 1e-9 if exact else NEAR_END) <= 8 * DENSE // 1000
