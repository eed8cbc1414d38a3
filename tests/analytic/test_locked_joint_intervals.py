"""The Panda's locked-q7 feasible sets, proved per pose (qpik.analytic.locked_joint_intervals): against dense sampling
of q7 through the compiled IK's own limit test, at random and at singular configurations, and every root the search
finds a sign change (or a touch) of a column evaluated through numpy; a search without the budget to finish says it is
not proved, and solve_best and solve_full then claim no proof. A seeded subset of poses and samples by default, all
with QPIK_TESTS_LARGE=1."""

from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import LARGE, model_robot, random_q

import qpik
from qpik.algebra import symbolic as sy
from qpik.analytic.api import closed_form_for
from qpik.analytic.intervals import shrunk_limits
from qpik.analytic.locked_joint import LockedJointSolver
from qpik.analytic.locked_joint_intervals import _levels
from qpik.nlp import solve_best
from qpik.nlp.best_search import UNPROVED_SETS
from qpik.nlp.full import FullOptions, solve_full

PANDA = qpik.load_robot("panda")
SOLVER = closed_form_for(PANDA)
DENSE = 100_000 if LARGE else 20_000
POSES = 8 if LARGE else 3
"""Poses per seed and margin; special configurations: POSES + 1 each in the large run, 1 by default."""


def assert_dense(T: np.ndarray, margin: float, fi, robot: qpik.Robot = PANDA) -> None:
    """Every one of DENSE random q7 farther than 1e-9 rad from a set end is in the set iff the compiled IK's branch
    is valid with every joint inside the limits shrunk by ``margin``."""
    lo, hi = shrunk_limits(robot.q_min, robot.q_max, margin)
    q7 = np.random.default_rng(7).uniform(-np.pi, np.pi, DENSE)
    sol = closed_form_for(robot).solve_many(T, q7)
    inside = sol.valid & np.all((sol.q >= lo) & (sol.q <= hi), axis=-1)
    for k in range(8):
        ends = np.sort([x for iv in fi[k] for x in iv])
        if ends.size:
            i = np.clip(np.searchsorted(ends, q7), 1, ends.size - 1)
            near = np.minimum(np.abs(q7 - ends[i - 1]), np.abs(q7 - ends[i])) < 1e-9
        else:
            near = np.zeros(DENSE, bool)
        assert np.array_equal(fi.contains(k, q7)[~near], inside[~near, k]), (k, fi[k])


def assert_roots_real(T: np.ndarray, margin: float) -> None:
    """Every root the search finds (its breakpoints) is where a column, evaluated through the numpy closed form,
    changes sign within 1e-9 rad or is within 1e-9 of 0: a joint of a branch crossing a limit, or a branch's
    validity changing; and the search ends."""
    sets = SOLVER._sets
    cols = sets._columns(_levels(*shrunk_limits(PANDA.q_min, PANDA.q_max, margin)))
    found, _, left = sets._isolate(T, cols)
    assert not left.size
    x = np.concatenate([found - 1e-9, found, found + 1e-9])
    R, p = sy.frame_of_batch(np.broadcast_to(T, (x.size, 4, 4)))
    pairs, valid = SOLVER.joint_trig(R, p, x, sy.NUMPY), SOLVER.validity(R, p, x, sy.NUMPY)
    br, slot, trig, joints, _ = cols
    cos_l, sin_l = trig[0::2], trig[1::2]
    f = []
    for k, i in zip(br, slot):  # the validity (slot 0), or sin(q_j − L) of the slot's joint and level
        if i == 0:
            f.append(valid[k])
        else:
            c, s = pairs[k][sets._joints[joints[i - 1]]]
            f.append(s * cos_l[i - 1] - c * sin_l[i - 1])
    f = np.array(f).reshape(br.size, 3, found.size)
    crossing = (f[:, 0] * f[:, 2] <= 0.0) | (np.abs(f[:, 1]) <= 1e-9)
    assert crossing.any(axis=0).all(), found[~crossing.any(axis=0)]


@pytest.mark.parametrize("margin", [0.0, 0.3])
@pytest.mark.parametrize("seed", range(3 if LARGE else 1))
def test_proved_sets_match_dense_sampling_and_their_roots_are_crossings(seed, margin):
    """Random configurations inside the limits: every pose's sets are proved and agree with dense sampling, and
    every root found is a crossing."""
    q = random_q(PANDA, POSES, 100 + seed)
    for T in PANDA.fk(q):
        fi = qpik.feasible_intervals(PANDA, T, margin=margin)
        assert fi.proved
        assert_dense(T, margin, fi)
        assert_roots_real(T, margin)


@pytest.mark.parametrize("joint, value", [(1, 0.0), (3, -0.0698), (4, 0.0), (5, 0.0)])
def test_sets_at_special_configurations(joint, value):
    """Axes 1 and 3 aligned (q2 = 0: q1 free at that q7), q4 at its upper limit, q5 = 0, q6 = 0: proved, and the
    dense check holds (a free joint's jump is inside a breakpoint's window)."""
    q = random_q(PANDA, 4 if LARGE else 1, joint, margin=0.1)
    q[:, joint] = value
    for T in PANDA.fk(q):
        fi = qpik.feasible_intervals(PANDA, T)
        assert fi.proved
        assert_dense(T, 0.0, fi)


@pytest.mark.parametrize("key", ["erd_panda", "pybullet_panda"] if LARGE else ["erd_panda"])
def test_the_columns_are_the_joints_cosines_and_sines_and_file_arms_sets_are_proved(key):
    """On the Panda files (their joints mapped to the table's): joint_trig is (cos q_j, sin q_j) of the IK's joints
    wherever the branch is valid, and its scaled pairs are those times their length (a positive multiple); in the
    large run, the sets of two poses are proved and agree with dense sampling
    (each file arm compiles its own Taylor models)."""
    robot = model_robot(key)
    solver = closed_form_for(robot)
    q = random_q(robot, 200, 4)
    T = robot.fk(q)
    R, p = sy.frame_of_batch(T)
    pairs = solver.joint_trig(R, p, q[:, 6], sy.NUMPY)
    scaled = solver.joint_trig(R, p, q[:, 6], sy.NUMPY, scaled=True)
    sol = solver.solve_batch(T, q[:, 6])
    for k in range(8):
        ok = sol.valid[:, k]
        for j in range(6):
            c, s = (np.broadcast_to(x, ok.shape)[ok] for x in pairs[k][j])
            np.testing.assert_allclose(c, np.cos(sol.q[ok, k, j]), atol=1e-9)
            np.testing.assert_allclose(s, np.sin(sol.q[ok, k, j]), atol=1e-9)
            x, y = (np.broadcast_to(v, ok.shape)[ok] for v in scaled[k][j])
            rho = np.hypot(x, y)
            assert np.all(rho > 1e-9), (k, j)  # random configurations: no joint free
            np.testing.assert_allclose(x, rho * np.cos(sol.q[ok, k, j]), atol=1e-9)
            np.testing.assert_allclose(y, rho * np.sin(sol.q[ok, k, j]), atol=1e-9)
    for pose in T[: 2 if LARGE else 0]:
        fi = qpik.feasible_intervals(robot, pose)
        assert fi.proved
        assert_dense(pose, 0.0, fi, robot)


def test_joint_trig_follows_a_joint_map():
    """A joint map q = s (q_DH − c) (signs and shifts as a file's joints may have): joint_trig is (cos, sin) of the
    joints that branches() returns through it."""
    solver = LockedJointSolver(PANDA)
    rng = np.random.default_rng(2)
    solver.joint_map = SimpleNamespace(sign=rng.choice([-1.0, 1.0], 7), shift=rng.uniform(-np.pi, np.pi, 7))
    q = random_q(PANDA, 200, 6)
    R, p = sy.frame_of_batch(PANDA.fk(q))
    pairs = solver.joint_trig(R, p, q[:, 6], sy.NUMPY)
    br = solver.branches(R, p, q[:, 6], sy.NUMPY)
    for k in range(8):
        for j in range(6):
            np.testing.assert_allclose(pairs[k][j][0], np.cos(br.q[k][j]), atol=1e-9)
            np.testing.assert_allclose(pairs[k][j][1], np.sin(br.q[k][j]), atol=1e-9)


def test_a_search_without_budget_is_not_proved_and_nothing_claims_a_proof(monkeypatch):
    """Three rounds cannot isolate the roots from the first cells: the answer says it is not proved; solve_best then
    certifies nothing. With no round at all, a pose beyond the elbow's reach is proved unreachable (no start cell is
    left), and without the start filters (_reach, _arm_reach) it is not proved, and solve_full does not call it
    "unreachable"."""
    weak = copy.copy(SOLVER._sets)  # the compiled model shared, the budget and the kept answer its own
    weak._rounds, weak._last = 3, None
    T = PANDA.fk(random_q(PANDA, 1, 11))[0]
    fi = weak(T)
    assert not fi.proved
    assert qpik.feasible_intervals(PANDA, T).proved
    monkeypatch.setitem(SOLVER.__dict__, "_sets", weak)
    res = solve_best(PANDA, T)
    assert res.status == "optimal" and not res.certified and res.message == UNPROVED_SETS, res.summary()
    far = np.eye(4)
    far[:3, 3] = (2.0, 0.0, 0.5)
    monkeypatch.setattr(weak, "_rounds", 0)
    assert weak(far).proved and not any(weak(far)[k] for k in range(8))  # every start cell beyond the elbow's reach
    monkeypatch.setattr(weak, "_reach", lambda T, a, b: np.ones(a.size, bool))
    monkeypatch.setattr(weak, "_arm_reach", lambda Tf, a, b: np.ones((a.size, 8), bool))
    weak._last = None
    assert not weak(far).proved
    res = solve_full(PANDA, far, options=FullOptions(max_starts=2))
    assert res.status == "not found"


def test_the_reach_filter_leaves_out_only_cells_where_no_branch_is_valid():
    """The start cells the search leaves out (Q7Intervals._reach, exact for the elbow) hold no q7 where a branch is
    valid, and neither do the branches it leaves out of a start cell (_arm_reach, where an elbow's wrist cannot
    reach), by dense sampling of the numpy validity, at random poses and at poses near the edge of the workspace (the
    elbow stretched, the position scaled by 0.999 or 1.001: the elbow reaches over few cells); and the search with
    and without the filters finds the same breakpoints."""
    sets = SOLVER._sets
    q = random_q(PANDA, 40 if LARGE else 12, 21)
    q[::2, 3] = PANDA.q_max[3]
    T = PANDA.fk(q)
    T[1::4, :3, 3] *= 1.001
    T[3::4, :3, 3] *= 0.999
    edges = np.linspace(-np.pi, np.pi, 65)
    x = edges[:-1, None] + (edges[1] - edges[0]) * np.linspace(0.0, 1.0, 201)
    cols = sets._columns(_levels(PANDA.q_min, PANDA.q_max))
    everywhere = copy.copy(sets)
    everywhere._reach = lambda T, a, b: np.ones(a.size, bool)
    everywhere._arm_reach = lambda Tf, a, b: np.ones((a.size, 8), bool)
    left_out = arm_out = 0
    for pose in T:
        near = sets._reach(pose, edges[:-1], edges[1:])
        R, p = sy.frame_of_batch(np.broadcast_to(pose, (x[~near].size, 4, 4)))
        assert not (np.array(SOLVER.validity(R, p, x[~near].ravel(), sy.NUMPY)) >= 0.0).any()
        left_out += (~near).sum()
        arm = sets._arm_reach(pose.reshape(-1, order="F"), edges[:-1], edges[1:])  # (cells, branches)
        R, p = sy.frame_of_batch(np.broadcast_to(pose, (x.size, 4, 4)))
        valid = np.array(SOLVER.validity(R, p, x.ravel(), sy.NUMPY)).reshape(8, *x.shape)
        assert not (valid[~arm.T] >= 0.0).any()
        arm_out += (~arm & near[:, None]).sum()
        found, _, left = sets._isolate(pose, cols)
        found_all, _, left_all = everywhere._isolate(pose, cols)
        assert np.array_equal(np.sort(found), np.sort(found_all)) and np.array_equal(left, left_all)
    assert left_out > 0 and arm_out > 0
