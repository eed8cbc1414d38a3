"""The level-set method of qpik.solve_best (the margin without obstacles) against the search with its Taylor-model
certificate, against dense sampling, and against the super-level sets themselves.

The 500-pose comparison with dense sampling of tests/nlp/test_nlp_best.py runs through this method too (the default
for the margin, then the search for the poses whose answer comes too close to itself). Here the arms' scenes are
without self-collision (:func:`_plain`): the level sets' own problem, the margin over the limits alone."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_q

import qpik
from qpik.analytic import closed_form_for
from qpik.core.errors import InputError
from qpik.geometry import Sphere
from qpik.nlp import levelset, solve_best
from qpik.nlp.options import BestOptions
from qpik.nlp.selfmotion import selfmotion_of
from qpik.objectives import JointLimitMargin
from qpik.scene import Scene

ARMS = ("iiwa14", "nammoto7")


def _margin(robot, q):
    half = 0.5 * (robot.q_max - robot.q_min)
    return np.minimum((q - robot.q_min) / half, (robot.q_max - q) / half).min(axis=-1)


def _plain(robot, objective=None):
    return Scene.of(robot, objective=objective, self_collision=False)


def _poses(robot, n, seed):
    return robot.fk(random_q(robot, n, seed))


@pytest.mark.parametrize("name", ARMS)
def test_levelset_meets_the_search_and_its_certificate(name):
    """On 60 poses the level sets find an answer no worse than the search's (1e-8), never better than the
    search's certified lower bound, and prove it on nearly every pose with the gap ε."""
    robot = qpik.load_robot(name)
    T = _poses(robot, 60, 5)
    fast = solve_best(_plain(robot), T, options=BestOptions(method="levelset"))
    slow = solve_best(_plain(robot), T, options=BestOptions(method="search"))
    for k, (a, b) in enumerate(zip(fast, slow)):
        assert a.status == b.status == "optimal", (k, a.summary(), b.summary())
        assert a.objective <= b.objective + 1e-8, (k, a.objective, b.objective)
        if b.certified:
            assert a.objective >= b.objective - b.gap - 1e-12, k
        assert a.objective == pytest.approx(-_margin(robot, a.q), abs=1e-14)
        np.testing.assert_allclose(robot.fk(a.q), T[k], atol=1e-9)
    certified = fast.certified
    assert certified.mean() >= 0.95
    assert all(r.gap == pytest.approx(levelset.EPS, rel=1e-6) for r in fast if r.certified)


@pytest.mark.parametrize("name", ARMS)
def test_the_answer_tops_its_super_level_set(name):
    """μ* the answer's margin: the feasible sets with the limits shrunk by μ* + 1e-7 are empty on every branch,
    and those shrunk by μ* − 1e-7 hold the answer's δ/ψ on its branch."""
    robot = qpik.load_robot(name)
    solver = closed_form_for(robot)
    T = _poses(robot, 25, 6)
    for k, res in enumerate(solve_best(_plain(robot), T)):
        mu = -res.objective
        above = solver.feasible_intervals(T[k], margin=mu + 1e-7)
        assert not any(above.intervals), (k, mu)
        below = solver.feasible_intervals(T[k], margin=max(mu - 1e-7, 0.0))
        assert below.contains(res.branch, res.param, tol=1e-9), (k, res.branch, res.param)


def test_poses_the_level_sets_leave_go_to_the_search(monkeypatch):
    """With one round only, no pose is proved by the level sets: the search and its certificate answer, as well
    as dense sampling (3,000 values × every branch)."""
    monkeypatch.setattr(levelset, "MAX_ROUNDS", 1)
    robot = qpik.load_robot("nammoto7")
    solver = closed_form_for(robot)
    T = _poses(robot, 12, 7)
    results = solve_best(_plain(robot), T, options=BestOptions(method="levelset"))
    psi = np.linspace(-np.pi, np.pi, 3000, endpoint=False)
    for k, res in enumerate(results):
        sol = solver.solve_batch(np.repeat(T[k : k + 1], len(psi), axis=0), psi)
        mu = np.where(sol.within_limits, _margin(robot, sol.q), -np.inf)
        assert -res.objective >= mu.max() - 1e-8, k
        assert res.certified == (res.gap < np.inf)
    assert results.certified.mean() >= 0.8  # by the Taylor models, as without the level sets


def test_weight_and_methods():
    """A weighted margin has the same maximiser and the weighted value; the level sets refuse what they cannot
    solve; "auto" picks them for the margin alone."""
    robot = qpik.load_robot("iiwa14")
    T = _poses(robot, 1, 8)[0]
    one = solve_best(_plain(robot), T)
    three = solve_best(_plain(robot, 3.0 * JointLimitMargin()), T, options=BestOptions(method="levelset"))
    assert three.objective == pytest.approx(3.0 * one.objective, abs=1e-12)
    np.testing.assert_allclose(three.q, one.q, atol=1e-9)
    assert three.gap == pytest.approx(3.0 * levelset.EPS, rel=1e-6)
    with pytest.raises(InputError, match="method"):
        solve_best(robot, T, obstacles=[Sphere((0.4, 0.3, 0.5), 0.05)], options=BestOptions(method="levelset"))
    with pytest.raises(InputError, match="method"):
        solve_best(robot, T, "smooth-margin", options=BestOptions(method="levelset"))
    with pytest.raises(InputError, match="method"):
        solve_best(robot, T, options=BestOptions(method="bisection"))
    assert one.method == "levelset"
    assert solve_best(robot, T, obstacles=[Sphere((2.0, 2.0, 2.0), 0.05)]).method == "search"


@pytest.mark.parametrize("name", ARMS)
def test_the_c_rounds_give_the_python_rounds_answers(name, monkeypatch):
    """Where the arm's rounds run in C (levelset.c), they give the values, proofs and rounds of the rounds in
    Python, branch by branch (to rounding: the C rounds take their level-0 sets from the shrunk limits' call, and
    compute the margin in C). Where branches or points tie (a margin bound by the elbow, the same on several
    branches), rounding may pick another of them: the answers then differ, but both have the optimal margin."""
    robot = qpik.load_robot(name)
    if levelset._native(selfmotion_of(robot)) is None:
        pytest.skip(f"no C rounds for {name} here (no compiler, or no native feasible sets)")
    T = _poses(robot, 40, 9)
    fast = solve_best(_plain(robot), T)
    monkeypatch.setattr(levelset, "_native", lambda selfmotion: None)
    slow = solve_best(_plain(robot), T)
    np.testing.assert_allclose(fast.objective, slow.objective, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(fast.certified, slow.certified)
    for res in (fast, slow):  # each answer has the optimal margin
        assert robot.within_limits(res.q).all()
        np.testing.assert_allclose(-_margin(robot, res.q), fast.objective, rtol=0, atol=1e-12)
    per_row = [[[b.objective for b in r.branches] for r in res] for res in (fast, slow)]
    np.testing.assert_allclose(*per_row, rtol=0, atol=1e-9)  # other rows: points off by the sets' rounding
    assert (fast.branch != slow.branch).mean() < 0.5  # ties are the exception
    rounds = [[b.rounds for b in r.branches] for r in fast], [[b.rounds for b in r.branches] for r in slow]
    assert rounds[0] == rounds[1]
