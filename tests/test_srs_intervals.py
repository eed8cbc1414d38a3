"""Feasible ψ intervals of iiwa14: exact against dense sampling of the closed form, boundaries at limits.

500 random poses (five hypothesis seeds of 100), 10,000 arm angles each,
every pose's samples in one batched ``ik`` call.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from conftest import SEEDS, random_q
from hypothesis import given, settings

import qpik
from qpik.analytic.api import solver_for

ROBOT = qpik.load_robot("iiwa14")
SOLVER = solver_for(ROBOT)
SAMPLES = 10_000
EDGE = 1e-6  # samples this close to a boundary may go either way


def sampled_feasibility(T: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """(branch, M): every branch valid and within limits at each ψ, by the closed form (batched path)."""
    Q, valid, _, _ = SOLVER.solve_batch(np.broadcast_to(T, (len(psi), 4, 4)), psi)
    return (valid & ROBOT.within_limits(Q.reshape(-1, 7)).reshape(valid.shape)).T


def genuine_boundaries(intervals: list[tuple[float, float]]) -> list[float]:
    """Interval ends, without the cut at ±π of a set that runs through ±π."""
    ends = [x for iv in intervals for x in iv]
    if len(intervals) > 1 and intervals[0][0] == -np.pi and intervals[-1][1] == np.pi:
        ends = ends[1:-1]
    return ends


def check_pose(T: np.ndarray, rng: np.random.Generator, intervals=None) -> int:
    """Compare the intervals of pose T with 10,000 sampled ψ; check every boundary; return how many."""
    fi = qpik.feasible_intervals(ROBOT, T) if intervals is None else intervals(T)
    assert fi.param_name == "psi" and np.array_equal(fi.branch, np.arange(8))
    psi = rng.uniform(-np.pi, np.pi, SAMPLES)
    sampled = sampled_feasibility(T, psi)
    bounds, owner = [], []
    for k in range(8):
        ivs = fi[k]
        assert all(-np.pi <= lo <= hi <= np.pi for lo, hi in ivs)
        assert all(a[1] < b[0] for a, b in itertools.pairwise(ivs))  # sorted, disjoint
        ends = np.array([x for iv in ivs for x in iv])
        near = np.abs(psi[:, None] - ends[None, :]).min(axis=1, initial=np.inf) < EDGE
        claimed = fi.contains(k, psi)
        assert np.array_equal(claimed[~near], sampled[k][~near]), f"branch {k}: {ivs}"
        b = genuine_boundaries(ivs)
        bounds += b
        owner += [k] * len(b)
    # every boundary is a joint at a limit, or a singular ψ where a joint jumps
    if bounds:
        bounds, owner = np.array(bounds), np.array(owner)
        Q = qpik.ik(ROBOT, np.broadcast_to(T, (bounds.size, 4, 4)), bounds).q[np.arange(bounds.size), owner]
        at_limit = np.minimum(np.abs(Q - ROBOT.q_min), np.abs(Q - ROBOT.q_max)).min(axis=1) < EDGE
        sing = [np.array(fi.singular[k]) for k in owner]
        at_jump = np.array([np.abs(x - s).min(initial=np.inf) < EDGE for x, s in zip(bounds, sing)])
        assert np.all(at_limit | at_jump), f"boundaries {bounds[~(at_limit | at_jump)]} of branches {owner}"
    return len(bounds)


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_intervals_match_dense_sampling(seed):
    rng = np.random.default_rng(seed)
    poses = ROBOT.fk(random_q(ROBOT, 100, seed))
    checked = sum(check_pose(T, rng) for T in poses)
    assert checked > 0


def test_intervals_exact_without_a_c_compiler(monkeypatch):
    """With no C compiler the gaps are classified in numpy (:class:`qpik.analytic.intervals.Assembler`): same sets."""
    from qpik.analytic import intervals
    from qpik.analytic.srs_intervals import PsiIntervals

    monkeypatch.setattr(intervals, "_library", lambda: None)
    without = PsiIntervals(SOLVER)
    assert without._assemble._native is None
    rng = np.random.default_rng(3)
    assert sum(check_pose(T, rng, without) for T in ROBOT.fk(random_q(ROBOT, 50, 3))) > 0


def test_an_interior_configuration_lies_in_its_branch_interval():
    q = random_q(ROBOT, 200, 21, margin=0.05)
    psi, branch = qpik.redundancy_parameter(ROBOT, q)
    for n in range(len(q)):
        fi = qpik.feasible_intervals(ROBOT, ROBOT.fk(q[n]))
        assert fi.contains(int(branch[n]), psi[n])


@pytest.mark.parametrize("joint", [1, 5])
def test_singular_psi_is_listed_and_intervals_stay_exact(joint):
    """θ2 = 0 (or θ6 = 0) at some ψ: the tan-type joints jump by π there; the jump is listed."""
    q = random_q(ROBOT, 1, 4, margin=0.2)[0]
    q[joint] = 0.0
    T = ROBOT.fk(q)
    psi0, branch = qpik.redundancy_parameter(ROBOT, q)
    fi = qpik.feasible_intervals(ROBOT, T)
    assert np.min(np.abs(np.array(fi.singular[branch]) - psi0)) < 1e-6
    check_pose(T, np.random.default_rng(0))


def test_joint_limits_shape_the_set():
    """Narrow limits on θ4 exclude the branches of the other elbow sign entirely."""
    q = random_q(ROBOT, 1, 9, margin=0.3)[0]
    q[3] = 0.8
    q_min = ROBOT.q_min.copy()
    q_min[3] = 0.0
    robot = dataclasses.replace(ROBOT, q_min=q_min)
    fi = qpik.feasible_intervals(robot, robot.fk(q))
    assert all(fi[k] == [] for k in range(8) if k & 2)
    assert any(fi.measure(k) > 0 for k in range(8) if not k & 2)
