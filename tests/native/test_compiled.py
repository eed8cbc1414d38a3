"""qpik.native.compiled: buffer evaluation equals CasADi's own call, for vector and matrix inputs/outputs."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS, matrix_function
from hypothesis import given, settings

from qpik.native.compiled import Compiled


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_buffer_call_equals_casadi_call(seed):
    rng = np.random.default_rng(seed)
    f = matrix_function()
    c = Compiled(f)
    A, x = rng.normal(size=(2, 3)), rng.normal(size=3)
    got = c(A, x)
    want = f(A, x)
    assert [g.shape for g in got] == [(2,), (3, 3), (1, 3)]
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, np.array(w).reshape(g.shape), atol=1e-15)
    np.testing.assert_allclose(got[0], A @ x, atol=1e-14)  # independent of CasADi


def test_outputs_are_views_overwritten_by_the_next_call():
    c = Compiled(matrix_function())
    A = np.arange(6.0).reshape(2, 3)
    first = c(A, np.ones(3))[0]
    kept = first.copy()
    second = c(A, 2 * np.ones(3))[0]
    assert first is second
    np.testing.assert_allclose(second, 2 * kept)


def test_accepts_lists_and_integers():
    c = Compiled(matrix_function())
    out = c([[1, 2, 3], [4, 5, 6]], [1, 0, 0])[0]
    np.testing.assert_array_equal(out, [1.0, 4.0])


def test_native_code_equals_the_virtual_machine_and_can_be_turned_off(monkeypatch, tmp_path):
    """The machine-code path computes what CasADi's own evaluation computes; QPIK_NATIVE=0 keeps the VM."""
    import shutil

    import pytest

    import qpik
    from qpik.analytic import closed_form_for
    from qpik.native import build

    if shutil.which("cc") is None or build.compiler() is None:
        pytest.skip("no C compiler, or QPIK_NATIVE=0: native() falls back to the virtual machine by design")
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path))
    robot = qpik.load_robot("nammoto7")
    f = closed_form_for(robot).casadi_function  # the largest single-pose function: 16 IK branches
    fast = Compiled(f)
    assert fast.fn is not f and fast.fn.name() == f.name()  # an external (compiled) function
    assert list(tmp_path.glob(f"{f.name()}_*.so"))  # cached on disk
    T = robot.fk(robot.q_home)
    for delta in np.linspace(-3.0, 3.0, 13):
        got = [g.copy() for g in fast(T, np.array([delta]))]
        want = f(T, delta)
        for g, w in zip(got, want):
            np.testing.assert_allclose(g, np.array(w).reshape(g.shape, order="F"), atol=1e-13, rtol=0)
    monkeypatch.setenv("QPIK_NATIVE", "0")
    assert build.native(f) is f


@pytest.mark.parametrize("chunks", [(8, 3), (16, 5, 2)])
def test_row_map_equals_one_call_per_row(chunks):
    """Every row as one call of the function, with two chunk sizes and with three, over counts of rows that take
    each size, padded or not."""
    from qpik.native.compiled import RowMap

    T, x, p = ca.SX.sym("T", 2, 2), ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    fn = ca.Function("g", [T, x, p], [ca.vertcat(ca.mtimes(T, x[:2]) * p[0], ca.sum1(x) + p[1]), ca.sin(x)])
    rows = RowMap(fn, shared=(2,), chunks=chunks)
    rng = np.random.default_rng(0)
    for M in (1, 2, 7, 8, 13, 29, 40):
        Ts, xs, pv = rng.normal(size=(M, 2, 2)), rng.normal(size=(M, 3)), rng.normal(size=2)
        a, b = rows(np.swapaxes(Ts, 1, 2).reshape(M, 4), xs, pv)  # matrices per row in column-major order
        for k in range(M):
            want = [np.asarray(v).ravel() for v in fn(Ts[k], xs[k], pv)]
            np.testing.assert_allclose(a[k], want[0], rtol=1e-14)
            np.testing.assert_allclose(b[k], want[1], rtol=1e-14)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_row_map_split_among_threads_gives_the_rows_of_one_thread_bit_for_bit(seed):
    from qpik.native.compiled import RowMap, cores

    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    fn = ca.Function("h", [x, p], [ca.vertcat(ca.sin(x[0]) * p[0] + x[1] * x[2], ca.sqrt(ca.sumsqr(x)) + p[1])])
    one, split = RowMap(fn, shared=(1,), chunks=(8, 3)), RowMap(fn, shared=(1,), chunks=(8, 3), threads=4)
    assert split.threads == min(4, cores())
    rng = np.random.default_rng(seed)
    for M in (5, 16, 17, 37, 200):  # below, at and above threads × chunk rows
        xs, pv = rng.normal(size=(M, 3)), rng.normal(size=2)
        want = one(xs, pv)[0]
        np.testing.assert_array_equal(split(xs, pv)[0], want)
        np.testing.assert_allclose(want[M // 2], np.asarray(fn(xs[M // 2], pv)).ravel(), rtol=1e-14)


def test_row_map_threads_work_in_a_forked_child():
    """A child forked after the pool's threads started makes its own (the parent's do not exist there)."""
    import multiprocessing

    from qpik.native.compiled import RowMap, cores

    if cores() < 2 or "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("needs 2 cores and fork")
    x = ca.SX.sym("x", 2)
    rows = RowMap(ca.Function("k", [x], [ca.sin(x) * x[1]]), chunks=(4, 2), threads=2)
    xs = np.random.default_rng(1).normal(size=(40, 2))
    want = rows(xs)[0].copy()  # the pool's threads now run in this process
    _FORKED["rows"] = rows  # the child has it by fork (a map is not pickled)
    try:
        with multiprocessing.get_context("fork").Pool(1) as child:
            got = child.apply_async(_row_map_in_child, (xs,)).get(timeout=60)
    finally:
        _FORKED.clear()
    np.testing.assert_array_equal(got, want)


_FORKED: dict = {}


def _row_map_in_child(xs):
    return _FORKED["rows"](xs)[0].copy()
