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
from qpik.analytic.api import closed_form_for
from qpik.analytic.srs_intervals import PsiIntervals

ROBOT = qpik.load_robot("iiwa14")
SOLVER = closed_form_for(ROBOT)
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
    """With no C compiler the gaps are classified in numpy (:class:`~qpik.analytic.intervals.SetAssembler`)."""
    from qpik.analytic import arm_sets, intervals
    from qpik.analytic.srs_intervals import PsiIntervals

    monkeypatch.setattr(intervals, "_library", lambda: None)
    monkeypatch.setattr(arm_sets, "_psi_library", lambda: None)
    without = PsiIntervals(SOLVER)
    assert without._fixed.native is None and without._assemble._native is None
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
    solver = closed_form_for(robot)
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
    from qpik.analytic import arm_sets, intervals
    from qpik.analytic.srs_intervals import PsiIntervals

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(intervals, "_library", lambda: None)
        mp.setattr(arm_sets, "_psi_library", lambda: None)
        out = [PsiIntervals(closed_form_for(robot)) for robot in (ROBOT, ASYMMETRIC)]
        assert all(x._fixed.native is None and x._shrunk.native is None and x._assemble._native is None for x in out)
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
            fi = closed_form_for(robot).feasible_intervals(T, margin)
            psi = rng.uniform(-np.pi, np.pi, MARGIN_SAMPLES)
            check_margin(robot, fi, T, margin, psi)
            other = numpy_path(T, margin)
            for k in range(8):
                assert len(other[k]) == len(fi[k]) and np.allclose(other[k], fi[k], atol=1e-12, rtol=0), k


@settings(max_examples=3, deadline=None)
@given(seed=SEEDS)
def test_no_set_above_the_elbows_margin(seed, without_compiler):
    """θ4 does not move with ψ: just above the larger of its two elbow signs' margins every set is empty (with no gap
    classified), just below it the sets still match dense sampling (which finds points of the larger margin), on
    both paths."""
    rng = np.random.default_rng(seed)
    for robot, numpy_path in zip((ROBOT, ASYMMETRIC), without_compiler):
        solver = closed_form_for(robot)
        for T in poses_for(robot, seed, 6):
            sol = solver.solve_one(T, 0.0)
            if not sol.valid.any():
                continue
            half = 0.5 * (robot.q_max[3] - robot.q_min[3])
            q4 = sol.q[sol.valid, 3]
            elbow = float(np.max(np.minimum(q4 - robot.q_min[3], robot.q_max[3] - q4) / half))
            if not 1e-3 < elbow < 0.999:
                continue
            above = elbow + 1e-9
            for sets in (solver.feasible_intervals(T, above), numpy_path(T, above)):
                assert all(len(s) == 0 for s in sets.intervals)
            below = elbow - 1e-3
            fi = solver.feasible_intervals(T, below)
            check_margin(robot, fi, T, below, rng.uniform(-np.pi, np.pi, MARGIN_SAMPLES))
            other = numpy_path(T, below)
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


# ---- the one C call (qpik_psi_sets) and its NativeSets ------------------------------------------------------------


def singular_poses(robot: qpik.Robot, seed: int, n: int) -> np.ndarray:
    """Poses with θ2 or θ6 = 0 (a shoulder or wrist singular ψ, a breakpoint of its own), inside the limits."""
    q = random_q(robot, n, seed, margin=0.2)
    q[np.arange(n), np.where(np.arange(n) % 2, 1, 5)] = 0.0
    return robot.fk(q)


def unreachable(T: np.ndarray) -> np.ndarray:
    """T moved 10 m away from the base: out of every arm's reach."""
    out = T.copy()
    out[:3, 3] += 10.0
    return out


def same_sets(a, b) -> None:
    """Two FeasibleIntervals with the same branches, pieces (to 1e-12 rad) and singular values (exactly)."""
    assert np.array_equal(a.branch, b.branch) and a.singular == b.singular
    for k, (x, y) in enumerate(zip(a.intervals, b.intervals)):
        assert len(x) == len(y) and np.allclose(x, y, atol=1e-12, rtol=0), (k, x, y)


def test_one_c_call_agrees_with_the_numpy_path(without_compiler):
    """qpik_psi_sets against the breakpoint function and the numpy SetAssembler: both arms, 150 poses each (uniform,
    near a limit, singular, unreachable), margin 0 and a random margin in (0, 1.1) (above 1 every set is empty)."""
    rng = np.random.default_rng(11)
    for robot, numpy_path in zip((ROBOT, ASYMMETRIC), without_compiler):
        c_path = PsiIntervals(closed_form_for(robot))
        if c_path._fixed.native is None:
            pytest.skip("no C compiler: the numpy path only (test_intervals_exact_without_a_c_compiler)")
        poses = np.concatenate([poses_for(robot, 12, 120), singular_poses(robot, 13, 20)])
        poses = np.concatenate([poses, [unreachable(T) for T in poses[:10]]])
        for T in poses:
            for margin in (0.0, float(rng.uniform(0.0, 1.1))):
                same_sets(c_path(T, margin), numpy_path(T, margin))


def native_lists(sets, rows: int) -> list[list[tuple[float, float]]]:
    """Rows 0..rows-1 of a NativeSets' output: count[r] pieces each, one row after the other in iv."""
    bounds = np.concatenate([[0], np.cumsum(sets.count[:rows])])
    pieces = sets.iv[: 2 * bounds[-1]].reshape(-1, 2)
    return [[tuple(x) for x in pieces[a:b].tolist()] for a, b in itertools.pairwise(bounds)]


@pytest.mark.parametrize("robot", [ROBOT, ASYMMETRIC], ids=["iiwa14", "asymmetric"])
def test_native_sets_called_through_ctypes(robot, without_compiler):
    """SRSSolver.native_sets() called as C code calls it: the pose (column-major) and shrunk limits written into its
    buffers give the sets of feasible_intervals(T, margin) and of the numpy path; an unreachable pose gives none."""
    import ctypes

    from qpik.analytic.intervals import shrunk_limits

    solver = closed_form_for(robot)
    sets = solver.native_sets()
    if sets is None:
        pytest.skip("no C compiler")
    call = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)(sets.function)
    numpy_path = without_compiler[0 if robot is ROBOT else 1]
    rng = np.random.default_rng(17)
    for T in np.concatenate([poses_for(robot, 18, 20), singular_poses(robot, 19, 4)]):
        for margin in (0.0, float(rng.uniform(0.0, 0.8))):
            sets.pose[:] = T.reshape(-1, order="F")
            sets.lo[:], sets.hi[:] = shrunk_limits(robot.q_min, robot.q_max, margin)
            m = call(sets.context)
            assert m == sets.count[:8].sum()
            got = native_lists(sets, 8)
            assert got == solver.feasible_intervals(T, margin).intervals
            expected = numpy_path(T, margin)
            for k in range(8):
                assert len(got[k]) == len(expected[k]) and np.allclose(got[k], expected[k], atol=1e-12, rtol=0), k
        sets.pose[:] = unreachable(T).reshape(-1, order="F")
        assert call(sets.context) == 0 and not sets.count[:8].any()
        assert solver.feasible_intervals(unreachable(T), margin).intervals == [[]] * 8
