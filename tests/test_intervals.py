"""Interval assembly on the circle: gaps, runs of feasible gaps, sets moved by π — checked point by point."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.analytic.intervals import SAME, FeasibleIntervals, gaps, merge, shift, wrap

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
