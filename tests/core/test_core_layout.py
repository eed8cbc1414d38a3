"""Named layouts: what is packed by name is read back by name, in numpy and in CasADi, for any shapes."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.core.layout import Layout

SHAPES = st.lists(st.integers(0, 4), max_size=3).map(tuple)
BLOCKS = st.dictionaries(st.from_regex(r"[a-z]{1,6}", fullmatch=True), SHAPES, min_size=1, max_size=5)


@settings(max_examples=60, deadline=None, database=None)
@given(blocks=BLOCKS, seed=st.integers(0, 2**16), lead=st.sampled_from([(), (3,), (2, 2)]))
def test_packed_blocks_come_back_by_name(blocks, seed, lead):
    """pack (CasADi, row-major) -> evaluate -> views gives every part back; packer() agrees with pack."""
    layout = Layout(**blocks)
    rng = np.random.default_rng(seed)
    parts = {k: rng.normal(size=shape) for k, shape in blocks.items()}
    flat = np.asarray(ca.evalf(layout.pack(**{k: ca.DM(v) if v.ndim <= 2 else v for k, v in parts.items()})))
    flat = flat.reshape(-1)
    assert flat.shape == (layout.size,) == (sum(v.size for v in parts.values()),)
    assert np.array_equal(flat, layout.packer()(parts))
    stacked = np.broadcast_to(flat, (*lead, layout.size))
    for k, v in layout.views(stacked).items():
        assert v.shape == (*lead, *blocks[k]) and np.array_equal(v, np.broadcast_to(parts[k], v.shape))


@settings(max_examples=40, deadline=None, database=None)
@given(blocks=BLOCKS, count=st.integers(1, 4), seed=st.integers(0, 2**16))
def test_symbols_read_what_views_read(blocks, count, seed):
    """A CasADi function of the symbols of ``count`` records gives the numpy views of the same buffer."""
    layout = Layout(**blocks)
    x = ca.SX.sym("x", count * layout.size)
    sym = layout.symbols(x, count)
    buffer = np.random.default_rng(seed).normal(size=count * layout.size)
    views = layout.views(buffer.reshape(count, layout.size))
    for k in blocks:
        got = np.asarray(ca.Function("f", [x], [sym[k]])(buffer))
        want = views[k]
        if count == 1 and len(blocks[k]) == 2:
            assert got.shape == want.shape[1:] and np.array_equal(got, want[0])
        else:
            assert np.array_equal(got.reshape(-1), want.reshape(-1))


def test_nested_layouts_and_wrong_sizes():
    inner = Layout(a=2, b=(2, 2))
    outer = Layout(head=(), inner=inner, tail=3)
    buf = np.arange(outer.size, dtype=float)
    parts = outer.views(buf)
    assert np.array_equal(inner.views(parts.inner).b, [[3.0, 4.0], [5.0, 6.0]]) and parts.tail.tolist() == [7, 8, 9]
    with pytest.raises(ValueError, match="block b has 3 values"):
        inner.pack(a=[1, 2], b=[1, 2, 3])
    with pytest.raises(ValueError, match="expected the blocks"):
        inner.pack(a=[1, 2])
    with pytest.raises(ValueError, match="last axis of 10"):
        outer.views(np.zeros(9))


@settings(max_examples=60, deadline=None, database=None)
@given(blocks=BLOCKS, seed=st.integers(0, 2**16))
def test_split_reads_a_sequence_as_views_read_the_buffer(blocks, seed):
    """split of a plain list of numbers gives each block's values in the shape views gives (scalars as scalars,
    vectors as tuples, matrices as row tuples)."""
    layout = Layout(**blocks)
    flat = np.random.default_rng(seed).normal(size=layout.size)
    parts, views = layout.split(flat.tolist()), layout.views(flat)
    assert list(parts) == list(views)
    for name, view in views.items():
        assert np.array_equal(np.array(parts[name], dtype=float).reshape(view.shape), view)
    with pytest.raises(ValueError, match="split"):
        layout.split([0.0] * (layout.size + 1))


def test_packer_writes_into_a_block_of_a_larger_buffer():
    """packer(buffer) writes the parts in place into the given block (as pack orders them), nothing else; a buffer
    of another size or dtype is refused."""
    inner = Layout(a=2, b=(2, 2), s=())
    outer = Layout(head=3, inner=inner, tail=2)
    buf = np.full(outer.size, -1.0)
    pack = inner.packer(outer.views(buf).inner)
    parts = {"a": [1.0, 2.0], "b": np.array([[3.0, 4.0], [5.0, 6.0]]), "s": 7.0}
    assert np.shares_memory(pack(parts), buf)
    assert buf.tolist() == [-1.0] * 3 + [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0] + [-1.0] * 2
    parts["s"] = 8.0
    pack(parts)
    assert buf[9] == 8.0 and np.array_equal(np.asarray(ca.evalf(inner.pack(**parts))).ravel(), buf[3:10])
    with pytest.raises(ValueError, match="shape"):
        inner.packer(np.zeros(inner.size + 1))
    with pytest.raises(ValueError, match="float64"):
        inner.packer(np.zeros(inner.size, dtype=np.float32))
