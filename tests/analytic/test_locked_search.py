"""The certified 1-D search with q1 locked (qpik.analytic.locked_search) on robosuite's Sawyer and example-robot-data's
Baxter (right arm, an exact member) (and, q7 locked, the Gen3 file, an exact member, its 0.35 mm wrist offset
included), against MuJoCo's FK of the model files: the configuration a pose came from is among the solutions, every
solution reaches the pose, and on the exact Sawyer every sign change of every error function on a dense grid of q4
(numpy, not the Taylor models) has its solution. 60 configurations per arm by default, 2,000 with QPIK_TESTS_LARGE=1.
Behind qpik.ik (the "locked_search" family, SearchSolver): the slots of the Sawyer, of Baxter and of the xArm7 with
axis 3 moved 1 mm, against MuJoCo's FK, the error functions and the solutions nearest along the parameter; 40
configurations per arm by default, 2,000 with QPIK_TESTS_LARGE=1. Baxter's notes give the offsets of its axes as
MuJoCo places them."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest
from conftest import LARGE, MODELS, SEEDS, model_robot, mujoco_poses, random_q, random_robot
from hypothesis import given, settings

import qpik
from qpik.algebra import symbolic as sy
from qpik.analytic import closed_form_for
from qpik.analytic.locked_search import LockedSearch
from qpik.analytic.search_geometry import ElbowSearch, ShoulderSearch, search_for
from qpik.analytic.trig import EPS
from qpik.core.errors import InputError, NoClosedFormError
from qpik.robots.model_files import MeshOptions

BATCH = 2000 if LARGE else 60
GRID = 20_000
_searches: dict[str, LockedSearch] = {}


def search(key: str) -> LockedSearch:
    if key not in _searches:
        _searches[key] = ShoulderSearch(model_robot(key).chain)
    return _searches[key]


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((np.asarray(a) - b + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("key", ["robosuite_sawyer", "sawyer_exact", "erd_baxter", "robosuite_gen3", "xarm7_offset"])
def test_the_search_finds_q_and_every_solution_reaches_the_pose_by_mujoco(key):
    """Over random q inside the limits: one solution is q to 1e-9 rad; every solution reaches the pose to 1e-10 by
    MuJoCo's FK of the file, at most 16 and no two the same; the searches of the exact members (the Sawyer
    unrounded, example-robot-data's Baxter (right arm), and, q7 locked, the Gen3 file and the xArm7 with axis 3 moved
    1 mm) are proved. The Sawyer file (a near member: the ideal chain's roots and near-roots polished on the file's)
    is not proved, and holds q too, also where the chain of joints 2-7 is near singular (σ_min down to 1e-5 among
    these q), where the ideal chain's error function only nears 0 at the file's pair of roots."""
    robot = model_robot(key)
    s = search(key)
    assert s.locked == (7 if key in ("xarm7_offset", "robosuite_gen3") else 1) and s.reversed == (s.locked == 1)
    assert s.exact == (key != "robosuite_sawyer")
    q = random_q(robot, BATCH, 11)
    T = mujoco_poses(robot, q)
    for qi, Ti in zip(q, T):
        sol = s.solve(Ti, qi[s.locked - 1])
        assert 0 < len(sol.q) <= 16 and sol.proved == s.exact
        assert angle_diff(sol.q, qi).max(axis=1).min() < 1e-9
        assert np.abs(mujoco_poses(robot, sol.q) - Ti).max() < 1e-10
        assert np.all(angle_diff(sol.q[:, s.locked - 1], qi[s.locked - 1]) < 1e-15)
        apart = angle_diff(sol.q[:, None], sol.q[None]).max(axis=2) + np.eye(len(sol.q))
        assert apart.min() > 1e-8


@settings(max_examples=4, deadline=None)
@given(seed=SEEDS)
def test_the_search_over_the_first_joint_serves_random_arms_of_its_geometry(seed):
    """Random DH arms (random lengths, twists, offsets, base and tool) with a3 = a5 = 0, so that axes 3-4 and 5-6 meet
    and no other pair does: no closed form and not the search over q4, but the search over q1 with q7 locked
    (ElbowSearch, read forwards). Over 10 random q inside the limits each: q is among the solutions to 1e-9 rad and
    every solution reaches the pose to 1e-10 by MuJoCo's FK of the arm's MJCF, also where the search ran out of its
    budget (``proved`` False: on some of these arms, for several poses in 10; its cells left are candidates)."""
    robot = random_robot(seed, "standard")
    a = list(robot.chain.a)
    a[2] = a[4] = 0.0
    robot = replace(robot, chain=replace(robot.chain, a=tuple(a)))
    s = search_for(robot.chain)
    assert isinstance(s, ElbowSearch) and not s.reversed and s.locked == 7
    q = random_q(robot, 10, seed)
    for qi, Ti in zip(q, mujoco_poses(robot, q)):
        sol = s.solve(Ti, qi[6])
        assert angle_diff(sol.q, qi).max(axis=1).min() < 1e-9
        assert np.abs(mujoco_poses(robot, sol.q) - Ti).max() < 1e-10


@pytest.mark.parametrize("key", ["sawyer_exact", "robosuite_sawyer"])
@settings(max_examples=4, deadline=None)
@given(seed=SEEDS)
def test_every_sign_change_of_the_error_functions_has_its_solution(key, seed):
    """At a random pose (MuJoCo's FK) and q1: every sign change of e_b between two points of a dense grid of the search
    variable where the branch is valid (validity above 1e-6 at both) has a solution of branch b there, and every
    solution is a root (e_b within 1e-12 of 0): the search over q4 of the Sawyer unrounded, the search over q7 of
    robosuite's Sawyer file (search_for's choice)."""
    robot = model_robot(key)
    s = search(key) if key == "sawyer_exact" else search_for(robot.chain)
    q = random_q(robot, 1, seed)[0]
    T = mujoco_poses(robot, q[None])[0]
    param = float(np.random.default_rng(seed).uniform(-np.pi, np.pi))
    sol = s.solve(T, param)
    assert sol.proved
    x = np.linspace(-np.pi, np.pi, GRID + 1)
    Ts = np.linalg.inv(T)
    R, p = sy.frame_of_batch(np.broadcast_to(Ts, (x.size, 4, 4)))
    for b, signs in enumerate(s.signs):
        e, valid, _ = s.error(R, p, param, x, tuple(signs), sy.NUMPY)
        e, valid = np.broadcast_to(e, x.shape), np.broadcast_to(valid, x.shape)
        change = (np.sign(e[:-1]) != np.sign(e[1:])) & (valid[:-1] > 1e-6) & (valid[1:] > 1e-6)
        roots = sol.q[sol.branch == b, s.variable_joint]
        for i in np.nonzero(change)[0]:
            assert ((roots >= x[i] - 1e-9) & (roots <= x[i + 1] + 1e-9)).any(), (b, x[i], roots)
        R1, p1 = sy.frame_of_batch(np.broadcast_to(Ts, (roots.size, 4, 4)))
        at, _, _ = s.error(R1, p1, param, roots, tuple(signs), sy.NUMPY)
        assert np.all(np.abs(at) < 1e-12)


def test_the_reach_that_discards_cells_first_holds_every_configuration_and_bounds_every_validity():
    """LockedSearch.reach, by which the search discards cells of q4 for every branch at once: at the pose (MuJoCo's FK)
    and q1 of random configurations of the exact Sawyer it is not negative at their own q4; on a dense grid of q4 it
    bounds every branch's validity (minus EPS)."""
    robot = model_robot("sawyer_exact")
    s = search("sawyer_exact")
    q = random_q(robot, BATCH, 13)
    Ts = np.linalg.inv(mujoco_poses(robot, q))
    R, p = sy.frame_of_batch(Ts)
    assert np.all(s.reach(R, p, q[:, 0], q[:, 3], sy.NUMPY) > -1e-12)
    x = np.linspace(-np.pi, np.pi, GRID + 1)
    R, p = sy.frame_of_batch(np.broadcast_to(Ts[0], (x.size, 4, 4)))
    top = s.reach(R, p, q[0, 0], x, sy.NUMPY)
    assert (top < 0).any() and (top > 0).any()
    for s3, s12 in ShoulderSearch.signs:
        _, valid, _ = s.error(R, p, q[0, 0], x, (s3, s12), sy.NUMPY)
        assert np.all(valid - EPS <= top + 1e-15)


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
    s = ShoulderSearch(robot.chain)
    assert s.locked == 7 and not s.reversed and s.exact
    q = random_q(robot, 20, 2)
    for qi, Ti in zip(q, mujoco_poses(robot, q)):
        sol = s.solve(Ti, qi[6])
        assert sol.proved and angle_diff(sol.q, qi).max(axis=1).min() < 1e-9
        assert np.abs(mujoco_poses(robot, sol.q) - Ti).max() < 1e-10
    why = "q1 locked: axes 7-6 do not meet (88 mm apart); q7 locked: axis 3 passes 0 µm from the point where axes 1-2"
    with pytest.raises(NoClosedFormError, match=re.escape(why)):
        ShoulderSearch(model_robot("erd_panda").chain)


def test_baxter_says_it_is_searched_with_the_offsets_of_its_axes_by_mujoco():
    """Baxter's right arm (example-robot-data): served by the search with q1 locked, and its notes give the distances
    between consecutive joint axes (mm) as MuJoCo places the axes at q = 0: axes 2-3, 4-5, 6-7 meet (< 1 µm apart),
    axes 1-2, 3-4 and 5-6 do not (69, 69 and 10 mm in the file), and along axes 3 and 5 the distance between the feet
    of the common normals with their neighbours (364.4 and 374.3 mm in the file)."""
    import mujoco

    robot = model_robot("erd_baxter")
    assert robot.closed_form == "locked_search" and robot.dof == 7
    assert robot.notes.startswith("served by a certified 1-D search over q4 with q1 locked")
    model = robot.mj_model()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ids = [model.joint(n).id for n in robot.joint_names]
    point, axis = data.xanchor[ids], data.xaxis[ids]

    def normal(i: int, j: int) -> tuple[float, np.ndarray, np.ndarray]:
        """Distance between axes i and j (0-based) and the feet of their common normal on each."""
        n = np.cross(axis[i], axis[j])
        d = point[j] - point[i]
        a = np.array([[axis[i] @ axis[i], -axis[i] @ axis[j]], [axis[i] @ axis[j], -axis[j] @ axis[j]]])
        s, t = np.linalg.solve(a, [d @ axis[i], d @ axis[j]])
        return abs(d @ n) / np.linalg.norm(n), point[i] + s * axis[i], point[j] + t * axis[j]

    gaps = [normal(i, i + 1)[0] for i in range(6)]
    assert max(gaps[1], gaps[3], gaps[5]) < 1e-6
    assert robot.notes.count("axes 2-3, 4-5, 6-7 meet") == 1
    for i in (0, 2, 4):
        assert gaps[i] > 5e-3
        assert f"axes {i + 1}-{i + 2} {gaps[i] * 1e3:.0f} mm apart" in robot.notes
    for k in (2, 4):  # axes 3 and 5 (0-based): the feet of the normals with axes k-1 and k+1
        along = np.linalg.norm(normal(k - 1, k)[2] - normal(k, k + 1)[1])
        assert f"axis {k + 1} {along * 1e3:.1f} mm" in robot.notes
    assert [round(g * 1e3) for g in gaps[::2]] == [69, 69, 10]


def test_the_sawyer_file_is_searched_over_q7_on_its_own_axes_and_agrees_with_its_near_search():
    """robosuite's Sawyer: its axes 7-6 miss by 0.8 µm, so the search over q4 runs on its ideal chain (a near member),
    but its axes 5-4 and 3-2 meet: search_for picks the search over q7 (ElbowSearch), exact. Over random q inside the
    limits, its solutions are proved, hold q to 1e-9 rad, reach the pose to 1e-10 by MuJoCo's FK of the file, and are
    the near search's solutions (each within 1e-8 rad of one of them, and as many)."""
    robot = model_robot("robosuite_sawyer")
    s = search_for(robot.chain)
    assert isinstance(s, ElbowSearch) and s.exact and s.locked == 1 and s.variable_joint == 6
    near = search("robosuite_sawyer")
    assert not near.exact
    q = random_q(robot, BATCH, 17)
    for qi, Ti in zip(q, mujoco_poses(robot, q)):
        sol = s.solve(Ti, qi[0])
        assert sol.proved and 0 < len(sol.q) <= 16
        assert angle_diff(sol.q, qi).max(axis=1).min() < 1e-9
        assert np.abs(mujoco_poses(robot, sol.q) - Ti).max() < 1e-10
        other = near.solve(Ti, qi[0]).q
        apart = angle_diff(sol.q[:, None], other[None]).max(axis=2)
        assert len(other) == len(sol.q) and apart.min(axis=1).max() < 1e-8 and apart.min(axis=0).max() < 1e-8


def test_the_sawyer_asked_for_q7_is_searched_over_q1():
    """The Sawyer file loaded with ``redundancy="q7"``: no closed form, but read forwards its axes 3-4 and 5-6 meet, so
    the search over q1 with q7 locked serves it; qpik.ik holds random q (to 1e-9 rad) at their own q7, and every valid
    slot reaches the pose to 1e-10 by MuJoCo's FK of the file."""
    path, options = MODELS["robosuite_sawyer"]()
    robot = qpik.load_robot(path, redundancy="q7", **options)
    assert robot.closed_form == "locked_search" and not robot.canonical.reversed
    assert robot.notes.startswith("served by a certified 1-D search over q1 with q7 locked")
    q = random_q(robot, 10, 23)
    for qi, Ti in zip(q, mujoco_poses(robot, q)):
        sols = qpik.ik(robot, Ti, float(qi[6]))
        assert sols.param_name == "q7"
        assert np.where(sols.valid, angle_diff(sols.q, qi).max(axis=1), np.inf).min() < 1e-9
        assert np.abs(mujoco_poses(robot, sols.q[sols.valid]) - Ti).max() < 1e-10


# ---- behind qpik.ik: the "locked_search" family ---------------------------------

API_BATCH = 2000 if LARGE else 40


@pytest.mark.parametrize("key", ["robosuite_sawyer", "erd_baxter", "xarm7_offset"])
def test_ik_holds_q_in_its_slot_and_every_valid_slot_reaches_the_pose_by_mujoco(key):
    """qpik.ik on random q inside the limits (the Sawyer: q1 locked, its file served by the search over q7, exact;
    Baxter's right arm: q1 locked, over q4, exact; the xArm7 with axis 3 moved 1 mm: q7 locked, over q4, exact): 16
    finite slots; one valid slot holds q to
    1e-9 rad (modulo 2π), within limits, and it is the slot that redundancy_parameter names (from qpik's FK of q, not
    MuJoCo's pose) unless the pose has a singular slot (a root of two error functions, whose b round-off decides);
    every valid slot reaches the pose to 1e-10 by MuJoCo's FK of the file and holds the locked joint at the
    parameter; the slots hold the search's roots as documented (the j-th of b in increasing search variable in slot
    4b + j, those past the fourth in the lowest slots left; singular where the search says a root is double), and
    every regular root is a root of its e_b: e_b there over its slope (a forward difference)
    below 1e-7 rad (e_b loses digits near some roots: on Baxter |e_b| 1e-7 at roots that reach their pose to
    1e-10)."""
    robot = model_robot(key)
    locked = 6 if key == "xarm7_offset" else 0
    x = "q7" if key == "robosuite_sawyer" else "q4"
    assert robot.closed_form == "locked_search" and robot.canonical.reversed == (locked == 0)
    assert robot.notes.startswith(f"served by a certified 1-D search over {x} with q{locked + 1} locked")
    assert not robot.branch_functions and robot.canonical.exact
    s = closed_form_for(robot).search
    assert isinstance(s, ElbowSearch if key == "robosuite_sawyer" else ShoulderSearch) and s.exact
    j = s.variable_joint
    q = random_q(robot, API_BATCH, 21)
    T = mujoco_poses(robot, q)
    param, branch = qpik.redundancy_parameter(robot, q)
    np.testing.assert_array_equal(param, sy.NUMPY.wrap(q[:, locked]))
    for qi, Ti, pi, bi in zip(q, T, param, branch):
        sols = qpik.ik(robot, Ti, float(pi))
        assert sols.q.shape == (16, 7) and np.isfinite(sols.q).all() and sols.param_name == f"q{locked + 1}"
        assert list(sols.branch) == list(range(16)) and not (sols.singular & ~sols.valid).any()
        assert 0 < sols.valid.sum() <= 16 and not (sols.within_limits & ~sols.valid).any()
        apart = np.where(sols.valid, angle_diff(sols.q, qi).max(axis=1), np.inf)
        assert apart.min() < 1e-9 and sols.within_limits[np.argmin(apart)]
        assert bi == np.argmin(apart) or sols.singular.any()
        good = sols.q[sols.valid]
        assert np.abs(mujoco_poses(robot, good) - Ti).max() < 1e-10
        assert np.all(angle_diff(sols.q[:, locked], pi) < 1e-15)
        sol = s.solve(Ti, float(pi))  # the documented numbering of the search's roots
        want, rank, spill = np.full(16, -1), [0] * 4, []
        for i in sorted(range(len(sol.q)), key=lambda i: (sol.branch[i], sol.q[i, j])):
            b = sol.branch[i]
            if rank[b] < 4:
                want[4 * b + rank[b]] = i
            else:
                spill.append(i)
            rank[b] += 1
        want[np.flatnonzero(want < 0)[: len(spill)]] = spill
        np.testing.assert_array_equal(sols.valid, want >= 0)
        assert angle_diff(sols.q[want >= 0], sol.q[want[want >= 0]]).max() < 1e-15
        np.testing.assert_array_equal(sols.singular[want >= 0], sol.double[want[want >= 0]])
        regular = ~sol.double
        if regular.any():  # each regular root is a root of its e_b
            Ts = np.linalg.inv(Ti) if locked == 0 else Ti
            R, p = sy.frame_of_batch(np.broadcast_to(Ts, (int(regular.sum()), 4, 4)))
            signs = s.signs[sol.branch[regular]]
            e, slope = (
                s.error(R, p, float(pi), sol.q[regular, j] + h, (signs[:, 0], signs[:, 1]), sy.NUMPY)[0]
                for h in (0.0, 1e-6)
            )
            slope = (slope - e) / 1e-6
            assert np.all(np.abs(e) <= 1e-7 * np.abs(slope))  # a Newton step of e_b below 1e-7 rad
    batch = qpik.ik(robot, T[:3], param[:3])
    assert batch.q.shape == (3, 16, 7)
    for i in range(3):
        np.testing.assert_array_equal(batch.q[i], qpik.ik(robot, T[i], float(param[i])).q)
    assert qpik.redundancy_parameter(robot, q[0]) == (float(param[0]), int(branch[0]))


def test_a_slot_keeps_its_solution_along_the_parameter():
    """Along small steps of q1 (2e-3 rad) at poses of random q of the Sawyer: wherever the set of valid slots does not
    change, each valid slot's next solution is the one nearest to its last (the numbering follows the roots)."""
    robot = model_robot("robosuite_sawyer")
    steps = 0
    for qi in random_q(robot, 3, 5):
        T = robot.fk(qi)
        last = None
        for x in qi[0] + np.linspace(-0.02, 0.02, 21):
            sols = qpik.ik(robot, T, float(x))
            if last is not None and np.array_equal(last.valid, sols.valid):
                for k in np.flatnonzero(sols.valid):
                    apart = np.where(sols.valid, angle_diff(sols.q, last.q[k]).max(axis=1), np.inf)
                    assert np.argmin(apart) == k
                    steps += 1
            last = sols
    assert steps > 200


def test_the_searched_family_says_what_it_does_not_serve():
    """An unreachable pose: 16 invalid finite slots; the home pose, q = 0, where a continuum of configurations reaches
    it at q1 = 0: 16 valid singular slots, each reaching it by MuJoCo's FK. load_robot's override: asked for ψ, the
    Sawyer has no closed form."""
    robot = model_robot("robosuite_sawyer")
    T = robot.fk(robot.q_home)
    T[:3, 3] = (2.0, 0.0, 0.5)
    sols = qpik.ik(robot, T, 0.3)
    assert not sols.valid.any() and np.isfinite(sols.q).all() and np.all(sols.q[:, 0] == 0.3)
    home = mujoco_poses(robot, robot.q_home[None])[0]  # q = 0: axes aligned, a continuum of solutions at q1 = 0
    sols = qpik.ik(robot, home, 0.0)
    assert sols.valid.all() and sols.singular.all()
    assert np.abs(mujoco_poses(robot, sols.q) - home).max() < 1e-10
    psi = qpik.load_robot(robot.model.path, redundancy="psi", meshes=MeshOptions(collision_only=True))
    assert psi.closed_form is None and "not srs" in psi.notes
