"""Roots of F(δ) = A(cos δ) + sin δ B(cos δ): every sign change of F is found, and every root is one."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.analytic import polyroots
from qpik.analytic.polyroots import trig_roots

P = np.polynomial.polynomial
GRID = np.linspace(-np.pi, np.pi, 100_001)  # spacing 6.3e-5


def _F(a: np.ndarray, b: np.ndarray, d: np.ndarray) -> np.ndarray:
    return P.polyval(np.cos(d), a) + np.sin(d) * P.polyval(np.cos(d), b)


def _circle_distance(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """|x_i − y_j| on the circle, (len(x), len(y))."""
    return np.abs((x[:, None] - y[None, :] + np.pi) % (2 * np.pi) - np.pi)


def _random_rows(seed: int, K: int) -> tuple[np.ndarray, np.ndarray]:
    """K rows of A (degree n) and B (degree n − 1), n in 1..8 per row, some scaled far from 1."""
    rng = np.random.default_rng(seed)
    A, B = np.zeros((K, 9)), np.zeros((K, 9))
    for k in range(K):
        n = rng.integers(1, 9)
        scale = 10.0 ** rng.uniform(-8, 3)
        A[k, : n + 1] = rng.standard_normal(n + 1) * scale
        B[k, :n] = rng.standard_normal(n) * scale
    return A, B


def _check(A: np.ndarray, B: np.ndarray, roots: np.ndarray, owner: np.ndarray) -> None:
    for k, (a, b) in enumerate(zip(A, B)):
        r = roots[owner == k]
        assert np.all(np.abs(r) <= np.pi + 1e-12)
        F = _F(a, b, GRID)
        scale = np.abs(a).sum() + np.abs(b).sum()
        # every root is a root: |F| near rounding level (a near-double root reported at its critical point
        # has |H| <= TOL Σ|h_i|, and Σ|h_i| can be ~2^n times Σ|a_i| + Σ|b_i|)
        assert np.all(np.abs(_F(a, b, r)) <= 1e-8 * scale), f"row {k}: a reported root is not a root"
        # every sign change of F on the grid has a root between its two samples
        change = np.flatnonzero(np.sign(F[1:]) * np.sign(F[:-1]) < 0)
        if change.size:
            mid = 0.5 * (GRID[change] + GRID[change + 1])
            near = _circle_distance(mid, r).min(axis=1, initial=np.inf) if r.size else np.full(mid.size, np.inf)
            assert np.all(near <= 0.6 * (GRID[1] - GRID[0])), f"row {k}: a sign change of F has no root"


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_every_sign_change_is_a_root_and_every_root_is_one(seed):
    A, B = _random_rows(seed, 20)
    _check(A, B, *trig_roots(A, B))


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_without_a_compiler_the_eigenvalue_path_finds_the_same_roots(seed):
    A, B = _random_rows(seed, 10)
    roots, owner = polyroots._eig_roots(A, B)
    _check(A, B, roots, owner)


def test_roots_at_zero_and_pi_and_clustered_near_them():
    """F = sin δ (roots 0 and ±π) and F = sin δ (cos δ − cos ε) (roots 0, ±ε, π): the t = tan(δ/2)
    form keeps them apart, where c = cos δ squeezes δ and −δ together. (For ε below ~1e-4, F is
    below its own rounding error between the roots: no method can separate them.)"""
    roots, _ = trig_roots(np.zeros((1, 2)), np.array([[1.0, 0.0]]))
    assert _circle_distance(np.array([0.0, np.pi]), roots).min(axis=1).max() < 1e-12
    for eps in (1e-1, 1e-2, 1e-3):
        roots, _ = trig_roots(np.zeros((1, 2)), np.array([[-np.cos(eps), 1.0]]))
        want = np.array([0.0, eps, -eps, np.pi])
        assert _circle_distance(want, roots).min(axis=1).max() < 1e-8, (eps, roots)


@settings(max_examples=40, deadline=None)
@given(st.floats(-3.0, 3.0), st.sampled_from([1e-3, 1e-5, 1e-7, 1e-9, 1e-12]), st.floats(0.3, 3.0))
def test_two_nearly_equal_roots_are_not_lost(r, gap, scale):
    """F = sin((δ − r1)/2) sin((δ − r2)/2) = ½ cos(Δ/2) − ½ cos(δ − m), m = (r1 + r2)/2, Δ = r2 − r1:
    roots closer than rounding separates give at least a candidate next to them (within 1e-9 rad on the C path;
    the eigenvalue path without a compiler resolves a double root to about √ε, here 1e-7)."""
    r1, r2 = r, r + gap
    m = 0.5 * (r1 + r2)
    a = scale * np.array([[0.5 * np.cos(0.5 * gap), -0.5 * np.cos(m)]])
    b = scale * np.array([[-0.5 * np.sin(m), 0.0]])
    roots, _ = trig_roots(a, b)
    assert roots.size, "no root reported"
    floor = 1e-9 if polyroots._library() is not None else 1e-7
    assert _circle_distance(np.array([r1, r2]), roots).min(axis=1).max() <= max(gap, floor)


def test_bad_shapes_are_rejected():
    with pytest.raises(ValueError):
        trig_roots(np.zeros((2, 3)), np.zeros((2, 4)))
    with pytest.raises(ValueError):
        trig_roots(np.zeros((1, 40)), np.ones((1, 40)))
