"""The compiled CPython extension that calls qpik's generated C kernels from Python (``fastcall.c`` of
:data:`qpik.native.sources.SRC`).

A call of a CasADi function through its ``buffer()`` interface costs about 1 µs beyond the
kernel's 0.1 µs, and a ctypes call about as much: argument marshalling and dispatch. The
extension's :class:`Kernel` holds the generated function's entry point (from the shared
library :mod:`qpik.native.compiled` built) with its work arrays and numpy buffers, copies the
arguments in C, checks them there where asked (finite, a pose's rotation orthonormal) and
returns new arrays or writes into the caller's (see ``fastcall.c``). Its module functions check
inputs in C (``pose_ok``, ``vector_ok``, installed into :mod:`qpik.core.validate` when it loads) and turn the
arrays of the feasible-set C code into Python lists (``circle_lists``: :class:`qpik.analytic.intervals.SetAssembler`).

The extension is compiled once by the system C compiler against this Python's and numpy's
headers and cached with the other libraries (:func:`qpik.native.sources.load_source`). Without
a compiler, without the Python headers, or with ``QPIK_NATIVE=0``, :func:`extension` is None
and every caller keeps its general path (CasADi's buffer interface or virtual machine).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import install_checks
from qpik.native.build import entry_point
from qpik.native.sources import load_source

if TYPE_CHECKING:
    import casadi as ca

INPUTS = {"plain": 0, "pose": 1, "scalar": 2}
"""Input checks of :meth:`Kernel.fresh`: ``plain`` (finite), ``pose`` (a (4, 4) homogeneous transform
that :func:`qpik.core.validate.single_pose` accepts without projection), ``scalar`` (one finite real number: a
Python float or int, a numpy floating or integer scalar, a 0-d array; never an array of one entry). An input
of one entry takes all of these real numbers whatever its check."""
OUTPUTS = {"matrix": 0, "raw": 1, "flags": 2, "skip": 3}
"""How :meth:`Kernel.fresh` hands an output out: ``matrix`` (CasADi's column-major (rows, cols) as a
row-major array), ``raw`` (the entries in CasADi's order, in the given shape), ``flags`` (entries
> 0.5 as bools, in the given shape), ``skip`` (not returned)."""


@cache
def extension() -> ModuleType | None:
    """The compiled extension module ``qpik_fastcall``, or None (no compiler or headers, or ``QPIK_NATIVE=0``)."""
    module = load_source("qpik_fastcall", "extension", ["fastcall.c"])
    if module is not None:
        module.set_input_error(InputError)
        install_checks(module.vector_ok, module.pose_ok)
    return module


def kernel(
    fn: ca.Function,
    library: Path,
    args: Sequence[np.ndarray],
    res: Sequence[np.ndarray],
    result: object = None,
    inputs: Sequence[str] = (),
    outputs: Sequence[tuple[str, tuple[int, ...]]] = (),
):
    """A :class:`Kernel` of ``fn`` (from ``library``) over the buffers ``args`` and ``res``, or None without the
    extension.

    Args:
        fn: the CasADi function (dense inputs and outputs) whose generated C ``library`` exports.
        args, res: one float64 buffer per input and output, ``nnz`` entries each (column-major).
        result: what calling the kernel returns (e.g. views of ``res``).
        inputs: the check of each input for :meth:`Kernel.fresh` (:data:`INPUTS`; default ``plain``).
        outputs: per output, ``(form, shape)`` for :meth:`Kernel.fresh` (:data:`OUTPUTS`; default the
            output as a row-major matrix, squeezed to 1-D for a column).
    """
    mod = extension()
    entry = None if mod is None else entry_point(library, fn.name())
    if entry is None:
        return None
    address, dll = entry
    ins = []
    for i, a in enumerate(args):
        rows, cols = fn.size_in(i)
        ins.append((a, rows, cols, INPUTS[inputs[i] if i < len(inputs) else "plain"]))
    outs = []
    for i, r in enumerate(res):
        rows, cols = fn.size_out(i)
        form, shape = outputs[i] if i < len(outputs) else ("matrix", (rows,) if cols == 1 else (rows, cols))
        outs.append((r, rows, cols, OUTPUTS[form], tuple(shape)))
    work = (fn.sz_arg(), fn.sz_res(), fn.sz_iw(), fn.sz_w())
    return mod.Kernel(address, work, tuple(ins), tuple(outs), result, dll)
