"""qpik.algebra.enclosure: the interval extension and the Taylor models contain every value of the function.

Checked against dense samples of the function itself inside random boxes (along random lines
for the Taylor models), on random expressions of every supported operation and on the closed
form of both arms (whose q over an arm-angle range the certificate bounds this way, checked
against the batched numpy closed form).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS
from hypothesis import given, settings

import qpik
from qpik.algebra.enclosure import interval_function, taylor_function
from qpik.analytic import closed_form_for
from qpik.core.errors import InputError


def _expressions(x: ca.SX, y: ca.SX, p: ca.SX) -> list[ca.SX]:
    """One expression per rule, with repeated variables (the dependency problem) and point parameters."""
    return [
        x * y - p * x + 2.0 * x,
        x * x - y / (2.0 + ca.sin(y)),
        ca.sqrt(ca.fmax(x + 3.0, 0.0)) + ca.fabs(y - p),
        ca.sin(3.0 * x) + ca.cos(y * p),
        ca.atan2(y, x) + ca.atan2(x - 2.0, p),
        ca.if_else(x > y, x * p, y - 1.0) + ca.floor(x),
        ca.fmin(x, y) * ca.fmax(x, p) + ca.exp(0.1 * y) - ca.log(2.0 + x * x),
        ca.if_else(ca.logic_and(x > 0, ca.logic_not(y < p)), x**2, -y) + (x <= y) + (x == p),
    ]


@settings(max_examples=15, deadline=None)
@given(seed=SEEDS)
def test_bounds_contain_every_sample(seed):
    x, y, p = ca.SX.sym("x"), ca.SX.sym("y"), ca.SX.sym("p")
    fn = ca.Function("f", [x, y, p], _expressions(x, y, p))
    box = interval_function(fn, [0, 1])  # inputs: x_lo, y_lo, p, x_hi, y_hi
    rng = np.random.default_rng(seed)
    for _ in range(20):
        lo = rng.uniform(-3, 3, 2)
        hi = lo + rng.uniform(0, 1.5, 2) * rng.choice([1e-3, 1.0], 2)
        pv = rng.uniform(-2, 2)
        out = [np.asarray(v).ravel() for v in box(lo[0], lo[1], pv, hi[0], hi[1])]
        n = len(out) // 2
        xs = rng.uniform(lo[0], hi[0], 300)
        ys = rng.uniform(lo[1], hi[1], 300)
        vals = np.array([np.asarray(fn(a, b, pv)).ravel() for a, b in zip(xs, ys)]).reshape(300, -1)
        for k in range(n):
            v = vals[:, k]
            ok = np.isfinite(v)
            tol = 1e-12 * (1 + np.abs(v[ok]))
            assert np.all(v[ok] >= out[k] - tol), (k, v[ok].min(), out[k])
            assert np.all(v[ok] <= out[n + k] + tol), (k, v[ok].max(), out[n + k])


def _self_motion(name: str):
    """The arm ``name``, its closed form ``q(T, ψ)`` as one SX function (all branches), a random reachable pose and
    the generator that drew it (seed 3)."""
    robot = qpik.load_robot(name)
    T, psi = ca.SX.sym("T", 4, 4), ca.SX.sym("psi")
    Q = closed_form_for(robot).casadi_function(T, psi)[0]
    rng = np.random.default_rng(3)
    return robot, ca.Function("q", [T, psi], [Q]), robot.fk(rng.uniform(robot.q_min, robot.q_max)), rng


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7"])
def test_closed_form_box_contains_the_self_motion(name):
    robot, self_motion, pose, rng = _self_motion(name)
    box = interval_function(self_motion, [1])
    for a in rng.uniform(-np.pi, np.pi - 0.05, 6):
        b = a + 0.05
        lo, hi = (np.asarray(v) for v in box(pose, a, b))
        sols = qpik.ik(robot, np.broadcast_to(pose, (400, 4, 4)), np.linspace(a, b, 400))
        assert np.all(sols.q >= lo - 1e-12) and np.all(sols.q <= hi + 1e-12)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_taylor_models_contain_every_sample_along_the_line(seed):
    """x(t) = cx + sx·t, y(t) = cy + sy·t for t ∈ [−1, 1]: every output at every t lies within its model
    ``centre + slope·t ± radius`` and within its bounds."""
    x, y, p = ca.SX.sym("x"), ca.SX.sym("y"), ca.SX.sym("p")
    fn = ca.Function("f", [x, y, p], _expressions(x, y, p))
    tm = taylor_function(fn, [0, 1])  # inputs: x, y, p, then slope, radius, lo, hi of x and of y
    rng = np.random.default_rng(seed)
    t = np.linspace(-1.0, 1.0, 301)
    for _ in range(20):
        c = rng.uniform(-3, 3, 2)
        sl = rng.uniform(-0.75, 0.75, 2) * rng.choice([1e-3, 1.0], 2)
        pv = rng.uniform(-2, 2)
        args = [c[0], c[1], pv] + [v for k in range(2) for v in (sl[k], 0.0, c[k] - abs(sl[k]), c[k] + abs(sl[k]))]
        out = np.array([np.asarray(v).ravel() for v in tm(*args)]).reshape(5, -1)
        centre, slope, radius, lo, hi = out
        vals = np.array([np.asarray(fn(c[0] + sl[0] * u, c[1] + sl[1] * u, pv)).ravel() for u in t])
        ok = np.isfinite(vals)
        tol = 1e-12 * (1 + np.abs(vals))
        below = np.maximum(lo, centre + slope * t[:, None] - radius)
        above = np.minimum(hi, centre + slope * t[:, None] + radius)
        assert np.all((vals >= below - tol) | ~ok) and np.all((vals <= above + tol) | ~ok)


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7"])
def test_closed_form_taylor_model_contains_the_self_motion_and_is_second_order(name):
    """The Taylor model of q over a ψ range holds the batched numpy closed form at 200 ψ of the range,
    and its remainder shrinks with the square of the range (100× narrower: a radius over 300× smaller;
    a first-order bound would give 100×)."""
    robot, self_motion, pose, rng = _self_motion(name)
    tm = taylor_function(self_motion, [1])
    t = np.linspace(-1.0, 1.0, 200)
    radius = {}
    for half in (0.05, 5e-4):
        radius[half] = []
        for mid in rng.uniform(-np.pi + 0.1, np.pi - 0.1, 5):
            centre, slope, r, lo, hi = (np.asarray(v) for v in tm(pose, mid, half, 0.0, mid - half, mid + half))
            sols = qpik.ik(robot, np.broadcast_to(pose, (len(t), 4, 4)), mid + half * t)
            tol = 1e-12 * (1 + np.abs(sols.q))
            assert np.all(sols.q >= np.maximum(lo, centre + slope * t[:, None, None] - r) - tol)
            assert np.all(sols.q <= np.minimum(hi, centre + slope * t[:, None, None] + r) + tol)
            radius[half].append(np.median(r))
    assert np.median(radius[5e-4]) <= np.median(radius[0.05]) / 300


def test_point_inputs_stay_points_and_bad_functions_are_refused():
    x, p = ca.SX.sym("x"), ca.SX.sym("p")
    fn = ca.Function("f", [x, p], [x * p + ca.sin(p)])
    box = interval_function(fn, [0])
    lo, hi = (float(v) for v in box(1.0, 2.0, 1.0))  # x = [1, 1]: a point box gives the value itself
    assert lo == hi == pytest.approx(2.0 + np.sin(2.0))
    with pytest.raises(InputError, match="SX function"):
        m = ca.MX.sym("m")
        interval_function(ca.Function("m", [m], [m * 2]), [0])
    with pytest.raises(InputError, match="no interval rule"):
        interval_function(ca.Function("t", [x], [ca.tanh(x)]), [0])
