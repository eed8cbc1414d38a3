"""Capsule–obstacle distances: against scipy minimisation, MuJoCo, finite differences and hand cases.

The reference is independent of the kernels: the signed distance of a *point*
to each shape (textbook formulas below), minimised over the segment parameter
with scipy (it is convex in s for every convex shape).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from qpik.core.errors import InputError
from qpik.geometry import Box, Capsule, HalfSpace, ObstacleSet, Sphere, distance, distances

SEEDS = st.integers(0, 2**32 - 1)


# ---- independent reference -----------------------------------------------------------------


def point_sd(shape, x: np.ndarray) -> np.ndarray:
    """Signed distance of points x (..., 3) to the shape surface (negative inside)."""
    if isinstance(shape, Sphere):
        return np.linalg.norm(x - shape.center, axis=-1) - shape.radius
    if isinstance(shape, Capsule):
        v = shape.p1 - shape.p0
        t = np.clip(((x - shape.p0) @ v) / max(v @ v, 1e-300), 0.0, 1.0)
        return np.linalg.norm(x - shape.p0 - t[..., None] * v, axis=-1) - shape.radius
    if isinstance(shape, Box):
        q = np.abs((x - shape.center) @ shape.rotation) - shape.half_extents
        return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0)
    return x @ shape.normal - shape.offset


def reference_d(a: np.ndarray, b: np.ndarray, r: float, shape) -> float:
    """min over s in [0, 1] of point_sd(a + s (b - a)) - r, by a grid then bounded Brent."""
    f = lambda s: float(point_sd(shape, a + s * (b - a)))  # noqa: E731
    grid = np.linspace(0.0, 1.0, 201)
    vals = point_sd(shape, a + grid[:, None] * (b - a))
    k = int(np.argmin(vals))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, 200)]
    res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
    return min(res.fun, vals.min(), f(lo), f(hi)) - r


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    return Rotation.random(random_state=rng).as_matrix()


def random_case(rng: np.random.Generator, n_seg: int = 10):
    """Segments (n_seg, 2, 3), radii and 2 obstacles of each type, with degenerate segments mixed in."""
    shapes = [
        Sphere(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.2)),
        Sphere(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.2)),
        Capsule(*rng.uniform(-0.3, 0.3, (2, 3)), rng.uniform(0.02, 0.15)),
        Capsule(*rng.uniform(-0.3, 0.3, (2, 3)), rng.uniform(0.02, 0.15)),
        Box(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.3, 3), random_rotation(rng)),
        Box(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.3, 3), random_rotation(rng)),
        HalfSpace(rng.normal(size=3), rng.uniform(-0.3, 0.3)),
        HalfSpace(rng.normal(size=3), rng.uniform(-0.3, 0.3)),
    ]
    a = rng.uniform(-0.5, 0.5, (n_seg, 3))
    u = rng.normal(size=(n_seg, 3)) * rng.uniform(0.0, 0.4, (n_seg, 1))
    u[0] = 0.0  # a sphere
    u[1] = (shapes[2].p1 - shapes[2].p0) * rng.uniform(-1.5, 1.5)  # parallel to a capsule obstacle
    u[2] = shapes[4].rotation[:, 0] * rng.uniform(-0.5, 0.5)  # parallel to box faces
    u[3] = np.cross(shapes[6].normal, rng.normal(size=3))  # parallel to a half-space boundary
    a[4] = shapes[4].center + shapes[4].rotation @ (rng.uniform(-0.9, 0.9, 3) * shapes[4].half_extents)  # in box
    segs = np.stack([a, a + u], axis=1)
    radii = rng.uniform(0.0, 0.08, n_seg)
    radii[5] = 0.0  # a bare segment
    return segs, radii, shapes


def both_paths(segs, radii, shapes):
    """The numpy path (batched input) and the compiled path (packed obstacles)."""
    out_np = distances(np.stack([segs, segs[::-1]]), radii, shapes)
    first = {k: getattr(out_np, k)[0] for k in ("d", "p_link", "p_obs", "normal", "s")}
    return [first, vars(distances(segs, radii, ObstacleSet(shapes)))]


def sd_gradient(shape, x: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    return np.array([(point_sd(shape, x + eps * e) - point_sd(shape, x - eps * e)) / (2 * eps) for e in np.eye(3)])


# ---- property tests ---------------------------------------------------------------------------


@settings(max_examples=15, deadline=None)
@given(SEEDS)
def test_distances_match_scipy_minimisation_and_witnesses_are_consistent(seed):
    rng = np.random.default_rng(seed)
    segs, radii, shapes = random_case(rng)
    for out in both_paths(segs, radii, shapes):
        for c, (a, b) in enumerate(segs):
            for o, shape in enumerate(shapes):
                d, s, n = out["d"][c, o], out["s"][c, o], out["normal"][c, o]
                p_link, p_obs = out["p_link"][c, o], out["p_obs"][c, o]
                assert d == pytest.approx(reference_d(a, b, radii[c], shape), abs=1e-7), (c, o)
                assert 0.0 <= s <= 1.0
                x = a + s * (b - a)
                assert point_sd(shape, x) - radii[c] == pytest.approx(d, abs=1e-9)  # the witness attains d
                assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
                assert np.allclose(p_link, x - radii[c] * n, atol=1e-12)  # on the capsule surface
                assert abs(point_sd(shape, p_obs)) < 1e-9  # on the obstacle surface
                assert np.allclose(p_link - p_obs, d * n, atol=1e-9)
                sd_x = point_sd(shape, x)
                if sd_x > 1e-4:  # outside: n is the gradient of the (C¹) distance field at the axis point
                    assert np.allclose(n, sd_gradient(shape, x), atol=1e-5)


@settings(max_examples=10, deadline=None)
@given(SEEDS)
def test_normal_is_a_subgradient_of_d_under_translation(seed):
    """Every shape is convex, so d(t) (capsule translated by t) is convex and n must satisfy
    d(t + δ) ≥ d(t) + nᵀδ for every δ, not only small ones, and d grows at rate 1 along n. The
    exception is a capsule axis inside a box, where d is the deepest axis point's depth and n its
    nearest face: there d does not decrease along n (rate in [0, 1]; 0 for a segment that crosses a
    slab, whose deepest point slides along it)."""
    rng = np.random.default_rng(seed)
    segs, radii, shapes = random_case(rng)
    base = distances(segs, radii, shapes)
    inside_box = np.array([[isinstance(sh, Box) for sh in shapes]]) & (base.d + radii[:, None] < 0)
    for _ in range(5):
        delta = rng.normal(size=3) * rng.choice([1e-4, 1e-2, 0.2])
        moved = distances(segs + delta, radii, shapes)
        slack = moved.d - base.d - base.normal @ delta
        assert np.all(slack[~inside_box] >= -1e-9)
    eps = 1e-7  # rate of change of d when capsule c alone moves along n[c, o]: batch k moves capsule k
    rate = np.empty_like(base.d)
    for o, shape in enumerate(shapes):
        moves = eps * np.eye(len(segs))[:, :, None, None] * base.normal[None, :, o, None, :]
        rate[:, o] = (np.diagonal(distances(segs + moves, radii, [shape]).d[..., 0]) - base.d[:, o]) / eps
    assert np.allclose(rate[~inside_box], 1.0, atol=1e-5)
    assert np.all(rate[inside_box] >= -1e-6) and np.all(rate[inside_box] <= 1.0 + 1e-6)


@settings(max_examples=10, deadline=None)
@given(SEEDS)
def test_finite_differences_of_d_equal_n_dot_witness_motion(seed):
    """Move the end points by ε(δa, δb): the witness axis point moves by ε((1−s)δa + sδb) and
    d changes by nᵀ of that, to O(ε²) (envelope theorem), wherever d is smooth."""
    rng = np.random.default_rng(seed)
    segs, radii, shapes = random_case(rng)
    out = distances(segs, radii, ObstacleSet(shapes))
    # central differences err by ~eps^2 times the third derivative of d: on a 1 cm segment the witness moves
    # ~100x faster than the end points, and eps = 1e-6 left errors of 3.5e-6 there; 1e-7 leaves ~4e-8
    eps = 1e-7
    da, db = rng.normal(size=(2, len(segs), 3))
    step = np.stack([da, db], axis=1)
    plus = distances(segs + eps * step, radii, shapes).d
    minus = distances(segs - eps * step, radii, shapes).d
    fd = (plus - minus) / (2 * eps)
    motion = (1 - out.s)[..., None] * da[:, None] + out.s[..., None] * db[:, None]
    predicted = np.einsum("coi,coi->co", out.normal, motion)
    checked = 0
    for c, (a, b) in enumerate(segs):
        for o, shape in enumerate(shapes):
            u = b - a
            x = a + out.s[c, o] * u
            if point_sd(shape, x) < 1e-2 or u @ u < 1e-6:  # axis inside/at the obstacle or a point
                continue
            if isinstance(shape, Capsule):
                v = shape.p1 - shape.p0
                if np.linalg.norm(np.cross(u, v)) < 0.1 * np.linalg.norm(u) * np.linalg.norm(v):
                    continue  # near-parallel: the witness is (nearly) not unique
            if isinstance(shape, HalfSpace) and abs(u @ shape.normal) < 1e-2:
                continue  # parallel to the plane: tie between the end points
            if isinstance(shape, Box) and np.min(np.abs(u @ shape.rotation)) < 1e-2 * np.linalg.norm(u):
                continue  # parallel to a face: tie along the face
            assert fd[c, o] == pytest.approx(predicted[c, o], abs=1e-6), (c, o)
            checked += 1
    assert checked > 20


# ---- hand cases ---------------------------------------------------------------------------------


def test_parallel_and_collinear_capsules():
    r, R = 0.1, 0.05
    link = np.array([0.0, 0, 0]), np.array([1.0, 0, 0])
    overlap = distance(*link, r, Capsule([0.5, 0.3, 0], [1.5, 0.3, 0], R))
    assert overlap.d == pytest.approx(0.3 - r - R, abs=1e-12)
    assert np.allclose(overlap.normal, [0, -1, 0]) and 0.5 - 1e-12 <= overlap.s <= 1.0
    for p0, p1 in (([2.0, 0, 0], [3.0, 0, 0]), ([3.0, 0, 0], [2.0, 0, 0])):  # collinear, both orientations
        apart = distance(*link, r, Capsule(p0, p1, R))
        assert apart.d == pytest.approx(1.0 - r - R, abs=1e-12) and apart.s == 1.0
        assert np.allclose(apart.normal, [-1, 0, 0]) and np.allclose(apart.p_obs, [2.0 - R, 0, 0])
    crossing = distance(*link, r, Capsule([0.5, -1, 0], [0.5, 1, 0], R))  # axes meet: n = u × v
    assert crossing.d == pytest.approx(-r - R) and np.allclose(np.abs(crossing.normal), [0, 0, 1])


def test_zero_length_segments_are_spheres():
    rng = np.random.default_rng(1)
    shapes = [
        Sphere([0.1, 0.2, 0.3], 0.1),
        Capsule([0, 0, 0], [0.3, 0.1, 0], 0.05),
        Capsule([0.2, 0.2, 0.2], [0.2, 0.2, 0.2], 0.05),  # zero-length obstacle capsule
        Box([0, 0, 0], [0.1, 0.2, 0.3], random_rotation(rng)),
        HalfSpace([0, 0, 1], 0.1),
    ]
    for _ in range(20):
        a = rng.uniform(-0.4, 0.4, 3)
        for shape in shapes:
            out = distance(a, a, 0.02, shape)
            assert out.d == pytest.approx(point_sd(shape, a) - 0.02, abs=1e-12) and out.s == 0.0
    centre = distance([0.1, 0.2, 0.3], [0.1, 0.2, 0.3], 0.02, shapes[0])  # point at the sphere centre
    assert centre.d == pytest.approx(-0.12) and np.linalg.norm(centre.normal) == pytest.approx(1.0)


def test_box_touching_inside_and_through():
    box = Box([0, 0, 0], [1.0, 1.0, 1.0])
    on_face = distance([-0.5, 0.2, 1.0], [0.5, -0.3, 1.0], 0.0, box)
    assert abs(on_face.d) < 1e-12 and np.allclose(on_face.normal, [0, 0, 1])
    on_edge = distance([-2.0, 1.0, 1.0], [2.0, 1.0, 1.0], 0.0, box)
    assert abs(on_edge.d) < 1e-12
    inside = distance([-0.5, 0, 0.2], [0.5, 0, 0.2], 0.05, box)  # deepest at x = 0: max(-1, -1, -0.8)
    assert inside.d == pytest.approx(-0.85, abs=1e-12)
    assert np.allclose(inside.normal, [0, 0, 1]) and np.allclose(inside.p_obs, [0, 0, 1.0], atol=1e-12)
    assert inside.s == pytest.approx(0.5)
    through = distance([0.1, 0, -3.0], [0.1, 0, 3.0], 0.05, box)  # pierces it: deepest point (0.1, 0, 0)
    assert through.d == pytest.approx(-0.95, abs=1e-12) and through.s == pytest.approx(0.5)
    assert np.allclose(through.normal, [1, 0, 0]) and np.allclose(through.p_obs, [1.0, 0, 0])
    rotated = Box([1.0, 2.0, 3.0], [0.1, 0.2, 0.3], Rotation.from_euler("z", 90, degrees=True).as_matrix())
    beside = distance([1.0, 2.5, 2.0], [1.0, 2.5, 4.0], 0.01, rotated)  # box is 0.2 wide along world y
    assert beside.d == pytest.approx(0.5 - 0.1 - 0.01) and np.allclose(beside.normal, [0, 1, 0])


def test_capsule_below_half_space_is_negative():
    table = HalfSpace([0, 0, 2.0], 1.0)  # the solid 2z <= 1: free side z >= 0.5
    below = distance([0, 0, 0.2], [0.3, 0, 0.6], 0.05, table)
    assert below.d == pytest.approx(0.2 - 0.5 - 0.05) and below.s == 0.0
    assert np.allclose(below.normal, [0, 0, 1]) and np.allclose(below.p_obs, [0, 0, 0.5])
    above = distance([0, 0, 0.9], [0.3, 0, 0.7], 0.05, table)
    assert above.d == pytest.approx(0.7 - 0.5 - 0.05) and above.s == 1.0


def test_agrees_with_mujoco_geom_distance():
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(40):
        link = Capsule(*rng.uniform(-0.5, 0.5, (2, 3)), rng.uniform(0.01, 0.06))
        shapes = [
            Sphere(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.2)),
            Capsule(*rng.uniform(-0.3, 0.3, (2, 3)), rng.uniform(0.02, 0.15)),
            Box(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.3, 3), random_rotation(rng)),
        ]
        xml = "<mujoco><worldbody>" + "".join(s.to_mjcf_geom() for s in [link, *shapes]) + "</worldbody></mujoco>"
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        ours = distances(np.stack([link.p0, link.p1])[None], [link.radius], shapes)
        for o in range(len(shapes)):
            if ours.d[0, o] <= 1e-3:  # compare separated pairs: penetration depth conventions differ
                continue
            fromto = np.zeros(6)
            ref = mujoco.mj_geomDistance(model, data, 0, o + 1, 10.0, fromto)
            assert ours.d[0, o] == pytest.approx(ref, abs=1e-6)
            assert np.allclose(ours.p_link[0, o], fromto[:3], atol=1e-4)
            assert np.allclose(ours.p_obs[0, o], fromto[3:], atol=1e-4)
            checked += 1
    assert checked > 60


# ---- inputs ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("segments", "radii", "match"),
    [
        (np.zeros((3, 3)), np.zeros(3), "segments"),
        (np.zeros((2, 2, 3)), np.zeros(3), "radii"),
        (np.full((2, 2, 3), np.nan), np.zeros(2), "segments"),
        (np.zeros((2, 2, 3)), [0.1, -0.1], "radii"),
        (np.zeros((2, 2, 3)), [0.1, np.inf], "radii"),
    ],
)
def test_bad_inputs_raise(segments, radii, match):
    with pytest.raises(InputError, match=match):
        distances(segments, radii, [Sphere([0, 0, 0], 1.0)])


def test_obstacles_must_be_shapes_and_empty_is_fine():
    with pytest.raises(InputError, match=r"obstacles\[1\]"):
        distances(np.zeros((1, 2, 3)), [0.1], [Sphere([0, 0, 0], 1.0), {"type": "sphere"}])
    empty = distances(np.zeros((3, 2, 3)), np.zeros(3), ObstacleSet([]))
    assert empty.d.shape == (3, 0) and empty.p_link.shape == (3, 0, 3)
