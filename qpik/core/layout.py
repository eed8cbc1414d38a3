"""Named layouts of flat buffers: what a compiled function packs, read back by name.

A compiled CasADi function returns one flat column; a :class:`Layout` names its blocks (each a
row-major array of a fixed shape, or a nested layout), packs the symbolic pieces in that order and hands
back numpy views (or CasADi symbols) by name. No other code computes an offset into such a buffer.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, Union

import casadi as ca
import numpy as np

Shape = Union[int, tuple[int, ...], "Layout"]


class Blocks(Mapping[str, Any]):
    """The blocks of one buffer by name, as attributes (``blocks.J``) or items (``blocks["J"]``)."""

    def __init__(self, parts: dict[str, Any]):
        self._parts = parts

    def __getattr__(self, name: str) -> Any:
        try:
            return self.__dict__["_parts"][name]
        except KeyError:
            raise AttributeError(name) from None

    def __getitem__(self, name: str) -> Any:
        return self._parts[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._parts)

    def __len__(self) -> int:
        return len(self._parts)


class Layout:
    """Blocks of a flat buffer, in order: ``Layout(pose=(4, 4), J=(6, n), dist=PAIR)``.

    A block's shape is an int (a vector), a tuple (row-major array; ``()`` a scalar) or a nested
    :class:`Layout` (its flat part, to be read with that layout).

    Attributes:
        size: the buffer's length.
    """

    def __init__(self, **blocks: Shape):
        self._shapes: dict[str, Shape] = {}
        self._spans: dict[str, slice] = {}
        start = 0
        for name, shape in blocks.items():
            shape = (shape,) if isinstance(shape, int) else shape
            size = shape.size if isinstance(shape, Layout) else math.prod(shape)
            if size < 0 or (not isinstance(shape, Layout) and min(shape, default=0) < 0):
                raise ValueError(f"block {name}: negative shape {shape}")
            self._shapes[name], self._spans[name] = shape, slice(start, start + size)
            start += size
        self.size = start

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._shapes)

    def shape(self, name: str) -> tuple[int, ...]:
        """The shape of block ``name`` (a nested layout's: its size)."""
        shape = self._shapes[name]
        return (shape.size,) if isinstance(shape, Layout) else shape

    def __repr__(self) -> str:
        return f"Layout({', '.join(f'{k}={v!r}' for k, v in self._shapes.items())})"

    # ---- packing --------------------------------------------------------------------------

    def pack(self, **parts: Any) -> ca.SX:
        """One SX column of every block in order; each part an SX (row-major), a nested sequence of scalars
        (SX or numbers) or an array of the block's size."""
        if set(parts) != set(self._shapes):
            raise ValueError(f"pack: expected the blocks {list(self._shapes)}, got {list(parts)}")
        columns = []
        for name in self._shapes:
            column = _column(parts[name])
            if column.numel() != self._spans[name].stop - self._spans[name].start:
                raise ValueError(f"pack: block {name} has {column.numel()} values, its shape {self.shape(name)}")
            columns.append(column)
        return ca.vertcat(*columns) if columns else ca.SX(0, 1)

    def flatten(self, **parts: Any) -> list:
        """The scalars of :meth:`pack` as a list (to write one record of a repeated layout into a larger list)."""
        column = self.pack(**parts)
        return [column[i] for i in range(column.numel())]

    def packer(self, buffer: np.ndarray | None = None) -> Callable[[Mapping[str, Any]], np.ndarray]:
        """A function writing parts by name (arrays or numbers of the blocks' shapes) into one buffer of this
        layout and returning it: the same buffer every call, overwritten by the next (a control loop's
        parameters, packed without allocating).

        ``buffer``: the vector written into (float64, :attr:`size` entries), e.g. a view of this layout's block
        in a larger buffer, which then receives the parts in place; default a new one."""
        if buffer is None:
            buffer = np.empty(self.size)
        elif buffer.shape != (self.size,) or buffer.dtype != np.float64:
            raise ValueError(f"packer: expected a float64 buffer of shape ({self.size},), got {buffer.dtype} "
                             f"{buffer.shape}")  # fmt: skip
        views = [(name, buffer[span].reshape(self.shape(name))) for name, span in self._spans.items()]

        def pack(parts: Mapping[str, Any]) -> np.ndarray:
            for name, view in views:
                view[...] = parts[name]
            return buffer

        return pack

    # ---- reading --------------------------------------------------------------------------

    def views(self, flat: np.ndarray) -> Blocks:
        """Views into ``flat`` (..., size) by name: block ``k`` as (..., \\*shape); a nested layout's block as its
        flat part (..., its size)."""
        if flat.shape[-1:] != (self.size,):
            raise ValueError(f"views: expected a last axis of {self.size}, got shape {flat.shape}")
        lead = flat.shape[:-1]
        return Blocks({k: flat[..., span].reshape((*lead, *self.shape(k))) for k, span in self._spans.items()})

    def split(self, values: Sequence[Any]) -> Blocks:
        """The blocks of a flat sequence of scalars (numbers, numpy arrays that broadcast, or SX), by name: a
        scalar block (shape ``()``) as its scalar, a vector as a tuple, a matrix (r, c) as a tuple of r row
        tuples, a nested layout's block as the tuple of its scalars (to :meth:`split` with that layout)."""
        if len(values) != self.size:
            raise ValueError(f"split: expected {self.size} values, got {len(values)}")
        out = {}
        for name, span in self._spans.items():
            part, shape = tuple(values[span]), self._shapes[name]
            if shape == ():
                part = part[0]
            elif not isinstance(shape, Layout) and len(shape) == 2:
                part = tuple(part[r * shape[1] : (r + 1) * shape[1]] for r in range(shape[0]))
            out[name] = part
        return Blocks(out)

    def symbols(self, flat: ca.SX, count: int = 1) -> Blocks:
        """The blocks of an SX column holding ``count`` records of this layout back to back.

        With ``count == 1``: a scalar block as a 1×1 SX, a vector as a column, a matrix (r, c) as an
        r×c SX, a block of more axes or a nested layout as its flat column. With ``count > 1``: each
        block as one column of its values over the records, record by record.
        """
        if flat.numel() != count * self.size:
            raise ValueError(f"symbols: expected {count} × {self.size} values, got {flat.numel()}")
        out = {}
        for name, span in self._spans.items():
            index = [r * self.size + i for r in range(count) for i in range(span.start, span.stop)]
            column = flat[index] if index else ca.SX(0, 1)
            shape = self.shape(name)
            if count == 1 and len(shape) == 2 and not isinstance(self._shapes[name], Layout):
                column = ca.reshape(column, shape[1], shape[0]).T
            out[name] = column
        return Blocks(out)


def _column(part: Any) -> ca.SX:
    """An SX column of a part's values, row-major."""
    if isinstance(part, ca.SX | ca.MX | ca.DM):
        return ca.vec(ca.SX(part).T) if part.numel() else ca.SX(0, 1)
    if isinstance(part, np.ndarray):
        return ca.SX(ca.DM(np.ravel(part.astype(float))))
    if isinstance(part, list | tuple):
        items = [_column(x) for x in part]
        return ca.vertcat(*items) if items else ca.SX(0, 1)
    return ca.SX(part)
