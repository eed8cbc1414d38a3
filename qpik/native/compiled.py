"""Fast numeric evaluation of CasADi functions.

A CasADi ``Function`` called from Python converts its arguments at every call;
its ``buffer()`` interface evaluates the same program by reading
and writing preallocated numpy arrays in place. :class:`Compiled` wraps that:
the single-configuration paths of qpik (FK + Jacobian, the closed-form IK,
capsule distances) are CasADi functions traced from the same source as the
batched numpy path and the symbolic path (:mod:`qpik.algebra.symbolic`), as machine code where
:mod:`qpik.native.build` can build it.
"""

from __future__ import annotations

import concurrent.futures
import ctypes
import os
import threading
from collections.abc import Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from qpik.native.build import entry_point, load, native_library
from qpik.native.fastcall import kernel


class Compiled:
    """A CasADi function evaluated through preallocated buffers.

    Args:
        fn: a CasADi ``Function`` with dense inputs and outputs.
        compile: evaluate machine code from :func:`native` rather than CasADi's
            virtual machine (same results).
        library: the shared library of ``fn`` already built by :func:`native_library`
            (then ``compile`` is not consulted).
        large, inline: as :func:`native_library`'s (a kernel called often enough to repay ``-O2`` on a large source
            and the inlining flags).

    Attributes:
        library: the shared library exporting the function as ``fn.name()`` (the C
            calling convention of CasADi's generated code, for C callers such as
            :class:`qpik.analytic.intervals.Assembler`), or None on the virtual machine.
        kernel: the compiled extension's call of that library (:func:`qpik.native.fastcall.kernel`),
            returning :attr:`outputs` (or None for arguments it does not take), or None
            without the extension.
        arguments, results: the flat input and output buffers (CasADi's column-major order) that
            :meth:`run` reads and writes.

    Calling it with numpy inputs returns *views* of internal output buffers
    shaped like the CasADi outputs (row-major ``(rows, cols)``, squeezed to 1-D
    for columns). The views are overwritten by the next call: copy them if
    they must outlive it.
    """

    def __init__(
        self,
        fn: ca.Function,
        compile: bool = True,
        library: Path | None = None,
        large: int | None = None,
        inline: bool = False,
    ):
        lib = library if library is not None else native_library(fn, large=large, inline=inline) if compile else None
        self.fn = load(fn, lib)
        self.library = lib if self.fn is not fn else None
        fn = self.fn
        self._buf, self._eval = fn.buffer()
        self._lock = threading.Lock()
        self.arguments = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self.results = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        for i, a in enumerate(self.arguments):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self.results):
            self._buf.set_res(i, memoryview(r))
        self._views = []
        for i, r in enumerate(self.results):
            rows, cols = fn.size_out(i)
            # CasADi stores column-major: reshape (cols, rows) then transpose.
            self._views.append(r if cols == 1 else r.reshape(cols, rows).T)
        self.kernel = self.fast(result=self._views)

    def fast(
        self,
        inputs: Sequence[str] = (),
        outputs: Sequence[tuple[str, tuple[int, ...]]] = (),
        result: object = None,
    ):
        """A :class:`qpik.native.fastcall` kernel over this function's buffers (checked inputs, new or caller-owned
        outputs: :func:`qpik.native.fastcall.kernel`), or None on the virtual machine or without the extension."""
        if self.library is None:
            return None
        return kernel(self.fn, self.library, self.arguments, self.results, result, inputs, outputs)

    @property
    def outputs(self) -> Sequence[np.ndarray]:
        """The output buffers (views, shaped like the CasADi outputs) that every call overwrites."""
        return self._views

    def copies(self, *args: np.ndarray) -> list[np.ndarray]:
        """Call it and return copies of the outputs, which no later call overwrites: the call and the copies are
        made under the function's lock, so threads may share it."""
        with self._lock:
            return [np.array(out) for out in self(*args)]

    def __call__(self, *args: np.ndarray) -> Sequence[np.ndarray]:
        if self.kernel is not None:
            out = self.kernel(*args)
            if out is not None:
                return out
        for dst, src in zip(self.arguments, args):
            if type(src) is np.ndarray and src.ndim == 1:
                dst[:] = src  # the common case, without conversions
            else:  # column-major flatten for matrix inputs
                dst[:] = np.asarray(src, dtype=float).reshape(-1, order="F")
        self._eval()
        return self._views

    def run(self) -> None:
        """Evaluate on what :attr:`arguments` hold now, into :attr:`results`."""
        self._eval()


class Kernel(ctypes.Structure):
    """``Kernel`` of ``casadi_call.h``: a generated function's entry, argument and result pointer arrays, work arrays
    (:attr:`NativeFunction.addresses`)."""

    _fields_ = [(name, ctypes.c_void_p) for name in ("fn", "arg", "res", "iw", "w")]


class NativeFunction:
    """A compiled function's C entry point (CasADi's calling convention: ``casadi_fn`` in ``intervals.c``) with what
    C code needs to call it: numpy buffers of its inputs (:attr:`args`, column-major) and of the outputs asked for
    (:attr:`res`, None for the others, which the function then skips), its argument and result pointer arrays and
    its work arrays.

    :attr:`addresses` are ``(entry, arg, res, iw, w)``, the function and the four arguments it takes.
    """

    def __init__(
        self, fn: ca.Function, entry: tuple[int, ctypes.CDLL], outputs: tuple[int, ...], inputs: dict[int, np.ndarray]
    ):
        address, self._library = entry  # the entry point lives as long as its library
        self.args = [inputs[i] if i in inputs else np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self.res = [np.zeros(fn.nnz_out(i)) if i in outputs else None for i in range(fn.n_out())]
        argv = (ctypes.c_void_p * max(fn.sz_arg(), fn.n_in()))(*[a.ctypes.data for a in self.args])
        resv = (ctypes.c_void_p * max(fn.sz_res(), fn.n_out()))(*[r if r is None else r.ctypes.data for r in self.res])
        self._work = (argv, resv, np.zeros(max(fn.sz_iw(), 1), np.int64), np.zeros(max(fn.sz_w(), 1)))
        iw, w = self._work[2].ctypes.data, self._work[3].ctypes.data
        self.addresses = (address, ctypes.addressof(argv), ctypes.addressof(resv), iw, w)

    @property
    def kernel(self) -> Kernel:
        """:attr:`addresses` as the C struct ``Kernel``."""
        return Kernel(*self.addresses)

    @classmethod
    def of(
        cls, compiled: Compiled, outputs: tuple[int, ...], inputs: dict[int, np.ndarray] | None = None
    ) -> NativeFunction | None:
        """The C call of ``compiled`` computing ``outputs`` (their indices), or None when it is not native code or its
        integers are not 64-bit (:func:`entry_point`). ``inputs``: buffers (float64, of the inputs' sizes) to read
        some inputs from, shared with other functions, instead of buffers of its own."""
        entry = None if compiled.library is None else entry_point(compiled.library, compiled.fn.name())
        return None if entry is None else cls(compiled.fn, entry, outputs, inputs or {})


class RowMap:
    """A CasADi function of one row, evaluated over M rows in compiled chunks.

    ``fn.map`` over ``chunks[0]`` rows per call while more than 3/4 of that is left, then
    over the next size while more than 3/4 of it is left, and so on, the last size to the end
    (the last call padded with copies of its first row): one call per chunk, the loop over rows in
    machine code (:class:`Compiled`). Every size is compiled into one library on first use
    (``fn`` once in it).

    With ``threads`` > 1, a call of at least ``threads · chunks[0]`` rows is split into that many runs of
    consecutive rows, one in the calling thread and the others in a pool shared by every map
    (:func:`pool`), each with buffers of its own: the compiled code runs without Python's lock, so the runs
    take the machine's cores at once. The results are those of one thread, bit for bit (each row is computed
    alone). One call at a time per map: the buffers are the map's.

    Args:
        fn: dense inputs (a matrix input is given per row as its entries in CasADi's
            column-major order) and dense column-vector outputs.
        shared: indices of the inputs that are the same for every row (given once, 1-D).
        chunks: rows per call, from the largest to the smallest (two sizes or more).
        threads: runs a large call is split into (at most the cores this process may use).
        inline: compile with :data:`qpik.native.build.INLINE_FLAGS` (a hot map whose calls repay the compile time).
    """

    def __init__(
        self,
        fn: ca.Function,
        shared: Sequence[int] = (),
        chunks: tuple[int, ...] = (32, 4),
        threads: int = 1,
        inline: bool = False,
    ):
        self.fn, self.shared, self.chunks, self.inline = fn, tuple(shared), chunks, inline
        self._widths = [fn.nnz_out(k) for k in range(fn.n_out())]
        self.threads = max(1, min(int(threads), cores()))
        self._lock = threading.Lock()
        self._library: tuple[Path | None, list[tuple[int, ca.Function]]] | None = None
        self._runs: list[dict[int, tuple[Compiled, list[np.ndarray | None], list[np.ndarray]]]] = []

    def _maps(self, run: int = 0) -> dict[int, tuple[Compiled, list[np.ndarray | None], list[np.ndarray]]]:
        """Per size, the compiled map and views (size, nnz) of its per-row input and output buffers of run ``run``
        (the library compiled on the first call under this map's own lock: a ``functools.cached_property`` would
        hold one lock for every instance on Python 3.11 and serialise the compiles of
        :func:`qpik.native.build.concurrently`)."""
        with self._lock:
            if self._library is None:
                name, shared, sizes = self.fn.name(), list(self.shared), sorted(set(self.chunks), reverse=True)
                maps = [(n, self.fn.map(f"{name}_rows{n}", "serial", n, shared, [])) for n in sizes]
                self._library = (native_library(*(fn for _, fn in maps), inline=self.inline), maps)
            while len(self._runs) <= run:
                self._runs.append(self._buffers(*self._library))
            return self._runs[run]

    def _buffers(self, lib: Path | None, fns: list[tuple[int, ca.Function]]):
        maps = {}
        for size, fn in fns:
            call = Compiled(fn, compile=False, library=lib)
            # column-major (nnz, size) buffers: one row's entries are contiguous
            ins = [None if k in self.shared else a.reshape(size, -1) for k, a in enumerate(call.arguments)]
            maps[size] = (call, ins, [r.reshape(size, -1) for r in call.results])
        return maps

    @property
    def built(self) -> bool:
        """Whether the maps are compiled (:meth:`build` would return at once)."""
        return self._library is not None

    def build(self) -> None:
        """Compile the maps now (else on the first call): a solve that starts its clock after this times
        evaluations, never a compile."""
        self._maps()

    def __call__(self, *args: np.ndarray) -> list[np.ndarray]:
        """Each output as (M, nnz) for per-row inputs (M, nnz_i) (shared inputs: (nnz_i,))."""
        shared = self.shared
        per_row = [(k, np.asarray(a, dtype=float).reshape(len(a), -1)) for k, a in enumerate(args) if k not in shared]
        M = len(per_row[0][1]) if per_row else 1
        outs = [np.empty((M, width)) for width in self._widths]
        big = self.chunks[0]
        runs = self.threads if self.threads * big <= M else 1
        if runs == 1:
            self._fill(self._maps(), args, per_row, outs, 0, M)
            return outs
        ends = [big * round(M * r / (runs * big)) for r in range(runs)] + [M]  # runs of whole big chunks
        work = [(self._maps(r), ends[r], ends[r + 1]) for r in range(runs)]
        others = [pool().submit(self._fill, maps, args, per_row, outs, i, j) for maps, i, j in work[1:]]
        maps, i, j = work[0]
        self._fill(maps, args, per_row, outs, i, j)
        for other in others:
            other.result()
        return outs

    def _fill(self, maps, args, per_row, outs: list[np.ndarray], start: int, stop: int) -> None:
        """Rows ``start:stop`` of ``outs`` from the buffers ``maps`` of one run."""
        shared, chunks = self.shared, self.chunks
        given = set()  # the sizes whose buffers hold this call's shared inputs
        i = start
        while i < stop:
            size = next((n for n in chunks[:-1] if stop - i > 3 * n // 4), chunks[-1])
            m = min(size, stop - i)
            call, ins, res = maps[size]
            if size not in given:
                given.add(size)
                for k in shared:
                    call.arguments[k][:] = np.ravel(args[k])
            for k, rows in per_row:
                buf = ins[k]
                buf[:m] = rows[i : i + m]
                if m < size:
                    buf[m:] = rows[i]
            call.run()
            for out, r in zip(outs, res):
                out[i : i + m] = r[:m]
            i += m


_pool: concurrent.futures.ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def cores() -> int:
    """The CPUs this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _forget_pool() -> None:
    """In a child made by ``fork``, the parent's pool threads do not exist: the child makes its own."""
    global _pool, _pool_lock
    _pool, _pool_lock = None, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)


def pool() -> concurrent.futures.ThreadPoolExecutor:
    """The threads that run the other runs of a :class:`RowMap` call (one fewer than :func:`cores`, made on first
    use; idle threads cost nothing, and they end with the process)."""
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = concurrent.futures.ThreadPoolExecutor(max(1, cores() - 1), thread_name_prefix="qpik-rows")
        return _pool
