"""Scene: one value for the arm, obstacles, clearance, objective and q_ref, checked once."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import fd, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.core.errors import InputError
from qpik.geometry import Box, HalfSpace, ObstacleSet, Sphere, distances
from qpik.objectives import JointLimitMargin, ReferenceDistance
from qpik.robots.self_pairs import checked_pairs, pair_distances
from qpik.scene import Scene

IIWA = qpik.load_robot("iiwa14")
SHAPES = [Sphere((0.5, 0.2, 0.6), 0.1), Box((0.4, -0.3, 0.3), (0.1, 0.2, 0.05)), HalfSpace((0, 0, 1), -0.2)]


def test_the_pieces_are_checked_and_packed_once():
    scene = Scene.of(IIWA, SHAPES, d_safe=0.03, objective="smooth-margin", q_ref=IIWA.q_home)
    assert isinstance(scene.obstacles, ObstacleSet) and scene.obstacles.shapes == tuple(SHAPES)
    assert scene.d_safe == 0.03 and scene.objective.key() == JointLimitMargin(smooth=True).key()
    assert not scene.q_ref.flags.writeable and scene.evaluator is scene.evaluator
    again = scene.replace(d_safe=0.05)
    assert again.d_safe == 0.05 and again.obstacles is scene.obstacles and again.objective is scene.objective
    assert np.array_equal(Scene.of(IIWA).reference, IIWA.q_home)


@pytest.mark.parametrize(
    "kwargs, named",
    [
        ({"d_safe": -0.01}, "d_safe"),
        ({"d_safe": float("nan")}, "d_safe"),
        ({"objective": "nope"}, "objective"),
        ({"q_ref": np.zeros(6)}, "q_ref"),
        ({"q_ref": np.full(7, np.nan)}, "q_ref"),
        ({"obstacles": [1]}, "obstacles"),
    ],
)
def test_a_bad_piece_is_named(kwargs, named):
    with pytest.raises(InputError, match=named):
        Scene.of(IIWA, **kwargs)
    with pytest.raises(InputError, match="robot"):
        Scene.of("iiwa14")


@settings(max_examples=25, deadline=None, database=None)
@given(seed=st.integers(0, 2**16))
def test_the_clearance_is_the_smallest_pair_distance_of_the_moving_capsules(seed):
    """Against the distance kernels on every (moving capsule, obstacle) pair, computed here from the capsules."""
    q = np.random.default_rng(seed).uniform(IIWA.q_min, IIWA.q_max, (4, 7))
    scene = Scene.of(IIWA, SHAPES)
    moving = ~IIWA.fixed_capsules
    want = [distances(IIWA.capsule_segments(x)[moving], IIWA.capsule_radii[moving], SHAPES).d.min() for x in q]
    assert np.allclose(scene.clearance(q), want, atol=1e-12)
    assert scene.pairs == np.count_nonzero(moving) * len(SHAPES)


def test_the_evaluator_is_the_objective_of_the_scene():
    """The compiled objective of the scene against the objective written out in numpy (ReferenceDistance)."""
    q_ref = IIWA.q_home + 0.1
    scene = Scene.of(IIWA, objective=ReferenceDistance(), q_ref=q_ref)
    q = np.random.default_rng(3).uniform(IIWA.q_min, IIWA.q_max, (5, 7))
    f, grad, _, _ = scene.evaluator(q, q_ref)
    assert np.allclose(f, 0.5 * ((q - q_ref) ** 2).sum(axis=1), atol=1e-12)
    assert np.allclose(grad, q - q_ref, atol=1e-12)


def test_the_solvers_take_the_scene_or_its_pieces_never_both():
    """solve_best and plan_self_motion give the same answers from a Scene as from the same pieces as arguments;
    a piece given both ways is named."""
    scene = Scene.of(IIWA, SHAPES[:1], d_safe=0.03, objective="smooth-margin")
    pose = IIWA.fk(IIWA.q_home + 0.2)
    a = qpik.solve_best(scene, pose)
    b = qpik.solve_best(IIWA, pose, "smooth-margin", SHAPES[:1], d_safe=0.03)
    assert a.status == b.status and np.allclose(a.q, b.q, atol=1e-12) and a.objective == b.objective
    path = IIWA.fk(IIWA.q_home + np.linspace(0.0, 0.3, 6)[:, None] * np.eye(7)[1])
    p, r = (
        qpik.plan_self_motion(scene, path, options=qpik.PlanOptions(mujoco=False)),
        qpik.plan_self_motion(
            IIWA, path, "smooth-margin", SHAPES[:1], d_safe=0.03, options=qpik.PlanOptions(mujoco=False)
        ),
    )
    assert p.status == r.status and np.allclose(p.q, r.q, atol=1e-12)
    for name, value in (("objective", "margin"), ("obstacles", []), ("d_safe", 0.05)):
        with pytest.raises(InputError, match=f"{name}: a Scene carries its own"):
            qpik.solve_best(scene, pose, **{name: value})


def test_self_collision_is_on_by_default_and_names_its_pairs():
    nammoto = qpik.load_robot("nammoto7")
    assert Scene.of(nammoto).self_pairs == checked_pairs(nammoto) and Scene.of(nammoto).self_pairs
    assert Scene.of(nammoto, self_collision=False).self_pairs == ()
    scene = Scene.of(nammoto, self_collision=True)
    assert scene.self_pairs == checked_pairs(nammoto) and scene.self_pairs
    assert scene.replace(d_safe=0.05).self_pairs == scene.self_pairs
    assert scene.replace(self_collision=False).self_pairs == ()
    assert Scene.of(nammoto, self_collision=[(5, 0), (0, 4)]).self_pairs == ((0, 4), (0, 5))
    for bad in ([(0, 1)], [(0, 9)], "pairs", [1, 2]):  # adjacent links, no such capsule, not pairs
        with pytest.raises(InputError, match="self_collision"):
            Scene.of(nammoto, self_collision=bad)


def test_the_default_pairs_leave_out_those_never_d_safe_apart():
    """With d_s = 0.4 m nammoto7's pairs whose distance never reaches it (seeded configurations, numpy's kernel) are
    left out and the others kept; at d_s = 0 none is; at d_s = 1 m every one is."""
    nammoto = qpik.load_robot("nammoto7")
    pairs = checked_pairs(nammoto)
    widest = pair_distances(nammoto, random_q(nammoto, 5000, 9), pairs).max(axis=0)
    assert widest.min() < 0.4 < widest.max()
    assert Scene.of(nammoto, d_safe=0.4).self_pairs == tuple(p for p, w in zip(pairs, widest) if w >= 0.4)
    assert Scene.of(nammoto, d_safe=0.0).self_pairs == pairs and Scene.of(nammoto, d_safe=1.0).self_pairs == ()


def test_the_evaluator_appends_the_capsule_pairs_with_their_exact_gradient():
    """The evaluator's clearances are the capsule–obstacle distances, then the scene's capsule pairs (the numpy
    kernel's values), and ∇ min d is their derivative (central differences) where a capsule pair is the nearest."""
    nammoto = qpik.load_robot("nammoto7")
    scene = Scene.of(nammoto, [Sphere((1.5, 0.0, 0.5), 0.1)], objective="margin", self_collision=True)
    q = random_q(nammoto, 400, 8)
    _, _, d, grad = scene.evaluator(q)
    n_obs = len(d[0]) - len(scene.self_pairs)
    np.testing.assert_allclose(d[:, n_obs:], pair_distances(nammoto, q, scene.self_pairs), atol=1e-12)
    np.testing.assert_allclose(d[:, :n_obs].min(axis=1), scene.clearance(q), atol=1e-12)
    np.testing.assert_allclose(d[:, n_obs:].min(axis=1), scene.self_clearance(q), atol=1e-12)
    np.testing.assert_allclose(scene.self_distances(q)[0], pair_distances(nammoto, q, scene.self_pairs), atol=1e-12)
    assert scene.replace(self_collision=False).self_clearance(q).min() == np.inf
    gaps = np.sort(d, axis=1)
    clear = np.flatnonzero((d.argmin(axis=1) >= n_obs) & (gaps[:, 1] - gaps[:, 0] > 1e-3) & (d.min(axis=1) > 1e-3))
    assert len(clear) >= 20
    for k in clear[:20]:
        want = fd(lambda x: pair_distances(nammoto, x, scene.self_pairs).min(axis=1), q[k][None])[0]
        np.testing.assert_allclose(grad[k], want, atol=1e-6)
