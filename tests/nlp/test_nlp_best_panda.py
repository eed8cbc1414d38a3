"""qpik.solve_best on the Panda's locked-q7 closed form against dense sampling of q7 (as tests/nlp/test_nlp_best.py
does for the S-R-S and offset-shoulder arms): 10 seeded random reachable poses (100 with QPIK_TESTS_LARGE=1), 20,000
values of q7 each."""

from __future__ import annotations

import numpy as np
from conftest import LARGE, random_q

import qpik
from qpik.analytic import closed_form_for
from qpik.nlp import solve_best

POSES = 100 if LARGE else 10
DENSE = 20_000


def _margin(robot: qpik.Robot, q: np.ndarray) -> np.ndarray:
    """−(joint-limit margin) from its definition, (...) for q (..., n)."""
    half = 0.5 * (robot.q_max - robot.q_min)
    return -np.minimum((q - robot.q_min) / half, (robot.q_max - q) / half).min(axis=-1)


def test_margin_is_certified_where_the_sets_are_proved_and_no_dense_sample_is_better():
    """Every pose's sets are proved here, so every answer is certified; no dense sample beats it."""
    robot = qpik.load_robot("panda")
    solver = closed_form_for(robot)
    T = robot.fk(random_q(robot, POSES, 5))
    results = solve_best(robot, T)
    q7 = np.linspace(-np.pi, np.pi, DENSE, endpoint=False)
    for k in range(POSES):
        res = results[k]
        assert solver.feasible_intervals(T[k]).proved
        assert res.status == "optimal" and res.certified and np.isfinite(res.gap), res.summary()
        assert res.param_name == "q7" and res.param == res.q[6]
        np.testing.assert_allclose(robot.fk(res.q), T[k], atol=1e-10)
        assert robot.within_limits(res.q)
        sol = solver.solve_many(T[k], q7)
        f = np.where(sol.within_limits, _margin(robot, sol.q), np.inf)
        assert np.isfinite(f).any()
        assert res.objective <= f.min() + 1e-8, (k, res.objective, f.min())


def test_auto_searches_the_panda_and_the_level_sets_agree():
    """The Panda's sets are a root isolation, not closed-form roots, so "auto" searches (with its certificate); the
    level sets, asked for, reach the same margin on the same poses (the two methods share no code but the
    objective)."""
    robot = qpik.load_robot("panda")
    T = robot.fk(random_q(robot, 3, 11))
    auto = solve_best(robot, T)
    level = solve_best(robot, T, options=qpik.BestOptions(method="levelset"))
    for a, b in zip(auto, level):
        assert a.method == "search" and b.method == "levelset"
        assert a.certified and b.certified
        assert abs(a.objective - b.objective) <= 1e-4 * max(1.0, abs(b.objective)), (a.summary(), b.summary())
