"""Interval assembly on the circle: gaps, runs of feasible gaps, sets moved by π — checked point by point."""

from __future__ import annotations

import ctypes
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.analytic import closed_form_for
from qpik.analytic.intervals import SAME, FeasibleIntervals, gaps, merge, shift, shrunk_limits, spaced, wrap

PROBE = np.linspace(-np.pi, np.pi, 20_001)


def _members(ivs, x):
    """x (M,) inside the union of the closed intervals ivs."""
    out = np.zeros(x.shape, bool)
    for lo, hi in ivs:
        out |= (x >= lo) & (x <= hi)
    return out


def _well_formed(ivs):
    assert all(-np.pi <= lo <= hi <= np.pi for lo, hi in ivs)
    assert all(a[1] < b[0] for a, b in itertools.pairwise(ivs)), ivs  # sorted, disjoint, not touching


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.floats(0.0, 1.0))
def test_merge_is_the_union_of_the_feasible_gaps(seed, G, density):
    rng = np.random.default_rng(seed)
    lo, hi = gaps(rng.uniform(-4.0, 4.0, G))  # any branch of 2π
    ok = rng.random((lo.size, 5)) < density
    # which gap each probe point falls in (gap i covers [lo[i], hi[i]), the last one wraps past π)
    x = PROBE[np.abs(wrap(PROBE[:, None] - lo[None, :])).min(axis=1) > 1e-9]  # off the breakpoints
    k = (np.searchsorted(lo, x, side="right") - 1) % lo.size
    for j, ivs in enumerate(merge(lo, hi, ok)):
        _well_formed(ivs)
        np.testing.assert_array_equal(_members(ivs, x), ok[k, j])


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 20), st.floats(0.0, 2 * np.pi, exclude_max=True))
def test_shift_moves_the_set_on_the_circle(seed, G, by):
    rng = np.random.default_rng(seed)
    lo, hi = gaps(rng.uniform(-np.pi, np.pi, G))
    ivs = merge(lo, hi, rng.random((lo.size, 1)) < 0.5)[0]
    moved = shift(ivs, by)
    _well_formed(moved)
    x = PROBE[np.abs(wrap(PROBE[:, None] - np.array([e for iv in moved for e in iv] or [9.0]))).min(axis=1) > 1e-9]
    np.testing.assert_array_equal(_members(moved, x), _members(ivs, wrap(x - by)))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-10.0, 10.0), min_size=1, max_size=50))
def test_gaps_tile_the_circle(breaks):
    lo, hi = gaps(np.array(breaks))
    assert np.all((lo > -np.pi) & (lo <= np.pi))
    assert np.all(np.diff(lo) > SAME)
    np.testing.assert_allclose(hi - lo, np.diff(np.append(lo, lo[0] + 2 * np.pi)))
    assert abs((hi - lo).sum() - 2 * np.pi) < 1e-12
    # every breakpoint is within SAME of one that is kept
    assert np.abs(wrap(wrap(np.array(breaks))[:, None] - lo[None, :])).min(axis=1).max() <= SAME + 1e-15


def test_contains_and_measure():
    fi = FeasibleIntervals("delta", np.array([1, 2]), [[(-1.0, 0.5), (2.0, 3.0)], []])
    assert fi.contains(1, 0.0) and not fi.contains(1, 1.0) and not fi.contains(2, 0.0)
    assert abs(fi.measure(1) - 2.5) < 1e-15


# ---- SetAssembler: both paths (C, numpy) against the IK at each gap's midpoint ----------------------------


def _assemblers():
    """nammoto7's solver and its SetAssembler of rows 1–8 with the sets moved by π: the C path (result lists built by
    the compiled extension, or in Python) and the numpy path."""
    import qpik
    from qpik.analytic import intervals
    from qpik.analytic.api import closed_form_for

    solver = closed_form_for(qpik.load_robot("nammoto7"))
    native = intervals.SetAssembler(solver, rows=8, shift=True)
    real, intervals._library = intervals._library, lambda: None
    try:
        numpy_path = intervals.SetAssembler(solver, rows=8, shift=True)
    finally:
        intervals._library = real
    assert numpy_path._native is None
    real_extension, intervals.extension = intervals.extension, lambda: None
    try:
        python_lists = intervals.SetAssembler(solver, rows=8, shift=True)
    finally:
        intervals.extension = real_extension
    paths = {"numpy": numpy_path}
    if native._native is not None:  # the C path, where a compiler works (QPIK_NATIVE=0: the numpy path only)
        paths["C"] = native
        paths["C, lists built in Python"] = python_lists  # as without the compiled extension (no Python headers)
    return solver, paths


SOLVER, ASSEMBLERS = _assemblers()


@settings(max_examples=80, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.integers(0, 60),
    st.sampled_from(sorted(ASSEMBLERS)),
    st.one_of(st.none(), st.floats(0.0, 1.2)),
)
def test_assembler_sets_are_the_runs_of_feasible_gaps(seed, n, path, margin):
    """Arbitrary breakpoints (any branch of 2π): each row's set holds a probe inside a gap iff the branch is
    feasible at that gap's midpoint (valid, every joint inside the robot's limits or, with ``margin``, the shrunk
    ones); row 8 + k at δ is row k at δ − π; singular values are kept where the branch is valid and singular.
    Calls with and without limits alternate over the examples: each call's limits are its own."""
    rng = np.random.default_rng(seed)
    robot = SOLVER.robot
    T = robot.fk(rng.uniform(robot.q_min, robot.q_max))
    breaks = rng.uniform(-3 * np.pi, 3 * np.pi, n)
    candidates = rng.uniform(-np.pi, np.pi, 3)
    limits = None if margin is None else shrunk_limits(robot.q_min, robot.q_max, margin)
    sets, singular = ASSEMBLERS[path](T, breaks, candidates, limits)
    assert len(sets) == len(singular) == 16
    b = np.sort(np.mod(breaks + np.pi, 2 * np.pi) - np.pi) if n else np.zeros(1)
    ends = np.append(b[1:], b[0] + 2 * np.pi)
    q, valid, _, _ = SOLVER.solve_many(T, 0.5 * (b + ends), rows=8)  # (G, 8, n), (G, 8)
    lo, hi = (robot.q_min, robot.q_max) if limits is None else limits
    feasible = valid & np.all((q >= lo) & (q <= hi), axis=2)
    u = rng.uniform(1e-6, 1 - 1e-6, (b.size, 4))
    probes = wrap((b[:, None] + u * (ends - b)[:, None]).ravel())
    gap = np.repeat(np.arange(b.size), 4)
    moved = np.searchsorted(b, wrap(probes - np.pi), side="right") - 1  # gap of δ − π (−1: the last one)
    for k in range(8):
        _well_formed(sets[k]), _well_formed(sets[k + 8])
        assert np.array_equal(_members(sets[k], probes), feasible[gap, k]), (path, k)
        assert np.array_equal(_members(sets[k + 8], probes), feasible[moved, k]), (path, k + 8)
    _, v, s, _ = SOLVER.solve_many(T, candidates, rows=8)
    for k in range(8):
        expect = np.sort(wrap(candidates[v[:, k] & s[:, k]]))
        assert np.allclose(singular[k], expect, atol=0) and np.allclose(
            singular[k + 8], np.sort(wrap(expect + np.pi)), atol=1e-15
        )


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 2.0))
def test_shrunk_limits_bound_the_joint_limit_margin(seed, margin):
    """q inside the shrunk limits iff its joint-limit margin (:class:`qpik.objectives.JointLimitMargin`'s
    min_j min(q_j − l_j, u_j − q_j) / ρ_j) is at least ``margin``; empty above 1."""
    rng = np.random.default_rng(seed)
    l = rng.uniform(-3.0, 0.0, 7)
    u = l + rng.uniform(0.1, 6.0, 7)
    lo, hi = shrunk_limits(l, u, margin)
    q = rng.uniform(l, u, (2000, 7))
    mu = np.minimum((q - l) / ((u - l) / 2), (u - q) / ((u - l) / 2)).min(axis=1)
    inside = np.all((q >= lo) & (q <= hi), axis=1)
    clear = np.abs(mu - margin) > 1e-12
    assert np.array_equal(inside[clear], mu[clear] >= margin)
    if abs(margin - 1.0) > 1e-9:
        assert np.all(lo <= hi) if margin < 1.0 else np.all(lo > hi)


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7"])
def test_native_sets_with_a_region_are_the_sets_without_it(name):
    """NativeSets through ctypes: at a margin m2, the sets computed with the region of the sets at a smaller margin
    m1 (which hold them) equal the sets computed without a region, on every row; a region that misses the sets
    empties them (the gaps outside it are not evaluated, so the region is the caller's promise)."""
    robot = qpik.load_robot(name)
    sets = closed_form_for(robot).native_sets()
    if sets is None:
        pytest.skip("no native feasible sets here (no compiler)")
    call = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)(sets.function)
    rng = np.random.default_rng(12)

    def run(T, margin, region=None):
        sets.pose[:] = T.T.ravel()
        sets.lo[:], sets.hi[:] = shrunk_limits(robot.q_min, robot.q_max, margin)
        sets.n_region[0] = -1 if region is None else len(region)
        if region is not None and len(region):
            sets.region[: 2 * len(region)] = np.ravel(region)
        assert call(sets.context) >= 0
        sets.n_region[0] = -1
        ends = np.cumsum(np.r_[0, sets.count[:8]])
        return [sets.iv[2 * a : 2 * b].reshape(-1, 2).copy() for a, b in itertools.pairwise(ends)]

    checked = 0
    for T in robot.fk(rng.uniform(robot.q_min, robot.q_max, (60, robot.dof))):
        m1 = rng.uniform(0.0, 0.3)
        m2 = m1 + rng.uniform(0.0, 0.2)
        outer = run(T, m1)
        region = np.concatenate(outer) if any(len(x) for x in outer) else np.zeros((0, 2))
        free, held = run(T, m2), run(T, m2, region)
        for a, b in zip(free, held):
            np.testing.assert_array_equal(a, b)
        checked += sum(len(x) for x in free)
        if len(region):
            assert not any(len(x) for x in run(T, m2, np.zeros((0, 2))))
    assert checked > 50


@settings(max_examples=200, deadline=None)
@given(
    lo=st.floats(-np.pi, np.pi),
    width=st.floats(0.0, 2 * np.pi),
    count=st.integers(1, 4096),
)
def test_spaced_samples_are_the_ends_and_every_multiple_between(lo, width, count):
    """Against the multiples of the spacing counted one by one over the circle."""
    hi, spacing = lo + width, 2 * np.pi / count
    x = spaced(lo, hi, spacing)
    assert x[0] == lo and x[-1] == hi and (np.diff(x) >= 0).all()
    every = np.arange(-count - 1, 2 * count + 2) * spacing
    np.testing.assert_array_equal(x[1:-1], every[(every > lo) & (every < hi)])
