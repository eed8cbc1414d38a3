"""The certified 1-D search with q1 locked (qpik.analytic.locked_search) on robosuite's Sawyer (and, q7 locked,
the Gen3 file, an exact member, its 0.35 mm wrist offset included), against MuJoCo's FK of the model files: the
configuration a pose came from is among the solutions, every solution reaches the pose, and on the exact Sawyer
every sign change of every error function on a dense grid of q4 (numpy, not the Taylor models) has its solution.
60 configurations per arm by default (a search takes ~30 ms), 2,000 with QPIK_TESTS_LARGE=1."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import LARGE, SEEDS, model_robot, mujoco_poses, random_q
from hypothesis import given, settings

from qpik.algebra import symbolic as sy
from qpik.analytic.locked_search import SIGNS, LockedSearch
from qpik.core.errors import InputError, NoClosedFormError

BATCH = 2000 if LARGE else 60
GRID = 20_000
_searches: dict[str, LockedSearch] = {}


def search(key: str) -> LockedSearch:
    if key not in _searches:
        _searches[key] = LockedSearch(model_robot(key).chain)
    return _searches[key]


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((np.asarray(a) - b + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("key", ["robosuite_sawyer", "sawyer_exact", "robosuite_gen3", "xarm7_offset"])
def test_the_search_finds_q_and_every_solution_reaches_the_pose_by_mujoco(key):
    """Over random q inside the limits: one solution is q to 1e-9 rad; every solution reaches the pose to 1e-10 by
    MuJoCo's FK of the file, at most 16 and no two the same; the searches of the exact members (the Sawyer
    unrounded, and, q7 locked, the Gen3 file and the xArm7 with axis 3 moved 1 mm) are proved. The Sawyer file (a
    near member: the ideal chain's roots polished on the file's) may miss q where the chain of joints 2-7 is near
    singular (σ_min < 1e-3; 3 of 2,000 on this seed, σ_min < 2e-4)."""
    robot = model_robot(key)
    s = search(key)
    assert s.locked == (7 if key in ("xarm7_offset", "robosuite_gen3") else 1) and s.reversed == (s.locked == 1)
    assert s.exact == (key != "robosuite_sawyer")
    q = random_q(robot, BATCH, 11)
    T = mujoco_poses(robot, q)
    others = [j for j in range(7) if j != s.locked - 1]
    sigma = np.linalg.svd(robot.jacobian(q)[:, :, others], compute_uv=False)[:, -1]
    missed = 0
    for qi, Ti, si in zip(q, T, sigma):
        sol = s.solve(Ti, qi[s.locked - 1])
        assert 0 < len(sol.q) <= 16 and sol.proved == s.exact
        if angle_diff(sol.q, qi).max(axis=1).min() >= 1e-9:
            assert not s.exact and si < 1e-3
            missed += 1
        assert np.abs(mujoco_poses(robot, sol.q) - Ti).max() < 1e-10
        assert np.all(angle_diff(sol.q[:, s.locked - 1], qi[s.locked - 1]) < 1e-15)
        apart = angle_diff(sol.q[:, None], sol.q[None]).max(axis=2) + np.eye(len(sol.q))
        assert apart.min() > 1e-8
    assert missed <= max(2, BATCH // 400)


@settings(max_examples=4, deadline=None)
@given(seed=SEEDS)
def test_every_sign_change_of_the_error_functions_has_its_solution(seed):
    """On the exact Sawyer at a random pose and q1: every sign change of e_b between two points of a dense grid of q4
    where the branch is valid (validity above 1e-6 at both) has a solution of branch b with q4 in that gap, and every
    solution is a root: e_b within 1e-12 of 0 there."""
    robot = model_robot("sawyer_exact")
    s = search("sawyer_exact")
    q = random_q(robot, 1, seed)[0]
    T = robot.fk(q)
    param = float(np.random.default_rng(seed).uniform(-np.pi, np.pi))
    sol = s.solve(T, param)
    assert sol.proved
    x = np.linspace(-np.pi, np.pi, GRID + 1)
    Ts = np.linalg.inv(T)
    R, p = sy.frame_of_batch(np.broadcast_to(Ts, (x.size, 4, 4)))
    for b, (s3, s12) in enumerate(SIGNS):
        e, valid, _ = s.error(R, p, param, x, (s3, s12), sy.NUMPY)
        e, valid = np.broadcast_to(e, x.shape), np.broadcast_to(valid, x.shape)
        change = (np.sign(e[:-1]) != np.sign(e[1:])) & (valid[:-1] > 1e-6) & (valid[1:] > 1e-6)
        q4 = sol.q[sol.branch == b, 3]
        for i in np.nonzero(change)[0]:
            assert ((q4 >= x[i] - 1e-9) & (q4 <= x[i + 1] + 1e-9)).any(), (b, x[i], q4)
        R1, p1 = sy.frame_of_batch(np.broadcast_to(Ts, (q4.size, 4, 4)))
        at, _, _ = s.error(R1, p1, param, q4, (s3, s12), sy.NUMPY)
        assert np.all(np.abs(at) < 1e-12)


def test_the_search_gives_no_solution_for_an_unreachable_pose_and_says_when_its_budget_ran_out():
    robot = model_robot("sawyer_exact")
    s = search("sawyer_exact")
    T = robot.fk(robot.q_home)
    T[:3, 3] = (2.0, 0.0, 0.5)
    sol = s.solve(T, 0.3)
    assert sol.q.shape == (0, 7) and sol.proved
    with pytest.raises(InputError, match="param"):
        s.solve(T, float("nan"))
    with pytest.raises(InputError, match="T"):
        s.solve(np.ones((4, 4)), 0.3)
    q = random_q(robot, 1, 4)[0]
    short = s.solve(robot.fk(q), q[0], rounds=2)
    assert not short.proved
    assert angle_diff(short.q, q).max(axis=1).min() < 1e-9  # the cells left are candidates: still found


def test_the_search_locks_q7_where_only_the_chain_itself_fits():
    """The Gen3 with a spherical wrist read from the flange has axis 5 through the point where axes 7 and 6 meet (the
    closed form's geometry, no search), but not read forwards (axis 3 passes 11.75 mm from where axes 1-2 meet): q7 is
    locked, and the search finds q. The Panda fits neither way (its axis 3 through that point)."""
    robot = model_robot("gen3_spherical")
    s = LockedSearch(robot.chain)
    assert s.locked == 7 and not s.reversed and s.exact
    q = random_q(robot, 20, 2)
    for qi, Ti in zip(q, mujoco_poses(robot, q)):
        sol = s.solve(Ti, qi[6])
        assert sol.proved and angle_diff(sol.q, qi).max(axis=1).min() < 1e-9
        assert np.abs(mujoco_poses(robot, sol.q) - Ti).max() < 1e-10
    why = "q1 locked: axes 7-6 do not meet (88 mm apart); q7 locked: axis 3 passes 0 µm from the point where axes 1-2"
    with pytest.raises(NoClosedFormError, match=re.escape(why)):
        LockedSearch(model_robot("erd_panda").chain)
