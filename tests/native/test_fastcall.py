"""qpik.native.fastcall: the compiled extension's kernels against CasADi's own evaluation, its checks against
qpik.core.validate, caller-owned outputs; and the paths that use it against the general ones."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS, matrix_function
from hypothesis import given, settings

import qpik
from qpik.core.validate import COMPILED, joint_vector, single_pose
from qpik.native.compiled import Compiled
from qpik.native.fastcall import extension

pytestmark = pytest.mark.skipif(extension() is None, reason="no compiled extension (QPIK_NATIVE=0 or no compiler)")


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_fresh_equals_casadi(seed):
    rng = np.random.default_rng(seed)
    f = matrix_function("fastcall_f")
    kernel = Compiled(f).fast()
    A, x = rng.normal(size=(2, 3)), rng.normal(size=3)
    got = kernel.fresh(A, x)
    want = [np.array(w) for w in f(A, x)]
    assert [g.shape for g in got] == [(2,), (3, 3), (1, 3)]
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w.reshape(g.shape), atol=1e-15)
    np.testing.assert_allclose(got[0], A @ x, atol=1e-14)  # independent of CasADi
    assert kernel.fresh(A, x)[1] is not got[1]  # new arrays every call


def test_fresh_returns_none_for_what_it_does_not_take():
    kernel = Compiled(matrix_function("fastcall_f")).fast()
    A, x = np.ones((2, 3)), np.ones(3)
    bad = x.copy()
    bad[1] = np.nan
    for args in ((A, bad), (A, np.ones(4)), (A, [1.0, 2.0, 3.0]), (A, np.ones(3, dtype=int)), (A.T, x), (A, x[::-1])):
        assert kernel.fresh(*args) is None
    assert kernel.fresh(A, np.inf * x) is None


def test_a_scalar_input_takes_every_real_number():
    """A one-entry input takes Python and numpy reals and 0-d arrays in C (not bools or complex numbers); the
    ``scalar`` check takes nothing else, ``plain`` also a float64 array of one entry."""
    x, y = ca.SX.sym("x"), ca.SX.sym("y", 2)
    f = Compiled(ca.Function("fastcall_scalar", [x, y], [x * y]))
    plain, scalar = f.fast(), f.fast(("scalar", "plain"))
    y0 = np.array([1.5, -2.0])
    for value in (3, 3.0, np.float64(3), np.float32(3), np.int8(3), np.uint64(3), np.array(3.0), np.array(3)):
        assert f.kernel(value, y0) is not None  # the compiled call, not CasADi's buffers
        np.testing.assert_array_equal(plain.fresh(value, y0)[0], 3.0 * y0)
        np.testing.assert_array_equal(scalar.fresh(value, y0)[0], 3.0 * y0)
    assert scalar.fresh(np.ones(1), y0) is None and plain.fresh(np.ones(1), y0) is not None
    for value in (True, np.True_, 1j, np.complex128(1), np.array([3.0, 1.0]), "3", None, 10**400, np.float32("nan")):
        assert plain.fresh(value, y0) is None and scalar.fresh(value, y0) is None
    assert f.kernel(np.inf, y0) is not None  # unchecked: only fresh and into check finiteness


def test_into_writes_the_callers_arrays():
    kernel = Compiled(matrix_function("fastcall_f")).fast()
    A, x = np.arange(6.0).reshape(2, 3), np.array([1.0, -2.0, 0.5])
    outs = (np.empty(2), np.empty((3, 3)), np.empty((1, 3)))
    assert kernel.into(outs, A, x) is outs
    for got, want in zip(outs, kernel.fresh(A, x)):
        np.testing.assert_array_equal(got, want)
    with pytest.raises(qpik.InputError, match="out"):
        kernel.into((np.empty(2), np.empty((3, 3)), np.empty(3)), A, x)
    with pytest.raises(qpik.InputError, match="out"):
        kernel.into((np.empty(2), np.empty((3, 3), order="F"), np.empty((1, 3))), A, x)


def test_the_extension_installs_its_checks_into_validate():
    """core sits below native: the extension hands validate its C checks when it loads, and they decide the common
    inputs (a vector the C check refuses still reaches the general path, which names it)."""
    ext = extension()
    assert COMPILED.vector_ok is ext.vector_ok and COMPILED.pose_ok is ext.pose_ok
    q = np.arange(7.0)
    assert ext.vector_ok(q, 7) and joint_vector(q, 7)[0] is q
    with pytest.raises(qpik.InputError, match="q: "):
        joint_vector(np.array([0.0, np.nan, 0.0]), 3)


@settings(max_examples=50, deadline=None)
@given(seed=SEEDS)
def test_pose_check_agrees_with_validate(seed):
    """pose_ok (C) accepts exactly the finite (4, 4) float64 poses qpik.core.validate accepts without projection."""
    rng = np.random.default_rng(seed)
    robot = qpik.load_robot("iiwa14")
    T = robot.fk(rng.uniform(robot.q_min, robot.q_max))
    cases = [T]
    for scale in (1e-7, 1e-5, 1e-3):
        R = T.copy()
        R[:3, :3] += scale * rng.normal(size=(3, 3))
        cases.append(R)
    far, row, nan, mirrored = T.copy(), T.copy(), T.copy(), T.copy()
    far[0, 3] = 2e6
    row[3, 0] = 1e-9
    nan[1, 2] = np.nan
    mirrored[:3, 0] *= -1.0
    cases += [far, row, nan, mirrored]
    check = extension().pose_ok
    for case in cases:
        try:
            single_pose(case.copy(order="F"))  # the Python path (not C-contiguous: no C check)
            accepted = True
        except (qpik.InputError, qpik.RotationError):
            accepted = False
        assert check(case) == accepted


@settings(max_examples=25, deadline=None)
@given(seed=SEEDS)
def test_fast_paths_equal_the_general_ones(seed):
    """FK/Jacobian and the closed form through the extension equal CasADi's buffer path and the numpy batch."""
    rng = np.random.default_rng(seed)
    for name in ("iiwa14", "nammoto7"):
        robot = qpik.load_robot(name)
        q = rng.uniform(robot.q_min, robot.q_max)
        T, J = robot.fk_jacobian(q)
        Tb, Jb = robot.fk_jacobian(q[None])  # numpy
        np.testing.assert_allclose(T, Tb[0], atol=1e-13)
        np.testing.assert_allclose(J, Jb[0], atol=1e-13)
        np.testing.assert_array_equal(robot.fk(q), T)
        np.testing.assert_array_equal(robot.jacobian(q), J)
        psi = float(qpik.redundancy_parameter(robot, q)[0])
        one = qpik.ik(robot, T, psi)
        batch = qpik.ik(robot, T[None], np.array([psi]))
        np.testing.assert_allclose(one.q[one.valid], batch.q[0][batch.valid[0]], atol=1e-9)
        for flag in ("valid", "within_limits", "singular"):
            np.testing.assert_array_equal(getattr(one, flag), getattr(batch, flag)[0])
        assert np.abs(robot.fk(one.q[one.valid]) - T).max() < 1e-9  # checked by FK


def test_fast_paths_reject_bad_input_with_the_python_errors():
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home.copy()
    q[3] = np.nan
    with pytest.raises(qpik.InputError, match="q"):
        robot.fk_jacobian(q)
    T = robot.fk(robot.q_home)
    T[0, 0] += 1e-3
    with pytest.raises(qpik.RotationError):
        qpik.ik(robot, T, 0.1)
    sols = qpik.ik(robot, T, 0.1, project=True)  # projection stays on the Python path
    assert sols.q.shape == (8, 7)


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_circle_lists_reads_the_rows_back(seed):
    """circle_lists against the layout qpik_circle_sets writes: row r's pieces after the rows before it, its
    singular values at r * ns."""
    rng = np.random.default_rng(seed)
    rows, ns = int(rng.integers(1, 6)), int(rng.integers(0, 4))
    count, scount = rng.integers(0, 4, rows).astype(np.intc), rng.integers(0, ns + 1, rows).astype(np.intc)
    iv, sv = rng.normal(size=2 * int(count.sum()) + 3), rng.normal(size=rows * ns + 1)
    sets, found = extension().circle_lists(iv, count, sv, scount, ns)
    starts = np.concatenate([[0], np.cumsum(count)])
    for r in range(rows):
        assert sets[r] == [(iv[2 * i], iv[2 * i + 1]) for i in range(starts[r], starts[r + 1])]
        assert found[r] == sv[r * ns : r * ns + scount[r]].tolist()


def test_circle_lists_rejects_what_it_does_not_take():
    circle_lists = extension().circle_lists
    count = np.ones(2, np.intc)
    with pytest.raises(TypeError, match="iv"):
        circle_lists(np.zeros(3), count, np.zeros(2), np.zeros(2, np.intc), 1)  # 2 rows of 1 piece need 4
    with pytest.raises(TypeError, match="count"):
        circle_lists(np.zeros(4), count.astype(float), np.zeros(2), np.zeros(2, np.intc), 1)
    with pytest.raises(ValueError, match="scount"):
        circle_lists(np.zeros(4), count, np.zeros(2), np.full(2, 2, np.intc), 1)


def _assigned(view: np.ndarray, value: object) -> object:
    """``view[...] = value`` in numpy: "ok" or the exception's type."""
    try:
        view[...] = value
    except Exception as exc:  # the kind of error is what is compared
        return type(exc)
    return "ok"


def test_scatter_writes_as_numpy_assignment_does():
    """scatter(parts, names, views) leaves every view as ``view[...] = parts[name]`` does (the peer: numpy), for the
    values C writes itself (floats, numpy floats, float64 arrays of the view's shape) and for those it hands to
    numpy (ints, bools, lists, other dtypes and layouts, broadcasts, wrong shapes: the same error)."""
    scatter = extension().scatter
    values = [2.5, np.float64(-1.25), np.nan, 3, True, [1.0, 2.0, 3.0], np.arange(3.0), np.arange(3, dtype=np.float32),
              np.arange(6.0)[::2], np.arange(6.0).reshape(2, 3), np.ones((3, 1)), np.ones(4), np.array(7.0),
              "x"]  # fmt: skip
    shapes = [(), (1,), (3,), (2, 3), (1, 3)]
    for shape in shapes:
        for value in values:
            want_buf, got_buf = np.full(20, -9.0), np.full(20, -9.0)
            size = int(np.prod(shape))
            want = _assigned(want_buf[4 : 4 + size].reshape(shape), value)
            view = got_buf[4 : 4 + size].reshape(shape)
            try:
                scatter({"a": value}, ("a",), (view,))
                got = "ok"
            except Exception as exc:
                got = type(exc)
            assert got == want, (shape, value)
            assert np.array_equal(got_buf, want_buf, equal_nan=True), (shape, value)  # the view's entries, no other
    views = (np.zeros(()), np.zeros(2))
    scatter({"b": [3.0, 4.0], "a": 1.0}, ("a", "b"), views)  # by name, whatever the order of the mapping
    assert views[0] == 1.0 and views[1].tolist() == [3.0, 4.0]
    with pytest.raises(KeyError, match="c"):
        scatter({"a": 1.0}, ("c",), (np.zeros(()),))
    read_only = np.zeros(2)
    read_only.flags.writeable = False
    with pytest.raises(ValueError):
        scatter({"a": np.ones(2)}, ("a",), (read_only,))
    with pytest.raises(TypeError):
        scatter({"a": 1.0}, ("a", "b"), (np.zeros(()),))
