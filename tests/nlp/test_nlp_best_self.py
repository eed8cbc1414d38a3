"""qpik.solve_best with self-collision (``Scene.of(..., self_collision=True)``) against dense sampling, on seeded poses
whose best answer without it brings the arm's own capsules closer than d_s (3 per arm by default, 100 with
``QPIK_TESTS_LARGE=1``).

The reference is independent of the search: every branch's closed form (the batched numpy path,
:meth:`AnalyticSolver.solve_batch`) at :data:`DENSE` values of δ/ψ, kept where inside the limits, clear of the
obstacles (:func:`qpik.geometry.distances`) and with the checked capsule pairs ≥ d_s apart (the numpy kernel,
:func:`qpik.robots.self_pairs.pair_distances`). The answer's self-clearance is measured by MuJoCo on the arm's twin
(:mod:`self_clearance`).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, random_q
from self_clearance import mujoco_self_clearance

import qpik
from qpik.analytic import closed_form_for
from qpik.geometry import Sphere, distances
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
    ok[ok] = pair_distances(robot, q[ok], scene.self_pairs).min(axis=1) >= scene.d_safe
    return q, ok


def _colliding_poses(plain, count, seed, q_ref=False):
    """Seeded poses whose answer of ``plain`` (no self-collision) is optimal with a MuJoCo-measured self-clearance
    below d_s − 1 mm, and those answers: (T, q_ref (or None), plain results)."""
    robot, safe = plain.robot, plain.replace(self_collision=True)
    Q = random_q(robot, (3000 if q_ref else 40) * count, seed)
    if q_ref:  # the reference itself collides: the nearest answer without the constraint is the reference
        Q = Q[pair_distances(robot, Q, safe.self_pairs).min(axis=1) < -0.005]
    T = robot.fk(Q)
    ref = Q if q_ref else None
    res = qpik.solve_best(plain, T, q_ref=ref, options=BestOptions(certify=False))
    ok = np.array([r.status == "optimal" for r in res])
    q = np.array([r.q for r in res])
    hit = np.flatnonzero(ok)[mujoco_self_clearance(safe, q[ok]) < D_SAFE - 1e-3][:count]
    assert len(hit) == count, f"only {len(hit)} colliding answers among {len(T)} poses"
    return T[hit], None if ref is None else ref[hit], q[hit]


@pytest.mark.parametrize("name", ["nammoto7", "iiwa14"])
def test_self_clearance_is_kept_and_the_answer_is_global(name):
    """nammoto7: the margin with a sphere, on poses whose answer without self-collision has its capsules touch; the
    answer with it keeps every checked pair ≥ d_s (MuJoCo) and is at least as good as every dense sample inside the
    limits, clear of the sphere and of itself. iiwa14 (link 1's capsule turns about its own axis, so its distance to
    the hand is set by the pose): the distance to a self-colliding reference configuration; a pose the arm cannot
    reach clear of itself must have no dense sample either."""
    robot = qpik.load_robot(name)
    if name == "nammoto7":
        plain = Scene.of(robot, [Sphere((0.45, -0.45, 0.3), 0.08)], d_safe=D_SAFE, objective="margin")
        T, ref, q_plain = _colliding_poses(plain, POSES, 3)
    else:
        plain = Scene.of(robot, d_safe=D_SAFE, objective="distance")
        T, ref, q_plain = _colliding_poses(plain, POSES, 4, q_ref=True)
    safe = plain.replace(self_collision=True)
    assert safe.self_pairs and (mujoco_self_clearance(safe, q_plain) < D_SAFE - 1e-3).all()
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
        assert mujoco_self_clearance(safe, res.q)[0] >= D_SAFE - TOL, (k, res.summary())
        assert safe.clearance(res.q[None])[0] >= D_SAFE - 1e-9
        f = _margin(robot, q[ok]) if f_of is None else f_of(q[ok], ref[k])[0]
        assert ok.any() and res.objective <= f.min() + 1e-8, (k, res.objective, f.min())
        if res.certified:
            assert res.gap <= 1e-4 * max(1.0, abs(res.objective))
    assert optimal >= (0.8 * POSES if name == "nammoto7" else 0)


@pytest.fixture(scope="module")
def margin_poses():
    """nammoto7's margin without obstacles: the scene, 4 seeded poses whose answer without self-collision
    collides, and those answers."""
    plain = Scene.of(qpik.load_robot("nammoto7"), d_safe=D_SAFE, objective="margin")
    T, _, q_plain = _colliding_poses(plain, 4, 5)
    return plain, T, q_plain


def test_without_the_constraint_the_answers_collide(margin_poses):
    """Without self-collision the answers' capsules come closer than d_s (qpik's kernel agrees with MuJoCo's); with
    it the level-set method (which does not see the constraint) is not used."""
    plain, T, q_plain = margin_poses
    safe = plain.replace(self_collision=True)
    assert (safe.self_clearance(q_plain) < D_SAFE).all()
    np.testing.assert_allclose(safe.self_clearance(q_plain), mujoco_self_clearance(safe, q_plain), atol=1e-6)
    assert {r.method for r in qpik.solve_best(plain, T)} == {"levelset"}
    assert {r.method for r in qpik.solve_best(safe, T)} == {"search"}


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
