"""Tests of qpik.analytic.trig: roots checked by substitution, numpy against CasADi."""

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.algebra import symbolic as sy
from qpik.analytic import trig

SEEDS = st.integers(0, 2**32 - 1)


def _abc(seed, n=2000):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(2, n))
    c = rng.normal(size=n) * 1.5  # about a third of the equations have no root
    return a, b, c


@settings(max_examples=10, deadline=None)
@given(SEEDS)
def test_solve_cos_sin_roots_satisfy_equation(seed):
    a, b, c = _abc(seed)
    tp, tm, ok = trig.solve_cos_sin(a, b, c, sy.NUMPY)
    assert np.all(np.isfinite(tp)) and np.all(np.isfinite(tm))
    assert np.array_equal(ok.astype(bool), a * a + b * b >= c * c)
    for t in (tp, tm):
        assert np.abs(a * np.cos(t) + b * np.sin(t) - c)[ok.astype(bool)].max() < 1e-12


@settings(max_examples=10, deadline=None)
@given(SEEDS)
def test_solve_cos_sin_cs_matches_angles(seed):
    a, b, c = _abc(seed)
    tp, tm, ok = trig.solve_cos_sin(a, b, c, sy.NUMPY)
    (cp, sp), (cm, sm), ok2 = trig.solve_cos_sin_cs(a, b, c, sy.NUMPY)
    assert np.array_equal(ok, ok2)
    m = ok.astype(bool)
    for t, cc, ss in ((tp, cp, sp), (tm, cm, sm)):
        assert np.all(np.isfinite(cc)) and np.all(np.isfinite(ss))
        assert np.abs(cc - np.cos(t))[m].max() < 1e-12
        assert np.abs(ss - np.sin(t))[m].max() < 1e-12


def test_solve_cos_sin_degenerate_is_finite():
    z = np.zeros(3)
    for out in (trig.solve_cos_sin(z, z, np.array([0.0, 1.0, -1.0]), sy.NUMPY),):
        assert all(np.all(np.isfinite(x)) for x in out[:2])
        assert not np.any(out[2])
    (cp, sp), (cm, sm), ok = trig.solve_cos_sin_cs(z, z, np.ones(3), sy.NUMPY)
    assert np.all(np.isfinite([cp, sp, cm, sm])) and not np.any(ok)


@settings(max_examples=10, deadline=None)
@given(SEEDS)
def test_asin2_acos2(seed):
    x = np.random.default_rng(seed).uniform(-1.2, 1.2, 2000)
    inside = np.abs(x) <= 1
    s1, s2, ok = trig.asin2(x, sy.NUMPY)
    c1, c2, ok2 = trig.acos2(x, sy.NUMPY)
    assert np.array_equal(ok, inside) and np.array_equal(ok2, inside)
    for t in (s1, s2):
        assert np.all(np.isfinite(t)) and np.abs(np.sin(t) - x)[inside].max() < 1e-12
    for t in (c1, c2):
        assert np.all(np.isfinite(t)) and np.abs(np.cos(t) - x)[inside].max() < 1e-12
    assert np.all(np.cos(s1) >= 0) and np.all(np.cos(s2) <= 1e-15)
    assert np.all(np.sin(c1) >= 0) and np.all(np.sin(c2) <= 1e-15)


def test_angle_and_flip_are_half_open():
    y = np.array([-0.0, 0.0, -1e-20, 1.0, -1.0])
    x = np.array([-1.0, -1.0, -1.0, 0.0, 0.0])
    t = trig.angle(y, x, sy.NUMPY)
    assert np.allclose(t, [np.pi, np.pi, np.pi, np.pi / 2, -np.pi / 2], atol=0)
    th = np.array([np.pi, 0.0, -1.0, 1.0, -np.pi + 1e-9])
    f = trig.flip(th, sy.NUMPY)
    assert np.all((f > -np.pi) & (f <= np.pi))
    assert np.allclose(np.cos(f), -np.cos(th)) and np.allclose(np.sin(f), -np.sin(th))


def test_casadi_backend_agrees_with_numpy():
    a, b, c = _abc(1, 50)
    A, B, C = (ca.SX.sym(n) for n in "abc")
    (cp, sp), (cm, sm), ok = trig.solve_cos_sin_cs(A, B, C, sy.CASADI)
    tp, tm, _ = trig.solve_cos_sin(A, B, C, sy.CASADI)
    f = ca.Function("f", [A, B, C], [cp, sp, cm, sm, ok, tp, tm, trig.angle(A, B, sy.CASADI)])
    ref = [*sum(trig.solve_cos_sin_cs(a, b, c, sy.NUMPY)[:2], ()), trig.solve_cos_sin_cs(a, b, c, sy.NUMPY)[2]]
    ref += [*trig.solve_cos_sin(a, b, c, sy.NUMPY)[:2], trig.angle(a, b, sy.NUMPY)]
    for i in range(len(a)):
        got = [float(v) for v in f(a[i], b[i], c[i])]
        assert np.allclose(got, [float(r[i]) for r in ref], atol=1e-14)
