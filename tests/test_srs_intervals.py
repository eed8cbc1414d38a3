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


# ---- with a margin: the super-level sets of the joint-limit margin ------------------------------------------

MARGIN_SAMPLES = 20_000
ASYMMETRIC = dataclasses.replace(
    ROBOT,
    q_min=np.array([-2.5, -1.9, -2.9, -2.0, -2.2, -2.1, -3.0]),
    q_max=np.array([2.9, 1.4, 2.0, 2.1, 2.9, 1.7, 3.5]),  # joint 7 past π, over a whole turn: q7 + 2π may be inside
)


def joint_limit_margin(robot: qpik.Robot, q: np.ndarray) -> np.ndarray:
    """μ(q) = min_j min(q_j − l_j, u_j − q_j) / ρ_j, ρ_j = (u_j − l_j)/2, of configurations q (..., n)."""
    rho = 0.5 * (robot.q_max - robot.q_min)
    return np.min(np.minimum(q - robot.q_min, robot.q_max - q) / rho, axis=-1)


def check_margin(robot: qpik.Robot, fi, T: np.ndarray, margin: float, psi: np.ndarray) -> None:
    """The sets of T at ``margin`` against the closed form at the arm angles ``psi``: a sample inside a set (off its
    ends) is valid with μ >= margin; a valid sample with μ > margin lies in the set."""
    solver = solver_for(robot)
    Q, valid, _, _ = solver.solve_batch(np.broadcast_to(T, (psi.size, 4, 4)), psi)  # (M, 8, 7), (M, 8)
    mu = joint_limit_margin(robot, Q)  # (M, 8)
    for k in range(8):
        ivs = fi[k]
        assert all(-np.pi <= lo <= hi <= np.pi for lo, hi in ivs)
        assert all(a[1] < b[0] for a, b in itertools.pairwise(ivs))
        ends = np.array([x for iv in ivs for x in iv])
        near = np.abs(psi[:, None] - ends[None, :]).min(axis=1, initial=np.inf) < EDGE
        inside = fi.contains(k, psi) & ~near
        assert np.all(valid[inside, k]) and np.all(mu[inside, k] >= margin - 1e-9), (k, margin, ivs)
        better = valid[:, k] & (mu[:, k] > margin + 1e-6)
        assert np.all(fi.contains(k, psi[better])), (k, margin, ivs)


def poses_for(robot: qpik.Robot, seed: int, n: int) -> np.ndarray:
    """Poses of configurations inside the limits: half uniform, half near a limit (off the limits' middle)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.q_min, robot.q_max, (n, 7))
    edge = rng.uniform(0.0, 0.1, (n // 2, 7))
    q[: n // 2] = np.where(rng.random((n // 2, 7)) < 0.5, robot.q_min + edge, robot.q_max - edge)
    return robot.fk(q)


@pytest.fixture(scope="module")
def without_compiler():
    """PsiIntervals of iiwa14 and of the asymmetric arm, gaps classified in numpy (no C compiler)."""
    from qpik.analytic import intervals
    from qpik.analytic.srs_intervals import PsiIntervals

    real, intervals._library = intervals._library, lambda: None
    try:
        out = [PsiIntervals(solver_for(robot)) for robot in (ROBOT, ASYMMETRIC)]
    finally:
        intervals._library = real
    assert all(x._assemble._native is None for x in out)
    return out


@settings(max_examples=4, deadline=None)
@given(seed=SEEDS)
def test_sets_with_a_margin_match_dense_sampling(seed, without_compiler):
    """Random margins in (0, 0.8) (half of them below 0.05, where joint 7 of the asymmetric arm still spans a whole
    turn), both arms, the default path (C where a compiler works) and the numpy path: each against 20,000 sampled
    ψ, and the same."""
    rng = np.random.default_rng(seed)
    for robot, numpy_path in zip((ROBOT, ASYMMETRIC), without_compiler):
        for T in poses_for(robot, seed, 6):
            margin = float(rng.uniform(0.0, rng.choice([0.05, 0.8])))
            fi = solver_for(robot).feasible_intervals(T, margin)
            psi = rng.uniform(-np.pi, np.pi, MARGIN_SAMPLES)
            check_margin(robot, fi, T, margin, psi)
            other = numpy_path(T, margin)
            for k in range(8):
                assert len(other[k]) == len(fi[k]) and np.allclose(other[k], fi[k], atol=1e-12, rtol=0), k


@settings(max_examples=3, deadline=None)
@given(seed=SEEDS)
def test_sets_shrink_as_the_margin_grows(seed):
    """Monotone: each set at a larger margin lies inside the set at a smaller one; above 1 all are empty."""
    rng = np.random.default_rng(seed)
    for robot in (ROBOT, ASYMMETRIC):
        for T in poses_for(robot, seed, 4):
            margins = np.sort(rng.uniform(0.0, 1.0, 4))
            sets = [qpik.feasible_intervals(robot, T, margin=float(m)) for m in (0.0, *margins)]
            for small, large in itertools.pairwise(sets):
                for k in range(8):
                    for lo, hi in large[k]:
                        assert any(a - 1e-9 <= lo and hi <= b + 1e-9 for a, b in small[k]), (k, large[k], small[k])
            assert all(s == [] for s in qpik.feasible_intervals(robot, T, margin=1.0 + 1e-9).intervals)


def test_a_tiny_margin_gives_the_sets_without_one():
    """margin 1e-12 (the second compiled function, limits as inputs) against margin 0 (the limits as constants)."""
    for T in poses_for(ROBOT, 5, 20):
        exact, tiny = qpik.feasible_intervals(ROBOT, T), qpik.feasible_intervals(ROBOT, T, margin=1e-12)
        for k in range(8):
            assert len(exact[k]) == len(tiny[k]) and np.allclose(exact[k], tiny[k], atol=1e-6, rtol=0), k


def test_the_best_margin_is_where_the_sets_vanish():
    """A configuration q of margin μ(q) lies in its branch's set at every margin below μ(q); the set at μ(q) + 1e-3
    misses ψ(q) (the sets bound the margin from above as well)."""
    for q in random_q(ROBOT, 10, 8, margin=0.1):
        psi, branch = qpik.redundancy_parameter(ROBOT, q)
        mu = float(joint_limit_margin(ROBOT, q))
        T = ROBOT.fk(q)
        assert qpik.feasible_intervals(ROBOT, T, margin=mu - 1e-6).contains(branch, psi)
        assert not qpik.feasible_intervals(ROBOT, T, margin=mu + 1e-3).contains(branch, psi)
