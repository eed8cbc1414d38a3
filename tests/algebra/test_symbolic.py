"""qpik.algebra.symbolic: the same expressions on numpy batches and CasADi symbols, against numpy's own algebra."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.algebra import symbolic as sy


def as_vec(v: np.ndarray) -> sy.Vec:
    return (v[..., 0], v[..., 1], v[..., 2])


def as_mat(M: np.ndarray) -> sy.Mat:
    return tuple(tuple(M[..., i, j] for j in range(3)) for i in range(3))  # type: ignore[return-value]


def to_np(M: sy.Mat) -> np.ndarray:
    """(..., 3, 3) from a rotation of scalars (constants broadcast to the batch)."""
    flat = np.broadcast_arrays(*[np.asarray(x, dtype=float) for row in M for x in row])
    return np.stack(flat, -1).reshape(*flat[0].shape, 3, 3)


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_vector_algebra_matches_numpy(seed):
    rng = np.random.default_rng(seed)
    u, v = rng.normal(size=(2, 1000, 3))
    A, B = rng.normal(size=(2, 1000, 3, 3))
    np.testing.assert_allclose(np.stack(sy.cross(as_vec(u), as_vec(v)), -1), np.cross(u, v), atol=1e-14)
    np.testing.assert_allclose(sy.dot(as_vec(u), as_vec(v)), np.einsum("ni,ni->n", u, v), atol=1e-14)
    np.testing.assert_allclose(to_np(sy.matmul(as_mat(A), as_mat(B))), A @ B, atol=1e-13)
    np.testing.assert_allclose(np.stack(sy.matvec(as_mat(A), as_vec(u)), -1), np.einsum("nij,nj->ni", A, u), atol=1e-14)
    np.testing.assert_allclose(to_np(sy.transpose(as_mat(A))), np.swapaxes(A, 1, 2), atol=0)
    np.testing.assert_allclose(np.stack(sy.vscale(u[:, 0], as_vec(v)), -1), u[:, :1] * v, atol=0)
    np.testing.assert_allclose(np.stack(sy.vsub(as_vec(u), as_vec(v)), -1), u - v, atol=0)


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_compose_is_the_homogeneous_product(seed):
    rng = np.random.default_rng(seed)
    T1, T2 = np.zeros((2, 500, 4, 4))
    for T in (T1, T2):
        T[:, :3, :3] = np.linalg.qr(rng.normal(size=(500, 3, 3)))[0]
        T[:, :3, 3] = rng.normal(size=(500, 3))
        T[:, 3, 3] = 1
    R, p = sy.compose(sy.frame_of_batch(T1), sy.frame_of_batch(T2))
    want = T1 @ T2
    np.testing.assert_allclose(to_np(R), want[:, :3, :3], atol=1e-14)
    np.testing.assert_allclose(np.stack(p, -1), want[:, :3, 3], atol=1e-14)


def test_elementary_rotations():
    th = np.linspace(-4, 4, 9)
    Rz = to_np(sy.rot_z(np.cos(th), np.sin(th)))
    Rx = to_np(sy.rot_x(np.cos(th), np.sin(th)))
    # R_z turns x toward y, R_x turns y toward z, by th; both keep their own axis
    np.testing.assert_allclose(Rz[:, :, 0], np.stack([np.cos(th), np.sin(th), 0 * th], -1), atol=1e-15)
    np.testing.assert_allclose(Rx[:, :, 1], np.stack([0 * th, np.cos(th), np.sin(th)], -1), atol=1e-15)
    np.testing.assert_array_equal(Rz[:, :, 2], np.broadcast_to([0.0, 0, 1], (9, 3)))
    np.testing.assert_array_equal(Rx[:, :, 0], np.broadcast_to([1.0, 0, 0], (9, 3)))


def test_constants_fold_to_python_numbers():
    x = ca.SX.sym("x")
    assert sy.mul(0.0, x) == 0.0 and sy.mul(x, 0) == 0.0
    assert sy.mul(1.0, x) is x and sy.add(0.0, x) is x
    assert isinstance(sy.mul(2.0, 3.0), float)
    assert sy.snap(np.cos(np.pi / 2)) == 0.0 and sy.snap(np.cos(np.pi)) == -1.0 and sy.snap(0.5) == 0.5
    R, _ = sy.frame_of(np.eye(4))
    assert all(isinstance(v, float) for row in R for v in row)
    # a product with a folded rotation keeps the zeros: the SX graph of x * (I) has no multiplications
    Rx = sy.matmul(sy.rot_z(x, x), R)
    assert Rx[2][2] == 1.0 and Rx[0][2] == 0.0


@pytest.mark.parametrize("name", ["sin", "cos", "sqrt", "fabs", "floor"])
def test_unary_ops_agree_across_backends(name):
    x = np.linspace(0.01, 7, 50)
    f = ca.Function("f", [s := ca.SX.sym("s")], [getattr(sy.CASADI, name)(s)])
    np.testing.assert_allclose(np.array(f(x)).ravel(), getattr(sy.NUMPY, name)(x), atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(y=st.floats(-10, 10), x=st.floats(-10, 10))
def test_binary_ops_agree_across_backends(y, x):
    a, b = ca.SX.sym("a"), ca.SX.sym("b")
    for name in ("atan2", "fmax", "fmin"):
        f = ca.Function("f", [a, b], [getattr(sy.CASADI, name)(a, b)])
        assert float(f(y, x)) == pytest.approx(float(getattr(sy.NUMPY, name)(y, x)), abs=1e-15)
    f = ca.Function("f", [a, b], [sy.CASADI.where(a > b, a, b)])
    assert float(f(y, x)) == float(sy.NUMPY.where(y > x, y, x))


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-1e3, 1e3))
def test_wrap_lands_in_half_open_interval(x):
    for w in (sy.NUMPY.wrap(np.array(x)), sy.NUMPY.wrap(x)):
        assert -np.pi < w <= np.pi
        k = (x - w) / (2 * np.pi)
        assert k == pytest.approx(round(k), abs=1e-9)
    s = ca.SX.sym("s")
    f = ca.Function("f", [s], [sy.CASADI.wrap(s)])
    assert float(f(x)) == pytest.approx(float(sy.NUMPY.wrap(np.array(x))), abs=1e-12)


def test_wrap_maps_minus_pi_to_pi():
    assert sy.NUMPY.wrap(-np.pi) == pytest.approx(np.pi)
    assert sy.NUMPY.wrap(np.array(-np.pi)) == pytest.approx(np.pi)


def test_safe_sqrt_never_nan():
    x = np.array([-1e-12, 0.0, 4.0])
    np.testing.assert_array_equal(sy.NUMPY.safe_sqrt(x), [0.0, 0.0, 2.0])


def test_ops_of_and_stack():
    x = ca.SX.sym("x")
    assert sy.ops_of(1.0, (2.0, x)) is sy.CASADI
    assert sy.ops_of(np.zeros(3), (1.0, [2.0])) is sy.NUMPY
    out = sy.stack([1.0, np.arange(3.0)], sy.NUMPY, (3,))
    np.testing.assert_array_equal(out, [[1, 0], [1, 1], [1, 2]])
    assert sy.stack([x, 1.0], sy.CASADI).shape == (2, 1)


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_solve_spd_matches_numpy_on_every_backend(seed):
    """sy.solve_spd on numpy batches and on CasADi symbols against numpy.linalg.solve, for SPD matrices of sizes 1-7
    down to a condition number of about 1e8."""
    rng = np.random.default_rng(seed)
    for m in range(1, 8):
        M = rng.normal(size=(m, m))
        A = M @ M.T + 10.0 ** rng.uniform(-8, 0) * np.eye(m)
        b = rng.normal(size=m)
        want = np.linalg.solve(A, b)
        scale = np.linalg.cond(A) * max(1.0, np.abs(want).max())
        batch = sy.solve_spd([[np.full(3, A[i, j]) for j in range(m)] for i in range(m)], [np.full(3, v) for v in b])
        np.testing.assert_allclose(np.array(batch).T, np.tile(want, (3, 1)), atol=1e-13 * scale)
        S, r = ca.SX.sym("A", m, m), ca.SX.sym("b", m)
        x = ca.vertcat(*sy.solve_spd([[S[i, j] for j in range(m)] for i in range(m)], [r[i] for i in range(m)]))
        got = np.asarray(ca.Function("f", [S, r], [x])(A, b)).ravel()
        np.testing.assert_allclose(got, want, atol=1e-13 * scale)
