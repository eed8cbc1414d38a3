"""qpik.objectives: values against independent formulas, gradients by finite differences, bounds by sampling.

The margin is checked against its definition in numpy, the manipulability against
``Robot.manipulability`` (QR of J), the clearance against :func:`qpik.geometry.distances` (the
numpy path); gradients (including the capsule–obstacle distances' closest-point form) against
central differences at configurations clear of the obstacles; the Taylor models of the
certificate (:class:`qpik.scene.bounds.BoundFunction`) and its lower bound against the values of many
configurations drawn along the modelled range.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS, fd, random_q
from hypothesis import given, settings

import qpik
from qpik.algebra.enclosure import taylor_function
from qpik.core.errors import InputError
from qpik.geometry import Box as BoxShape
from qpik.geometry import Sphere, distances
from qpik.geometry.distance import ObstacleSet
from qpik.nlp.certificate import lower_bound
from qpik.objectives import (
    NAMES,
    Clearance,
    Expression,
    JointLimitMargin,
    Manipulability,
    ReferenceDistance,
    Sum,
    resolve,
)
from qpik.scene.bounds import bound_function
from qpik.scene.evaluator import Evaluator

OBSTACLES = [Sphere((0.45, 0.25, 0.65), 0.1), BoxShape((0.5, -0.35, 0.3), (0.1, 0.12, 0.08))]


def _normalised(robot, q):
    half = 0.5 * (robot.q_max - robot.q_min)
    return np.concatenate([(q - robot.q_min) / half, (robot.q_max - q) / half], axis=-1)


def _clearances(robot, q, obstacles):
    """(N, C'·O) distances of the capsules a joint moves (the fixed ones are tested in test_robot.py), m."""
    moving = ~robot.fixed_capsules
    return distances(robot.capsule_segments(q)[:, moving], robot.capsule_radii[moving], obstacles).d.reshape(len(q), -1)


@pytest.mark.parametrize("name", ["iiwa14", "panda"])
def test_values_equal_their_definitions(name):
    """Every named objective on iiwa14; the margin and the clearance on panda (modified DH, its own limits);
    the values alone (Evaluator.value_rows) equal the values beside the gradients."""
    robot = qpik.load_robot(name)
    q = random_q(robot, 200, 1)
    ref = robot.q_home
    g = _normalised(robot, q)
    d = _clearances(robot, q, OBSTACLES)
    beta = 20.0
    expected = {
        "margin": -g.min(axis=1),
        "smooth-margin": np.log(np.exp(-beta * g).sum(axis=1)) / beta,
        "manipulability": -np.log(robot.manipulability(q)),
        "clearance": -np.minimum(d.min(axis=1), 0.1),
        "smooth-clearance": np.log(np.exp(-100.0 * np.c_[d, np.full(len(d), 0.1)]).sum(axis=1)) / 100.0,
        "distance": 0.5 * ((q - ref) ** 2).sum(axis=1),
    }
    for key in NAMES if name == "iiwa14" else ("margin", "clearance"):
        ev = Evaluator(robot, resolve(key), OBSTACLES)
        f, _, dist, _ = ev(q, ref)
        np.testing.assert_allclose(f, expected[key], rtol=1e-10, atol=1e-12, err_msg=key)
        np.testing.assert_allclose(dist, d, atol=1e-12)
        value, value_dist = ev.value_rows(q, np.broadcast_to(ref, q.shape))  # the same numbers, without ∇f
        np.testing.assert_array_equal(value, f, err_msg=key)
        np.testing.assert_array_equal(value_dist, dist, err_msg=key)


@settings(max_examples=4, deadline=None)
@given(seed=SEEDS)
def test_gradients_match_finite_differences(seed):
    robot = qpik.load_robot("iiwa14")
    q = random_q(robot, 60, seed, margin=0.05)
    objective = (
        Manipulability()
        + 3.0 * Clearance(smooth=True, cap=0.3)
        + 0.5 * ReferenceDistance()
        + JointLimitMargin(smooth=True)
    )
    ev = Evaluator(robot, objective, OBSTACLES)
    _, grad, d, grad_d = ev(q, robot.q_home)
    clear = d.min(axis=1) > 0.01  # the distances' gradient is exact where the closest points are unique
    num = fd(lambda x: ev(x, robot.q_home)[0], q, 1e-6)
    np.testing.assert_allclose(grad[clear], num[clear], atol=2e-6, rtol=1e-5)
    num_d = fd(lambda x: ev(x)[2].min(axis=1), q, 1e-6)
    np.testing.assert_allclose(grad_d[clear], num_d[clear], atol=2e-6)


@pytest.mark.parametrize("objective", [JointLimitMargin(), JointLimitMargin(smooth=True) + ReferenceDistance(),
                                       Clearance(cap=0.25), Clearance(smooth=True)])  # fmt: skip
def test_taylor_models_contain_every_value_along_the_range(objective):
    """Configurations along a random curve q(t) = c + s·t + a·t² (a model with radius |a|), t ∈ [−1, 1]:
    every value of the split and every distance lies in its model at the same t, and the certificate's
    lower bound is below the objective at every t."""
    robot = qpik.load_robot("nammoto7")
    rng = np.random.default_rng(5)
    obs = ObstacleSet(OBSTACLES)
    bounds = bound_function(robot, objective, obs)
    ev = Evaluator(robot, objective, obs)
    t = np.linspace(-1.0, 1.0, 201)
    whole = taylor_function(bounds.values, [0])
    for k, c in enumerate(random_q(robot, 12, 2, margin=0.3)):
        s, a = rng.uniform(-1, 1, (2, robot.dof)) * rng.choice([1e-3, 0.05, 0.3])
        q = c + t[:, None] * s + (t * t)[:, None] * a
        r = np.abs(a)
        model = [m[0] for m in bounds.rows(c[None], bounds.params, robot.q_home[None], obs.params, s[None],
                                           r[None], (c - np.abs(s) - r)[None], (c + np.abs(s) + r)[None])]  # fmt: skip
        values = np.array([np.asarray(bounds.values(x, bounds.params, robot.q_home, obs.params)).ravel() for x in q])
        centre, slope, radius, lo, hi = model
        line = centre + t[:, None] * slope
        tol = 1e-12 * (1.0 + np.abs(values))
        assert np.all(values >= np.maximum(lo, line - radius) - tol), k
        assert np.all(values <= np.minimum(hi, line + radius) + tol), k
        bound = lower_bound([m[None] for m in model], bounds.sizes)[0]
        assert bound <= ev(q, robot.q_home)[0].min() + 1e-12
        # the composition (capsule axes, then each pair, then the split) encloses no wider than one Taylor
        # function of the whole values: the total width of the enclosures along t is at most the latter's
        direct = [np.asarray(m).ravel() for m in whole(c, bounds.params, robot.q_home, obs.params, s, r,
                                                       c - np.abs(s) - r, c + np.abs(s) + r)]  # fmt: skip
        widths = [np.minimum(m[4], m[0] + t[:, None] * m[1] + m[2]) - np.maximum(m[3], m[0] + t[:, None] * m[1]
                  - m[2]) for m in (model, direct)]  # fmt: skip
        assert widths[0].sum() <= widths[1].sum() * (1 + 1e-9), k


def test_sums_weights_parameters_and_names():
    robot = qpik.load_robot("iiwa14")
    s = 2.0 * JointLimitMargin() + Manipulability() + 0.5 * (Clearance() + ReferenceDistance())
    assert isinstance(s, Sum) and [w for w, _ in s.terms] == [2.0, 1.0, 0.5, 0.5]
    assert s.param_size(robot) == len(s.params(robot)) == 4 + 0 + 0 + 1 + robot.dof
    assert not s.smooth and not s.bounded  # a maximum inside; the manipulability is not bounded
    assert JointLimitMargin(smooth=True).smooth and (JointLimitMargin() + Clearance()).bounded
    q = random_q(robot, 20, 3)
    parts = [Evaluator(robot, o, OBSTACLES)(q, robot.q_home)[0] for _, o in s.terms]
    total = Evaluator(robot, s, OBSTACLES)(q, robot.q_home)[0]
    np.testing.assert_allclose(total, 2 * parts[0] + parts[1] + 0.5 * (parts[2] + parts[3]), rtol=1e-12)
    # weights are parameters: another weight, the same compiled function
    s2 = 5.0 * JointLimitMargin() + Manipulability() + 0.5 * (Clearance() + ReferenceDistance())
    assert s2.key() == s.key()
    with pytest.raises(InputError, match="weights"):
        Sum([(-1.0, JointLimitMargin())])
    with pytest.raises(InputError, match="objective"):
        resolve("fastest")
    with pytest.raises(InputError, match="sharpness"):
        JointLimitMargin(smooth=True, sharpness=0.0)


def test_user_expression_and_split_epigraph():
    robot = qpik.load_robot("iiwa14")
    user = Expression(lambda q: ca.sumsqr(q[:3]), name="shoulder")
    q = random_q(robot, 10, 4)
    f, grad, _, _ = Evaluator(robot, user)(q)
    np.testing.assert_allclose(f, (q[:, :3] ** 2).sum(axis=1), rtol=1e-14)
    np.testing.assert_allclose(grad[:, :3], 2 * q[:, :3], rtol=1e-14)
    assert user.key() != Expression(lambda q: q[0]).key()
    assert bound_function(robot, user, ObstacleSet([])) is not None  # every operation has a Taylor rule
    assert bound_function(robot, Expression(lambda q: ca.erf(q[0])), ObstacleSet([])) is None  # erf has none
    # the epigraph form: t >= every piece, cost = t: at the smallest feasible t it equals the value
    from qpik.objectives import Context

    qs = ca.SX.sym("q", 7)
    ctx = Context(robot, qs, ca.SX.zeros(7), ObstacleSet([]), ca.SX(0, 1))
    split = JointLimitMargin().split(ctx, ca.SX(0, 1))
    t, cost, g = split.epigraph()
    fn = ca.Function("e", [qs, t], [cost, g, split.value()])
    value = float(fn(q[0], 0.0)[2])
    c, gg, _ = fn(q[0], value)
    assert float(c) == value and float(np.max(np.asarray(gg))) == pytest.approx(0.0, abs=1e-15)
    with pytest.raises(InputError, match="scalar"):
        Evaluator(robot, Expression(lambda q: q[:2]))


def test_each_objective_reports_the_quantity_it_measures():
    """Quantity.value turns the minimised f into the measured quantity, checked against definitions written here: the
    margin (min of the normalised distances, > 0 inside the limits), the capped clearance (m), Yoshikawa's
    √det(J Jᵀ) from the Jacobian (not −log of it), the distance to q_ref; a weighted term reads the same quantity,
    a sum of maximised quantities their weighted sum, any other sum the objective itself."""
    robot = qpik.load_robot("iiwa14")
    q = random_q(robot, 100, 7, margin=0.05)
    ref = robot.q_home
    g = _normalised(robot, q)
    d = _clearances(robot, q, OBSTACLES)
    J = robot.jacobian(q)
    measured = {
        "margin": g.min(axis=1),
        "manipulability": np.sqrt(np.linalg.det(J @ np.swapaxes(J, 1, 2))),
        "clearance": np.minimum(d.min(axis=1), 0.1),
        "distance": 0.5 * ((q - ref) ** 2).sum(axis=1),
    }
    for key, value in measured.items():
        objective = resolve(key)
        f = Evaluator(robot, objective, OBSTACLES)(q, ref)[0]
        quantity = objective.quantity
        np.testing.assert_allclose(quantity.value(f), value, rtol=1e-9, atol=1e-12, err_msg=key)
        assert quantity.maximised == (key != "distance") and (quantity.sense == "minimised") == (key == "distance")
        assert isinstance(quantity.value(float(f[0])), float)
        weighted = (2.5 * objective).quantity
        f2 = Evaluator(robot, 2.5 * objective, OBSTACLES)(q, ref)[0]
        np.testing.assert_allclose(weighted.value(f2), value, rtol=1e-9, atol=1e-12, err_msg=key)
        assert weighted.name == quantity.name
    assert measured["margin"].min() > 0
    both = Clearance() + 0.1 * JointLimitMargin()
    f = Evaluator(robot, both, OBSTACLES)(q, ref)[0]
    np.testing.assert_allclose(both.quantity.value(f), measured["clearance"] + 0.1 * measured["margin"], atol=1e-12)
    assert both.quantity.name == "clearance + 0.1 × margin" and both.quantity.maximised
    mixed = Manipulability() + ReferenceDistance()
    f = Evaluator(robot, mixed, OBSTACLES)(q, ref)[0]
    np.testing.assert_array_equal(mixed.quantity.value(f), f)
    assert mixed.quantity.name == "objective" and mixed.quantity.sense == "minimised"
    assert JointLimitMargin().quantity.text(-0.25) == "margin 0.25"
    assert Clearance().quantity.text(-0.042, ".3g") == "clearance 0.042 m"
    assert "qpik minimises −margin" in JointLimitMargin().quantity.goal
