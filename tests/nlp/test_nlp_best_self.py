"""qpik.solve_best with self-collision (on by default; ``Scene.of(..., self_collision=False)`` turns it off) against
dense sampling, on seeded poses whose best answer without it brings the arm's own capsules closer than d_s (3 per arm
by default, 100 with ``QPIK_TESTS_LARGE=1``); the two passes (the answer without the capsule pairs kept when it is
clear of them, the pose solved again with them otherwise) on the Panda.

The reference is independent of the search: every branch's closed form (the batched numpy path,
:meth:`AnalyticSolver.solve_batch`) at :data:`DENSE` values of δ/ψ, kept where inside the limits, clear of the
obstacles (:func:`qpik.geometry.distances`) and with the checked capsule pairs ≥ d_s apart (the numpy kernel,
:func:`qpik.robots.self_pairs.pair_distances`). The answer's self-clearance is measured by MuJoCo on the arm's twin
(:mod:`self_clearance`).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import LARGE, random_q
from self_clearance import mujoco_self_clearance

import qpik
from qpik.analytic import closed_form_for
from qpik.geometry import Sphere, distances
from qpik.nlp.best import build_search
from qpik.nlp.options import BestOptions
from qpik.objectives import resolve
from qpik.robots.self_pairs import pair_distances
from qpik.scene import Scene
from qpik.scene.evaluator import Evaluator

POSES = 100 if LARGE else 3
DENSE = 20_000 if LARGE else 4_000
"""δ/ψ samples per branch of the dense reference: a step of 1.6 mrad by default, 0.3 mrad in the large run."""
D_SAFE = 0.02
TOL = 1e-6
"""m: MuJoCo's distance of an answer on the boundary d_s may differ from qpik's kernel by rounding."""


def _margin(robot, q):
    half = 0.5 * (robot.q_max - robot.q_min)
    return -np.minimum((q - robot.q_min) / half, (robot.q_max - q) / half).min(axis=-1)


def _feasible(scene, T, num=DENSE):
    """(q (num·B, n), feasible (num·B,)) of every branch at ``num`` parameters: inside the limits, clear of the
    obstacles and of the arm's own checked capsule pairs."""
    robot = scene.robot
    psi = np.linspace(-np.pi, np.pi, num, endpoint=False)
    sol = closed_form_for(robot).solve_batch(np.broadcast_to(T, (num, 4, 4)), psi)
    q = sol.q.reshape(-1, robot.dof)
    ok = sol.within_limits.ravel().copy()
    if len(scene.obstacles):
        d = distances(robot.capsule_segments(q[ok]), robot.capsule_radii, scene.obstacles.shapes).d
        ok[ok] = d.reshape(ok.sum(), -1).min(axis=1) >= scene.d_safe
    if scene.self_pairs:
        ok[ok] = pair_distances(robot, q[ok], scene.self_pairs).min(axis=1) >= scene.d_safe
    return q, ok


def _colliding_poses(plain, count, seed, q_ref=False):
    """Seeded poses whose answer of ``plain`` (no self-collision) is optimal with a MuJoCo-measured self-clearance
    below d_s − 1 mm, and those answers: (T, q_ref (or None), plain results). With ``q_ref``, the poses of
    configurations whose forearm (the only capsule of a checked pair that moves along the self-motion, on iiwa14)
    comes inside d_s, with a dense sample of their self-motion clear of itself: the reference itself, the nearest
    answer without the constraint, is too close, and a clear optimum exists."""
    robot, safe = plain.robot, plain.replace(self_collision=True)
    if q_ref:  # iiwa14's first pair is link 1's capsule and the forearm's
        Q = random_q(robot, 10_000 * count, seed)
        d = safe.self_distances(Q)[0]
        Q = Q[(d[:, 0] < plain.d_safe - 0.005) & (d[:, 1:] > plain.d_safe).all(axis=1)]
        Q = np.array(list(itertools.islice((q for q in Q if _feasible(safe, robot.fk(q))[1].any()), count)))
    else:
        Q = random_q(robot, 40 * count, seed)
    T = robot.fk(Q)
    ref = Q if q_ref else None
    res = qpik.solve_best(plain, T, q_ref=ref, options=BestOptions(certify=False))
    ok = np.array([r.status == "optimal" for r in res])
    q = np.array([r.q for r in res])
    hit = np.flatnonzero(ok)[mujoco_self_clearance(safe, q[ok]) < plain.d_safe - 1e-3][:count]
    assert len(hit) == count, f"only {len(hit)} colliding answers among {len(T)} poses"
    return T[hit], None if ref is None else ref[hit], q[hit]


@pytest.mark.parametrize("name", ["nammoto7", "iiwa14"])
def test_self_clearance_is_kept_and_the_answer_is_global(name):
    """nammoto7: the margin with a sphere, on poses whose answer without self-collision has its capsules touch; the
    answer with it keeps every checked pair ≥ d_s (MuJoCo) and is at least as good as every dense sample inside the
    limits, clear of the sphere and of itself. iiwa14 (link 1's capsule turns about its own axis, so its distance to
    the wrist and the hand is set by the pose; only the forearm's moves with ψ, and comes within a few cm of it at
    few poses that keep the others clear): the distance to a reference configuration whose forearm is inside
    d_s = 0.15 m, on poses with a clear dense sample. A pose the arm cannot reach clear of itself must have no dense
    sample either."""
    robot = qpik.load_robot(name)
    if name == "nammoto7":
        plain = Scene.of(robot, [Sphere((0.45, -0.45, 0.3), 0.08)], d_safe=D_SAFE, objective="margin",
                         self_collision=False)  # fmt: skip
        T, ref, q_plain = _colliding_poses(plain, POSES, 3)
    else:
        plain = Scene.of(robot, d_safe=0.15, objective="distance", self_collision=False)
        T, ref, q_plain = _colliding_poses(plain, POSES, 4, q_ref=True)
    safe, d_safe = plain.replace(self_collision=True), plain.d_safe
    assert safe.self_pairs and (mujoco_self_clearance(safe, q_plain) < d_safe - 1e-3).all()
    results = qpik.solve_best(safe, T, q_ref=ref)
    f_of = Evaluator(robot, resolve(plain.objective)) if ref is not None else None
    optimal = 0
    for k, res in enumerate(results):
        q, ok = _feasible(safe, T[k])
        if res.status != "optimal":
            assert res.status == "no feasible branch" and not ok.any(), (k, res.summary())
            continue
        optimal += 1
        np.testing.assert_allclose(robot.fk(res.q), T[k], atol=1e-9)
        assert robot.within_limits(res.q)
        assert res.self_collision == "re-solved" and "re-solved" in res.summary()
        assert mujoco_self_clearance(safe, res.q)[0] >= d_safe - TOL, (k, res.summary())
        assert safe.clearance(res.q[None])[0] >= d_safe - 1e-9
        f = _margin(robot, q[ok]) if f_of is None else f_of(q[ok], ref[k])[0]
        assert ok.any() and res.objective <= f.min() + 1e-8, (k, res.objective, f.min())
        if res.certified:
            assert res.gap <= 1e-4 * max(1.0, abs(res.objective))
    assert optimal >= 0.8 * POSES


@pytest.fixture(scope="module")
def margin_poses():
    """nammoto7's margin without obstacles: the scene, 4 seeded poses whose answer without self-collision
    collides, and those answers."""
    plain = Scene.of(qpik.load_robot("nammoto7"), d_safe=D_SAFE, objective="margin", self_collision=False)
    T, _, q_plain = _colliding_poses(plain, 4, 5)
    return plain, T, q_plain


def test_without_the_constraint_the_answers_collide(margin_poses):
    """Without self-collision the answers' capsules come closer than d_s (qpik's kernel agrees with MuJoCo's); with
    it these poses are solved again by the search (the level-set method does not see the constraint)."""
    plain, T, q_plain = margin_poses
    safe = plain.replace(self_collision=True)
    assert (safe.self_clearance(q_plain) < D_SAFE).all()
    np.testing.assert_allclose(safe.self_clearance(q_plain), mujoco_self_clearance(safe, q_plain), atol=1e-6)
    assert {(r.method, r.self_collision) for r in qpik.solve_best(plain, T)} == {("levelset", "off")}
    assert {(r.method, r.self_collision) for r in qpik.solve_best(safe, T)} == {("search", "re-solved")}


def test_ipopt_per_branch_keeps_self_clearance_and_finds_no_better_optimum(margin_poses):
    """``method="ipopt"`` (the clearances as IPOPT's constraints): its answers keep the capsule pairs ≥ d_s apart
    (MuJoCo) and are no better than the certified search's."""
    plain, T, _ = margin_poses
    safe = plain.replace(self_collision=True)
    search = qpik.solve_best(safe, T)
    ipopt = qpik.solve_best(safe, T, options=BestOptions(certify=False, method="ipopt"))
    assert any(b.status == "optimal" for b in ipopt)
    for a, b in zip(search, ipopt):
        if b.status == "optimal":
            assert mujoco_self_clearance(safe, b.q)[0] >= D_SAFE - TOL, b.summary()
            assert a.status == "optimal" and b.objective >= a.objective - 1e-8, (a.summary(), b.summary())


@pytest.mark.parametrize("name", ["nammoto7", "iiwa14"])
def test_the_certificate_models_enclose_the_capsule_pair_distances(name):
    """The certificate's clearances end with the capsule pairs (iiwa14's include its fixed base capsule, a
    constant): at q(t) = Q + t·step every pair distance lies within its model's line ± radius and its bounds."""
    robot = qpik.load_robot(name)
    safe = Scene.of(robot, [Sphere((0.5, 0.2, 0.6), 0.1)], d_safe=D_SAFE, objective="margin", self_collision=True)
    bounds = safe.bounds
    assert bounds.n_clear == bounds.n_pairs + len(safe.self_pairs) and bounds.n_pairs
    Q = random_q(robot, 50, 6)
    step = np.full_like(Q, 1e-2)
    models = bounds.rows(Q, bounds.params, np.zeros_like(Q), safe.obstacles.params, step, np.zeros_like(Q),
                         Q - step, Q + step)  # fmt: skip
    c, s, r, d_lo, d_hi = (m[:, -len(safe.self_pairs) :] for m in models)
    assert np.isfinite(c).all() and np.isfinite(d_lo).all() and (r < 0.05).all()
    for t in np.linspace(-1.0, 1.0, 9):
        d = pair_distances(robot, Q + t * step, safe.self_pairs)
        assert (np.abs(d - (c + s * t)) <= r + 1e-12).all()
        assert (d_lo <= d + 1e-12).all() and (d <= d_hi + 1e-12).all()


@pytest.fixture(scope="module")
def panda():
    """The Panda's margin with self-collision (the default) and three poses of seed 0: the 22nd, whose best margin
    without the capsule pairs brings two of them closer than d_s while others of its self-motion are clear; the 1st,
    which no configuration reaches clear of itself (its hand reaches into the base's capsule); the 2nd, whose answer
    without the pairs is clear of them."""
    robot = qpik.load_robot("panda")
    safe = Scene.of(robot, d_safe=D_SAFE, objective="margin")
    return safe, robot.fk(random_q(robot, 22, 0)[[21, 0, 1]])


def test_panda_pose_whose_best_self_collides_is_solved_again(panda):
    """(a) The answer without the pairs comes closer than d_s (MuJoCo); with them the pose is solved again, the
    answer keeps every checked pair ≥ d_s apart (MuJoCo), is at least as good as every dense sample inside the limits
    and clear of itself, and no better than the answer without the pairs; the table and the summary say so. The
    pose that self-collides at every parameter has no dense sample clear of itself, and no answer."""
    safe, T = panda
    robot, plain = safe.robot, safe.replace(self_collision=False)
    before = qpik.solve_best(plain, T[0])
    assert before.status == "optimal" and mujoco_self_clearance(safe, before.q)[0] < D_SAFE - 1e-3
    res = qpik.solve_best(safe, T[0])
    assert res.status == "optimal" and res.self_collision == "re-solved", res.summary()
    assert "re-solved with the capsule pairs" in res.summary() and "capsule pairs as constraints" in res.table()
    np.testing.assert_allclose(robot.fk(res.q), T[0], atol=1e-9)
    assert robot.within_limits(res.q) and mujoco_self_clearance(safe, res.q)[0] >= D_SAFE - TOL
    q, ok = _feasible(safe, T[0])
    assert ok.any() and res.objective <= _margin(robot, q[ok]).min() + 1e-8
    assert res.objective >= before.objective - 1e-12
    assert not any(b.self_collides for b in res.branches)
    none = qpik.solve_best(safe, T[1])
    assert none.status == "no feasible branch" and none.self_collision == "re-solved", none.summary()
    assert not _feasible(safe, T[1])[1].any()


def test_panda_clear_answer_is_kept_without_a_second_solve(panda):
    """(b) An answer without the pairs that keeps them ≥ d_s apart is the answer: the same q, certificate and method,
    and no evaluation beyond the first pass (the table's counts equal those of the solve without the pairs); the
    table marks exactly the rows whose point comes closer than d_s (qpik's numpy kernel)."""
    safe, T = panda
    plain = safe.replace(self_collision=False)
    off, on = qpik.solve_best(plain, T[2]), qpik.solve_best(safe, T[2])
    assert on.self_collision == "clear" and on.status == "optimal", on.summary()
    np.testing.assert_array_equal(on.q, off.q)
    assert (on.method, on.certified, on.gap) == (off.method, off.certified, off.gap)
    assert [b.evaluations for b in on.branches] == [b.evaluations for b in off.branches]
    assert on.clearance == pytest.approx(mujoco_self_clearance(safe, on.q)[0], abs=TOL)
    for b in on.branches:
        close = b.feasible and pair_distances(safe.robot, b.q, safe.self_pairs).min() < D_SAFE
        assert b.self_collides == close


def test_panda_without_self_collision_keeps_the_unconstrained_answer(panda):
    """(c) ``self_collision=False``: no pair is checked, and the answer is the best margin over the limits alone, as
    good as every dense sample inside them (the ones that self-collide included) and as the search's."""
    safe, T = panda
    robot, plain = safe.robot, safe.replace(self_collision=False)
    assert plain.self_pairs == ()
    res = qpik.solve_best(plain, T[0], options=BestOptions(method="levelset"))  # "auto" searches on the Panda
    assert res.self_collision == "off" and res.method == "levelset"
    q, ok = _feasible(plain, T[0])
    assert res.objective <= _margin(robot, q[ok]).min() + 1e-8
    assert safe.self_clearance(res.q[None])[0] < D_SAFE
    search = qpik.solve_best(plain, T[0], options=BestOptions(method="search"))
    assert search.self_collision == "off" and search.objective == pytest.approx(res.objective, abs=1e-8)


def test_build_search_builds_the_passes_without_and_with_the_pairs():
    """``build_search`` compiles what both passes of the search call (the objective and clearance maps without and
    with the capsule pairs, the pairs' distances), which a first solve whose answer is clear of itself leaves
    unbuilt."""
    robot = qpik.load_robot("panda")
    safe = Scene.of(robot, d_safe=D_SAFE, objective="margin")
    plain = safe.replace(self_collision=False)
    T = robot.fk(robot.q_home)

    def built(scene):
        maps = scene.evaluator._maps
        return maps.rows.built and maps.values.built

    qpik.solve_best(safe, T, options=BestOptions(method="search", certify=False))
    assert built(plain)  # the pairs' pass may be built already by another test of this process
    build_search(robot, T, "margin", d_safe=D_SAFE)
    assert built(plain) and built(safe) and safe.self_distances.built
    res = qpik.solve_best(safe, T, options=BestOptions(method="search", certify=False))
    assert res.status == "optimal" and res.self_collision == "clear", res.summary()
