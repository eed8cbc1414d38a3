"""qpik.checks.crosscheck: solve_best, the full-joint NLP and the QP controller agree on seeded random poses.

(a) is checked against dense sampling in tests/nlp/test_nlp_best.py; here (b) and (c) must confirm it
(same q to 1e-6 rad, same objective to 1e-8, KKT residual ≤ 1e-8, QP velocity ≤ 1e-6 rad/s), with
and without obstacles, and a deliberately wrong (a) must be caught.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_q

import qpik
from qpik.checks.crosscheck import crosscheck
from qpik.core.errors import InputError
from qpik.geometry import Sphere
from qpik.nlp.best_result import BestResult
from qpik.nlp.options import BestOptions

OBSTACLES = [Sphere((0.35, 0.25, 0.6), 0.1), Sphere((0.3, -0.35, 0.45), 0.1)]


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7"])
@pytest.mark.parametrize("objective, obstacles", [("smooth-margin", ()), ("distance", ()), ("smooth-margin", OBSTACLES),
                                                  ("manipulability", OBSTACLES)])  # fmt: skip
def test_three_way_agreement(name, objective, obstacles):
    robot = qpik.load_robot(name)
    T = robot.fk(random_q(robot, 25, 31))
    checks = [crosscheck(robot, pose, objective, obstacles, q_ref=robot.q_home) for pose in T]
    applicable = [c for c in checks if c.applicable]
    assert len(applicable) >= 20
    for c in applicable:
        assert c.passed, c.report()
        assert c.q_gap <= 1e-6 and c.f_gap <= 1e-8 and c.kkt <= 1e-8 and c.speed <= 1e-6


@pytest.mark.parametrize("key", ["erd_baxter", "erd_tiago_pro"])
def test_three_way_agreement_on_an_arm_whose_slots_are_found_per_pose(key):
    """Baxter's right arm (example-robot-data; its slots found by the 1-D search) and the TIAGo Pro's left arm (the
    general 6-R), solve_best sampled and polished: (b) and (c) confirm (a) on two seeded poses, the second with a
    sphere beside the arm."""
    from conftest import model_robot

    robot = model_robot(key)
    T = robot.fk(random_q(robot, 4, 32)[[0, 2]])
    for k, pose in enumerate(T):
        obstacles = [Sphere(pose[:3, 3] + (0.0, 0.0, 0.25), 0.08)] if k >= 1 else []
        c = crosscheck(robot, pose, "smooth-margin", obstacles)
        assert c.applicable and c.passed, c.report()
        assert "not certified (sampled" in c.report() and c.q_gap <= 1e-6 and c.speed <= 1e-6


def test_three_way_agreement_with_self_collision_active():
    """nammoto7, the smooth margin with self-collision (the default), on seeded poses whose answer without it brings
    the arm's capsules closer than d_s: (b)'s NLP and (c)'s self-collision dampers confirm (a), with the capsule-pair
    constraint active (at d_s) on some of them."""
    robot = qpik.load_robot("nammoto7")
    plain = qpik.Scene.of(robot, d_safe=0.02, objective="smooth-margin", self_collision=False)
    safe = plain.replace(self_collision=True)
    T = robot.fk(random_q(robot, 60, 3))
    res = qpik.solve_best(plain, T, options=BestOptions(certify=False))
    q = np.array([r.q for r in res])
    ok = np.array([r.status == "optimal" for r in res])
    hit = np.flatnonzero(ok & (safe.self_clearance(q) < 0.019))[:3]
    assert len(hit) == 3
    checks = [crosscheck(safe, pose) for pose in T[hit]]
    for c in checks:
        assert c.applicable and c.passed, c.report()
        assert safe.self_clearance(c.best.q[None])[0] >= 0.02 - 1e-9
    active = [abs(safe.self_clearance(c.best.q[None])[0] - 0.02) < 1e-7 for c in checks]
    assert any(active)


def test_a_wrong_answer_is_reported(monkeypatch):
    """(a) moved off its optimum along the self-motion: (b) and (c) disagree, and the report says so."""
    import qpik.checks.crosscheck as cc

    robot = qpik.load_robot("iiwa14")
    pose = robot.fk(random_q(robot, 1, 32)[0])
    honest = cc.solve_best

    def off(*args, **kwargs):
        best = honest(*args, **kwargs)
        q = qpik.ik(robot, pose, best.param + 0.05).q[list(qpik.ik(robot, pose, 0.0).branch).index(best.branch)]
        return BestResult(best.status, best.branch, best.param + 0.05, q, best.objective, param_name=best.param_name)

    monkeypatch.setattr(cc, "solve_best", off)
    check = crosscheck(robot, pose, "smooth-margin")
    assert not check.passed and check.failures
    assert "DISAGREE" in check.report()


def test_random_starts_rate_and_bad_input():
    robot = qpik.load_robot("iiwa14")
    pose = robot.fk(random_q(robot, 1, 33)[0])
    check = crosscheck(robot, pose, "smooth-margin", random_starts=4)
    assert check.random_starts == 4 and 0.0 <= check.random_rate <= 1.0
    assert "random starts" in check.report()
    with pytest.raises(InputError, match="smooth"):
        crosscheck(robot, pose, "margin")
    unreachable = np.eye(4)
    unreachable[:3, 3] = (3.0, 0.0, 0.0)
    assert not crosscheck(robot, unreachable).applicable
