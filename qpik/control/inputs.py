"""The inputs of a function traced from a :class:`~qpik.control.state.SymState`, beyond ``q``, and their numbers.

Each input is an SX column (:attr:`Input.symbol`) and how its numbers are found:

- :class:`Input`: ``value(state)`` gives them (state: a numeric :class:`~qpik.control.state.State`, or None in
  the controller), read at every call (e.g. an obstacle set's packed parameters, which moving it changes in place);
- :class:`Constant`: numbers fixed when the input is declared (the control period, a mask of pairs);
- :class:`Owned`: a task's or limit's parameters, ``owner.param_values()`` by name in its ``param_layout``.

:class:`Filler` gives a function's inputs one buffer, a block each (laid out by :class:`~qpik.core.layout.Layout`),
and writes their numbers in place: a constant once, the others at every call, each straight into its block (an
owner's parameters by name, in C where the extension of :mod:`qpik.native.fastcall` loads: ``scatter``, which
writes as ``view[...] = value`` does).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from qpik.core.layout import Layout
from qpik.native.fastcall import extension

if TYPE_CHECKING:
    import casadi as ca


class Parametrised(Protocol):
    """What :class:`Owned` reads of a task or limit (a :class:`~qpik.control.state.Traced`): its parameters'
    numbers by name."""

    def param_values(self) -> Mapping[str, Any]: ...


class Input:
    """An input read at every call: ``value(state)`` gives its :attr:`size` numbers (state: a numeric
    :class:`~qpik.control.state.State`, or None in the controller).

    Attributes:
        symbol: the input's SX column.
        value: the function giving its numbers.
    """

    def __init__(self, symbol: ca.SX, value: Callable[[Any], Any]):
        self.symbol, self.value = symbol, value

    @property
    def size(self) -> int:
        """The number of entries."""
        return self.symbol.numel()

    def writer(self, block: np.ndarray) -> Callable[[], object] | None:
        """A function writing the numbers of now (state None) into ``block`` (this input's (size,) block of a
        buffer), to call before every call of the traced function; None where the block is written now, once."""
        value = self.value

        def write() -> None:
            block[...] = value(None)

        return write


class Constant(Input):
    """An input whose numbers are fixed: ``numbers`` (copied, flattened to :attr:`size` entries)."""

    def __init__(self, symbol: ca.SX, numbers: Any):
        fixed = np.array(numbers, dtype=float).reshape(-1)
        super().__init__(symbol, lambda state: fixed)

    def writer(self, block: np.ndarray) -> None:
        block[...] = self.value(None)
        return None


class Owned(Input):
    """The parameters of a task or limit (``owner``): ``owner.param_values()`` by name, laid out by ``layout``
    (the owner's ``param_layout``), read at every call."""

    def __init__(self, symbol: ca.SX, owner: Parametrised, layout: Layout):
        pack = layout.packer()
        super().__init__(symbol, lambda state: pack(owner.param_values()))
        self.owner, self.layout = owner, layout

    def writer(self, block: np.ndarray) -> Callable[[], object]:
        values, fast = self.owner.param_values, extension()
        if fast is None:
            pack = self.layout.packer(block)
            return lambda: pack(values())
        scatter, names = fast.scatter, self.layout.names
        views = tuple(self.layout.views(block)[name] for name in names)
        return lambda: scatter(values(), names, views)


class Filler:
    """The numbers of ``inputs`` in one buffer: block ``p<k>`` of :attr:`layout` the k-th input's.

    Attributes:
        layout: the buffer's :class:`~qpik.core.layout.Layout`.
        buffer: (layout.size,) the numbers, as the last call left them (constants written at construction).
    """

    def __init__(self, inputs: Sequence[Input]):
        self.layout = Layout(**{f"p{k}": inp.size for k, inp in enumerate(inputs)})
        self.buffer = np.empty(self.layout.size)
        blocks = self.layout.views(self.buffer)
        writers = [inp.writer(blocks[f"p{k}"]) for k, inp in enumerate(inputs)]
        self._writers = tuple(write for write in writers if write is not None)

    def __call__(self) -> np.ndarray:
        """Write the inputs' numbers of now and return :attr:`buffer` (the same array every call)."""
        for write in self._writers:
            write()
        return self.buffer
