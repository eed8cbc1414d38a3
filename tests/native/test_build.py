"""qpik.native.build: the optimisation level of the generated libraries ($QPIK_OPTIMISE), the flags a compiler accepts,
the inline fmin and fmax."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import matrix_function

from qpik.core.errors import InputError
from qpik.native import build


def test_the_level_is_the_variables_or_else_by_size(monkeypatch):
    monkeypatch.delenv("QPIK_OPTIMISE", raising=False)
    assert build.optimisation(1000) == "-O2" and build.optimisation(build.LARGE + 1) == "-O1"
    # a caller's own threshold (the controller's QP): -O2 up to it, -O1 beyond
    assert build.optimisation(build.LARGE + 1, large=build.LARGE + 1) == "-O2"
    assert build.optimisation(build.LARGE + 2, large=build.LARGE + 1) == "-O1"
    for level in build.LEVELS:
        monkeypatch.setenv("QPIK_OPTIMISE", level)
        assert build.optimisation(1000) == level == build.optimisation(build.LARGE + 1)
        assert build.optimisation(build.LARGE + 1, large=build.LARGE + 1) == level
    monkeypatch.setenv("QPIK_OPTIMISE", "-Ofast")
    with pytest.raises(InputError, match="QPIK_OPTIMISE"):
        build.optimisation(1000)


@pytest.mark.skipif(build.compiler() is None, reason="no C compiler, or QPIK_NATIVE=0")
def test_each_level_is_its_own_library_with_the_same_answers(monkeypatch, tmp_path):
    """A library built at -O0 and one at -O2 are two files of the cache, and give the same bits (no fast-math)."""
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path))
    fn = matrix_function("levels")
    rng = np.random.default_rng(3)
    A, x = rng.normal(size=(2, 3)), rng.normal(size=3)
    outs, libs = [], []
    for level in ("-O0", "-O2"):
        monkeypatch.setenv("QPIK_OPTIMISE", level)
        libs.append(build.native_library(fn))
        outs.append([np.asarray(o) for o in ca.external("levels", str(libs[-1]))(A, x)])
    assert libs[0] != libs[1] and all(lib.exists() for lib in libs)
    for a, b in zip(*outs):
        assert np.array_equal(a, b)


@pytest.mark.skipif(build.compiler() is None, reason="no C compiler, or QPIK_NATIVE=0")
@pytest.mark.parametrize("level", ["-O0", "-O2"])
def test_compiled_fmin_and_fmax_give_the_virtual_machines_bits(monkeypatch, tmp_path, level):
    """The inline fmin and fmax of the generated libraries (build.PRELUDE) against CasADi's virtual machine (the
    maths library's): every pair of ±0, ±1, ±inf and NaN, the sign of a zero and NaN included."""
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path))
    monkeypatch.setenv("QPIK_OPTIMISE", level)
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    fn = ca.Function("extremes", [x, y], [ca.fmin(x, y), ca.fmax(x, y)])
    compiled = ca.external("extremes", str(build.native_library(fn)))
    values = [-0.0, 0.0, 1.0, -1.0, np.inf, -np.inf, np.nan]
    for a in values:
        for b in values:
            want = [float(v) for v in fn(a, b)]
            got = [float(v) for v in compiled(a, b)]
            for w, g in zip(want, got):
                assert (np.isnan(w) and np.isnan(g)) or (w == g and np.signbit(w) == np.signbit(g)), (a, b, w, g)


@pytest.mark.skipif(build.compiler() is None, reason="no C compiler, or QPIK_NATIVE=0")
def test_a_compiler_that_rejects_the_inline_flag_builds_without_it(monkeypatch, tmp_path):
    """build.INLINE_FLAGS (asked with inline=True) go only to a compiler that accepts them: one that rejects them
    still builds every library (with the same answers), and native code stays on."""
    cc = build.compiler()
    assert all(build.accepts(cc, flag) for flag in build.INLINE_FLAGS)  # gcc >= 5 and clang do
    assert not build.accepts(cc, "-fno-such-option-qpik")
    strict = tmp_path / "strict-cc"
    rejected = " ".join(build.INLINE_FLAGS)
    loop = f'for a in "$@"; do case " {rejected} " in *" $a "*) exit 1;; esac; done'
    strict.write_text(f'#!/bin/sh\n{loop}\nexec {cc} "$@"\n')
    strict.chmod(0o755)
    assert not build.accepts(str(strict), build.INLINE_FLAGS[0])
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(build, "_native_failed", None)
    fn = matrix_function("strict")
    rng = np.random.default_rng(4)
    A, x = rng.normal(size=(2, 3)), rng.normal(size=3)
    libs, outs = [], []
    for compiler in (cc, str(strict)):
        monkeypatch.setenv("CC", compiler)
        libs.append(build.native_library(fn, inline=True))
        outs.append([np.asarray(o) for o in ca.external("strict", str(libs[-1]))(A, x)])
    assert libs[0] != libs[1] and build.compiler() is not None
    for a, b in zip(*outs):
        assert np.array_equal(a, b)
