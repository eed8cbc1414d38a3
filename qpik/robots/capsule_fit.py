r"""The smallest capsule containing a set of balls (mesh vertices are balls of radius 0).

A capsule is the set of points within R of a segment [a, b]. It contains a ball
(c, r) iff :math:`\mathrm{dist}(c, [a, b]) + r \le R`, so for a given axis line and
segment the smallest containing radius is :math:`R = \max_i \mathrm{dist}(c_i, [a, b]) + r_i`:
every candidate below is made to contain the balls by construction, and only its
volume :math:`\pi R^2 |b - a| + \tfrac43 \pi R^3` is minimised:

1. the centres are reduced to the vertices of their convex hull (a capsule is convex);
2. starts: :func:`capsule_for_axis` along the three principal directions of the centres and
   :data:`DIRECTIONS` directions spread evenly over a hemisphere (u and −u give the same
   capsule); the volume is not convex in the axis, so one start can sit in a local minimum;
3. refine the segment's end points (6 numbers) of the :data:`REFINED` best starts by
   Nelder–Mead on the volume, and keep the smallest.

This is a multi-start local search, not a proof of global optimality: on nearly round
point clouds, where many axes give almost the same volume, it can end within about 1 % of
the best capsule found by sampling axes (``tests/robots/test_capsule_fit.py``).

Used by :mod:`qpik.robots.loader` to give each link of a loaded model the capsule of its
collision geometry; the result is checked to contain every ball in the tests.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize, minimize_scalar
from scipy.spatial import ConvexHull, QhullError

DIRECTIONS = 48
"""Axis directions (a Fibonacci lattice on the upper hemisphere) tried besides the principal ones."""
REFINED = 3
"""Starting capsules refined by Nelder–Mead."""


def segment_distances(a: np.ndarray, b: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distances (m) of points (N, 3) to the segment [a, b] (3,)."""
    ab = b - a
    L2 = float(ab @ ab)
    t = np.zeros(len(points)) if L2 == 0.0 else np.clip((points - a) @ ab / L2, 0.0, 1.0)
    return np.linalg.norm(points - a - t[:, None] * ab, axis=1)


def containing_radius(a: np.ndarray, b: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> float:
    """The smallest R for which the capsule on [a, b] contains every ball (centres (N, 3), radii (N,))."""
    return float(np.max(segment_distances(a, b, centres) + radii))


def volume(a: np.ndarray, b: np.ndarray, R: float) -> float:
    """Volume (m³) of the capsule on [a, b] with radius R."""
    return float(np.pi * R * R * np.linalg.norm(b - a) + 4.0 / 3.0 * np.pi * R**3)


def fit_capsule(centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The smallest capsule (a (3,), b (3,), R) containing the balls (centres (N, 3), radii (N,)), m.

    See the module docstring; the capsule always contains every ball (R is computed from
    the balls for the end points found).
    """
    centres, radii = _reduce(np.asarray(centres, float), np.asarray(radii, float))
    if len(centres) == 1:
        return centres[0].copy(), centres[0].copy(), float(radii[0])

    def cost(x: np.ndarray) -> float:
        return volume(x[:3], x[3:], containing_radius(x[:3], x[3:], centres, radii))

    scale = max(float(np.ptp(centres, axis=0).max()), 1e-6)
    starts = sorted((np.concatenate(capsule_for_axis(centres, radii, u)[:2]) for u in _axes(centres)), key=cost)
    best = starts[0]
    for x0 in starts[:REFINED]:
        simplex = np.vstack([x0, x0 + 0.05 * scale * np.eye(6)])
        opts = {"initial_simplex": simplex, "xatol": 1e-7, "fatol": 1e-12}
        res = minimize(cost, x0, method="Nelder-Mead", options=opts)
        if res.fun < cost(best):
            best = res.x
    a, b = best[:3], best[3:]
    return a, b, containing_radius(a, b, centres, radii)


def _axes(centres: np.ndarray) -> np.ndarray:
    """Candidate axis directions (unit rows): the principal directions of the centres, then
    :data:`DIRECTIONS` on a Fibonacci lattice of the upper hemisphere."""
    _, _, Vt = np.linalg.svd(centres - centres.mean(axis=0), full_matrices=False)
    k = np.arange(DIRECTIONS) + 0.5
    z = 1.0 - k / DIRECTIONS
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.vstack([Vt, np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)])


def _reduce(centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The balls whose centres are hull vertices, or all of them when the radii differ or the hull is flat."""
    if len(centres) > 8 and np.ptp(radii) == 0.0:
        try:
            idx = ConvexHull(centres).vertices
            return centres[idx], radii[idx]
        except QhullError:  # flat or degenerate: keep them all
            pass
    return centres, radii


def capsule_for_axis(centres: np.ndarray, radii: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The smallest capsule (a, b, R) containing the balls with its axis along the unit vector ``u`` (nearly).

    Across u, the axis passes through the centre of the smallest circle containing the balls'
    projections (Nelder–Mead on the largest radial distance, so to its tolerance); along u,
    the radius R trades against the length: for each R the end points follow exactly (each ball
    must fit in the end caps), and R minimises the volume (bounded scalar search).
    """
    centres, radii = np.asarray(centres, float), np.asarray(radii, float)
    u = np.asarray(u, float) / np.linalg.norm(u)
    e1 = _normal(u)
    e2 = np.cross(u, e1)
    mean = centres.mean(axis=0)
    across = np.stack([(centres - mean) @ e1, (centres - mean) @ e2], axis=1)

    def radial(c: np.ndarray) -> float:
        return float(np.max(np.linalg.norm(across - c, axis=1) + radii))

    c = minimize(radial, np.zeros(2), method="Nelder-Mead", options={"xatol": 1e-9, "fatol": 1e-12}).x
    rho = np.linalg.norm(across - c, axis=1)
    t = (centres - mean) @ u
    R_min = radial(c)

    def ends(R: float) -> tuple[float, float]:
        reach = np.sqrt(np.maximum((R - radii) ** 2 - rho**2, 0.0))
        lo, hi = float(np.min(t + reach)), float(np.max(t - reach))
        return (lo, hi) if lo <= hi else ((lo + hi) / 2, (lo + hi) / 2)

    def vol(R: float) -> float:
        lo, hi = ends(R)
        return np.pi * R * R * (hi - lo) + 4.0 / 3.0 * np.pi * R**3

    span = float(np.ptp(t)) + 2.0 * float(radii.max())
    R = minimize_scalar(vol, bounds=(R_min, R_min + span), method="bounded").x if span > 0 else R_min
    lo, hi = ends(R)
    axis_point = mean + c[0] * e1 + c[1] * e2
    a, b = axis_point + lo * u, axis_point + hi * u
    return a, b, containing_radius(a, b, centres, radii)


def _normal(u: np.ndarray) -> np.ndarray:
    """A unit vector normal to u."""
    v = np.cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    return v / np.linalg.norm(v)
