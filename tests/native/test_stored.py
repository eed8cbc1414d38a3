"""qpik.native.stored: a derived function kept on disk is the function a fresh derivation gives.

Checked on the Taylor-model extension of a random expression (:func:`qpik.algebra.enclosure.taylor_function`):
the stored copy, read back by another call, returns the same bits as a derivation made without the store, on
random inputs; a different derivation (other model inputs) is another file; a damaged file is derived again.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS
from hypothesis import given, settings

from qpik.algebra import enclosure
from qpik.native import stored


def _function(seed: int) -> ca.Function:
    """A random SX function of two inputs, with every kind of operation the Taylor models have rules for."""
    rng = np.random.default_rng(seed)
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    a, b = rng.uniform(-2, 2, 2)
    out = ca.sin(a * x) * ca.cos(y + b) + ca.atan2(y, x - 3.0) + ca.sqrt(x * x + 1.0) / (2.0 + ca.cos(x * y))
    return ca.Function(f"f{seed}", [x, y], [out, x * y - b])


def _files(tmp_path) -> list:
    return sorted((tmp_path / stored.FOLDER).glob("*.casadi"))


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_the_stored_copy_gives_the_bits_of_a_fresh_derivation(seed, tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("cache")
    fn = _function(seed)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("QPIK_CACHE", str(tmp_path))
        first = enclosure.taylor_function(fn, [0])
        assert len(_files(tmp_path)) == 1
        again = enclosure.taylor_function(fn, [0])  # read back from the file
    fresh = enclosure._taylor(fn, [0], None)  # derived without the store
    rng = np.random.default_rng(seed)
    for _ in range(10):
        c, y = rng.uniform(-2, 2, 2)
        w = rng.uniform(0, 0.5)
        args = (c, y, w, 0.0, c - w, c + w)
        for got, want, one in zip(again(*args), fresh(*args), first(*args)):
            assert np.array_equal(np.asarray(got), np.asarray(want), equal_nan=True)
            assert np.array_equal(np.asarray(one), np.asarray(want), equal_nan=True)
    assert len(_files(tmp_path)) == 1


def test_another_derivation_is_another_file_and_a_damaged_file_is_derived_again(tmp_path, monkeypatch):
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path))
    fn = _function(7)
    enclosure.taylor_function(fn, [0])
    enclosure.taylor_function(fn, [0, 1])
    enclosure.interval_function(fn, [0])
    files = _files(tmp_path)
    assert len(files) == 3
    for f in files:
        f.write_text("not a serialized function")
    box = enclosure.interval_function(fn, [0])  # inputs: x_lo, y, x_hi
    bounds = np.concatenate([o.full().ravel() for o in box(0.2, 0.5, 0.4)])
    lo, hi = np.split(bounds, 2)
    xs = np.linspace(0.2, 0.4, 201)
    vals = np.array([np.ravel(np.concatenate([o.full().ravel() for o in fn(x, 0.5)])) for x in xs])
    assert np.all(vals >= lo - 1e-12) and np.all(vals <= hi + 1e-12)
    readable = [f for f in _files(tmp_path) if f.read_text() != "not a serialized function"]
    assert len(readable) == 1 and ca.Function.deserialize(readable[0].read_text()).n_in() == 3
