"""The smallest capsule around balls: containment, exact primitives, and the volume against many axis directions."""

from __future__ import annotations

import numpy as np
from conftest import SEEDS
from hypothesis import given, settings

from qpik.robots.capsule_fit import capsule_for_axis, containing_radius, fit_capsule, volume


def test_a_capsule_and_a_sphere_are_their_own_smallest_capsules():
    a, b, R = fit_capsule(np.array([[0.1, 0.2, 0.0], [0.1, 0.2, 0.3]]), np.array([0.05, 0.05]))
    assert np.float64(R) == R and abs(R - 0.05) < 1e-5
    assert abs(np.linalg.norm(b - a) - 0.3) < 1e-5
    a, b, R = fit_capsule(np.array([[0.3, -0.1, 0.2]]), np.array([0.07]))
    np.testing.assert_array_equal(a, b)
    assert R == 0.07


@settings(max_examples=3, deadline=None)
@given(seed=SEEDS)
def test_fit_contains_the_balls_and_beats_every_sampled_axis(seed):
    """Random boxes of points with a few balls: the fit contains them all, and no capsule along any of
    100 random axis directions (each the best for its direction) is smaller by more than 1 % (the fit is
    a multi-start local search; nearly round clouds have many axes of almost the same volume)."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1, 1, (300, 3)) * rng.uniform(0.02, 0.3, 3) @ np.linalg.qr(rng.normal(size=(3, 3)))[0]
    radii = np.zeros(len(pts))
    radii[:5] = rng.uniform(0.0, 0.03, 5)
    a, b, R = fit_capsule(pts, radii)
    assert containing_radius(a, b, pts, radii) <= R + 1e-12
    best = min(volume(*capsule_for_axis(pts, radii, u)) for u in rng.normal(size=(100, 3)))
    assert volume(a, b, R) <= best * 1.01
