"""Fast numeric evaluation of CasADi functions for one input at a time.

A CasADi ``Function`` called from Python spends ~25 µs converting arguments;
its ``buffer()`` interface evaluates the same SX program in a few µs by
reading and writing preallocated numpy arrays in place. :class:`Compiled`
wraps that: the single-configuration paths of qpik (FK + Jacobian, the
closed-form IK) are CasADi functions traced from the same source as the
batched numpy path and the symbolic path (:mod:`qpik.symbolic`).
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np


class Compiled:
    """A CasADi function evaluated through preallocated buffers.

    Args:
        fn: a CasADi ``Function`` with dense inputs and outputs.

    Calling it with numpy inputs returns *views* of internal output buffers
    shaped like the CasADi outputs (row-major ``(rows, cols)``, squeezed to 1-D
    for columns). The views are overwritten by the next call: copy them if
    they must outlive it.
    """

    def __init__(self, fn: ca.Function):
        self.fn = fn
        self._buf, self._eval = fn.buffer()
        self._args = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self._res = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        for i, a in enumerate(self._args):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self._res):
            self._buf.set_res(i, memoryview(r))
        self._views = []
        for i, r in enumerate(self._res):
            rows, cols = fn.size_out(i)
            # CasADi stores column-major: reshape (cols, rows) then transpose.
            self._views.append(r if cols == 1 else r.reshape(cols, rows).T)

    def __call__(self, *args: np.ndarray) -> Sequence[np.ndarray]:
        for dst, src in zip(self._args, args):
            if type(src) is np.ndarray and src.ndim == 1:
                dst[:] = src  # the common case, without conversions
            else:  # column-major flatten for matrix inputs
                dst[:] = np.asarray(src, dtype=float).reshape(-1, order="F")
        self._eval()
        return self._views
