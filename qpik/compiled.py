"""Fast numeric evaluation of CasADi functions.

A CasADi ``Function`` called from Python spends ~25 µs converting arguments;
its ``buffer()`` interface evaluates the same program in a few µs by reading
and writing preallocated numpy arrays in place. :class:`Compiled` wraps that:
the single-configuration paths of qpik (FK + Jacobian, the closed-form IK,
capsule distances) are CasADi functions traced from the same source as the
batched numpy path and the symbolic path (:mod:`qpik.symbolic`).

:func:`native` goes one step further: it has CasADi generate C for a
function, compiles it once with the system C compiler (``cc``) and caches the
shared library on disk, keyed by a hash of the source. CasADi's SX virtual
machine costs a few ns per instruction; machine code is several times faster,
which matters for the large functions (IK of all branches, distances of all
capsule/obstacle pairs, mapped sweeps). Where no compiler works, or with
``QPIK_NATIVE=0``, the virtual machine is used: same results, slower.
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Sequence
from functools import cache, cached_property
from pathlib import Path

import casadi as ca
import numpy as np

CFLAGS = ("-shared", "-fPIC")
_native_failed: str | None = None  # why native compilation is off in this process


def cache_dir() -> Path:
    """Where compiled functions are kept: ``$QPIK_CACHE``, else ``$XDG_CACHE_HOME/qpik``, else ``~/.cache/qpik``."""
    if os.environ.get("QPIK_CACHE"):
        return Path(os.environ["QPIK_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "qpik"


def compiler() -> str | None:
    """The C compiler that :func:`shared_library` uses (``$CC``, else ``cc``), or None when off or missing.

    Off with ``QPIK_NATIVE=0``, or after a compilation failed in this process (warned once).
    """
    global _native_failed
    if os.environ.get("QPIK_NATIVE", "1") == "0" or _native_failed:
        return None
    found = shutil.which(os.environ.get("CC", "cc"))
    if found is None:
        _native_failed = "no C compiler (cc) on PATH"
    return found


def shared_library(name: str, source: bytes, flags: Sequence[str] = (), fatal: bool = True) -> Path | None:
    """C ``source`` compiled once into a shared library cached in :func:`cache_dir`, or None.

    The library is keyed by a hash of the source, the flags (:func:`optimisation` for the source's size,
    :data:`CFLAGS` and ``flags``, e.g. include folders) and CasADi's version. Processes that need the same
    library at once compile it once: the others wait on a lock file beside it. A compilation that takes
    longer than :data:`QUIET` seconds says so on stderr, and again every :data:`TICK` seconds. None when
    :func:`compiler` is None or compilation fails: then a warning says why, once, and with ``fatal`` native
    code stays off in this process (without it only this library is missing).
    """
    global _native_failed
    cc = compiler()
    if cc is None:
        return None
    cflags = (optimisation(len(source)), *CFLAGS, *flags)
    key = hashlib.sha256(source + " ".join(cflags).encode() + ca.__version__.encode()).hexdigest()[:20]
    try:
        folder = cache_dir()
        folder.mkdir(parents=True, exist_ok=True)
        lib = folder / f"{name}_{key}.so"
        if not lib.exists():
            with _locked(folder / f"{lib.name}.lock"):  # another process compiling it: wait for its library
                if not lib.exists():
                    _compile(cc, cflags, name, source, lib)
        return lib
    except (OSError, subprocess.CalledProcessError) as exc:
        why = f"{type(exc).__name__}: {exc}"
        if not fatal:
            warnings.warn(f"qpik: {name} not compiled ({why})", stacklevel=2)
            return None
        _native_failed = why
        warnings.warn(f"qpik: native compilation off ({_native_failed})", stacklevel=2)
        return None


@contextlib.contextmanager
def _locked(path: Path):
    """An exclusive lock on the file ``path`` while the block runs (none where ``fcntl`` is missing)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: concurrent processes may compile the same library twice
        yield
        return
    with open(path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


QUIET = 2.0
"""Seconds a compilation runs before it says what it builds."""
TICK = 8.0
"""Seconds between its progress lines after that."""
LARGE = 256_000
"""Bytes of C above which :func:`optimisation` gives ``-O1``."""


def optimisation(size: int) -> str:
    """The optimisation flag for a C source of ``size`` bytes: ``-O2``, or ``-O1`` for a source over :data:`LARGE`
    bytes. The large sources are CasADi's straight-line code of big expressions (the Taylor models of a
    distance kernel), for which gcc's ``-O2`` costs several times the time and memory of ``-O1`` and gives no
    faster code."""
    return "-O1" if size > LARGE else "-O2"


def _compile(cc: str, cflags: Sequence[str], name: str, source: bytes, lib: Path) -> None:
    """Compile ``source`` into ``lib`` (atomically: concurrent readers never see a partial library), saying on stderr
    what it builds when it takes longer than :data:`QUIET` seconds."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp, f"{name}.c")
        src.write_bytes(source)
        partial = lib.with_name(f"{lib.name}.{os.getpid()}.tmp")
        with subprocess.Popen(
            [cc, *cflags, str(src), "-o", str(partial), "-lm"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        ) as job:
            start, wait = time.monotonic(), QUIET
            while True:
                try:
                    _, err = job.communicate(timeout=wait)
                    break
                except subprocess.TimeoutExpired:
                    elapsed = time.monotonic() - start
                    if wait == QUIET:
                        print(f"qpik: compiling {describe(name)} ({name}.c, {len(source) // 1000} kB) with {cc}: "
                              f"once on this machine, cached in {lib.parent}", file=sys.stderr, flush=True)  # fmt: skip
                    else:
                        print(f"qpik: ... still compiling {name} ({elapsed:.0f} s)", file=sys.stderr, flush=True)
                    wait = TICK
        if job.returncode:
            raise subprocess.CalledProcessError(job.returncode, cc, stderr=err)
        if wait != QUIET:
            print(f"qpik: compiled {name} in {time.monotonic() - start:.1f} s", file=sys.stderr, flush=True)
        os.replace(partial, lib)


_WHAT = {
    "pair_": "the Taylor-model bounds of a capsule–obstacle distance (certificate of solve_best)",
    "axes_": "the Taylor-model bounds of the link capsules (certificate of solve_best)",
    "bound_": "the Taylor-model bounds of an objective (certificate of solve_best)",
    "selfmotion_taylor": "the Taylor models of the closed form along δ/ψ (certificate of solve_best)",
    "selfmotion": "the closed form along δ/ψ (solve_best)",
    "objective": "an objective and its gradient",
    "ik_": "the inverse kinematics",
    "plan_states": "the planner's states",
    "qp_": "the controller's QP",
    "qpik_": "qpik's C code",
}


def describe(name: str) -> str:
    """What the generated function ``name`` is, in words, for the progress lines."""
    return next((what for prefix, what in _WHAT.items() if name.startswith(prefix)), "a generated function")


def python_library(
    name: str, source: bytes, signatures: dict[str, Sequence[type]], flags: Sequence[str] = ()
) -> ctypes.PyDLL | None:
    """:func:`shared_library` loaded as a :class:`ctypes.PyDLL` (its calls keep the GIL), each function named in
    ``signatures`` declared with those argument types and an ``int`` result; None where it is not compiled."""
    lib = shared_library(name, source, flags)
    if lib is None:
        return None
    dll = ctypes.PyDLL(str(lib))
    for function, argtypes in signatures.items():
        entry = getattr(dll, function)
        entry.restype, entry.argtypes = ctypes.c_int, list(argtypes)
    return dll


def native_library(*fns: ca.Function) -> Path | None:
    """The shared library holding ``fns`` as machine code (each exported under its ``name()``; the functions
    they call are emitted once), or None.

    None when :func:`compiler` is None or code generation or compilation fails
    (then a warning says why, once, and native code stays off in this process).
    """
    if compiler() is None:
        return None
    name = fns[0].name()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
            for fn in fns:
                gen.add(fn)
            gen.generate(tmp + os.sep)
            return shared_library(name, Path(tmp, f"{name}.c").read_bytes())
    except RuntimeError as exc:  # CasADi's code generation failed
        return _off(exc)


def native(fn: ca.Function) -> ca.Function:
    """``fn`` as machine code (cached shared library), or ``fn`` itself when that is not possible.

    The result computes the same outputs (IEEE arithmetic, no fast-math) and
    has the same inputs and outputs, so callers cannot tell the difference
    except by speed.
    """
    return _load(fn, native_library(fn))


def _load(fn: ca.Function, lib: Path | None) -> ca.Function:
    """``fn`` from ``lib`` (CasADi's external), or ``fn`` itself when there is no library or it fails to load."""
    if lib is None:
        return fn
    try:
        return ca.external(fn.name(), str(lib))
    except RuntimeError as exc:
        _off(exc)
        return fn


def _off(exc: Exception) -> None:
    """Turn native code off in this process because of ``exc``, with a warning (once per failure)."""
    global _native_failed
    _native_failed = f"{type(exc).__name__}: {exc}"
    warnings.warn(f"qpik: native compilation off, using CasADi's virtual machine ({_native_failed})", stacklevel=3)


class Compiled:
    """A CasADi function evaluated through preallocated buffers.

    Args:
        fn: a CasADi ``Function`` with dense inputs and outputs.
        compile: evaluate machine code from :func:`native` rather than CasADi's
            virtual machine (same results).
        library: the shared library of ``fn`` already built by :func:`native_library`
            (then ``compile`` is not consulted).

    Attributes:
        library: the shared library exporting the function as ``fn.name()`` (the C
            calling convention of CasADi's generated code, for C callers such as
            :class:`qpik.analytic.intervals.Assembler`), or None on the virtual machine.
        kernel: the compiled extension's call of that library (:func:`qpik.fastcall.kernel`),
            returning :attr:`outputs` (or None for arguments it does not take), or None
            without the extension.
        arguments, results: the flat input and output buffers (CasADi's column-major order) that
            :meth:`run` reads and writes.

    Calling it with numpy inputs returns *views* of internal output buffers
    shaped like the CasADi outputs (row-major ``(rows, cols)``, squeezed to 1-D
    for columns). The views are overwritten by the next call: copy them if
    they must outlive it.
    """

    def __init__(self, fn: ca.Function, compile: bool = True, library: Path | None = None):
        lib = library if library is not None else native_library(fn) if compile else None
        self.fn = _load(fn, lib)
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
        """A :class:`qpik.fastcall` kernel over this function's buffers (checked inputs, new or caller-owned
        outputs: :func:`qpik.fastcall.kernel`), or None on the virtual machine or without the extension."""
        if self.library is None:
            return None
        from qpik.fastcall import kernel

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


@cache
def entry_point(library: Path, name: str) -> tuple[int, ctypes.CDLL] | None:
    """The address of the generated function ``name`` in the shared library ``library`` and the loaded library
    (the address is valid while it lives), or None when the function's integers are not the 64-bit
    ``casadi_int`` that qpik's C callers (:mod:`qpik.fastcall`, ``intervals.c``, ``grid.c``) pass (the library's
    size query is named after its first function, :func:`native_library`'s file name)."""
    dll = ctypes.CDLL(str(library))
    if getattr(dll, f"{library.stem.rsplit('_', 1)[0]}_casadi_int_size")() != 8:
        return None
    return ctypes.cast(getattr(dll, name), ctypes.c_void_p).value, dll


def call_header() -> bytes:
    """``casadi_call.h``: the types qpik's C code uses to call CasADi-generated C (``casadi_fn``, ``Kernel``), for the
    start of its sources."""
    return Path(__file__).with_name("casadi_call.h").read_bytes()


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
    over ``chunks[1]`` (the last call padded with copies of its first row): one call per
    chunk, the loop over rows in machine code (:class:`Compiled`). Both sizes are compiled
    into one library on first use (``fn`` once in it).

    Args:
        fn: dense inputs (a matrix input is given per row as its entries in CasADi's
            column-major order) and dense column-vector outputs.
        shared: indices of the inputs that are the same for every row (given once, 1-D).
        chunks: rows per call, large then small.
    """

    def __init__(self, fn: ca.Function, shared: Sequence[int] = (), chunks: tuple[int, int] = (32, 4)):
        self.fn, self.shared, self.chunks = fn, tuple(shared), chunks
        self._lock = threading.Lock()

    @cached_property
    def _maps(self) -> dict[int, tuple[Compiled, list[np.ndarray | None], list[np.ndarray]]]:
        """Per size, the compiled map and views (size, nnz) of its per-row input and output buffers."""
        sizes = sorted(set(self.chunks), reverse=True)
        fns = [self.fn.map(f"{self.fn.name()}_rows{size}", "serial", size, list(self.shared), []) for size in sizes]
        lib = native_library(*fns)
        maps = {}
        for size, fn in zip(sizes, fns):
            call = Compiled(fn, compile=False, library=lib)
            # column-major (nnz, size) buffers: one row's entries are contiguous
            ins = [None if k in self.shared else a.reshape(size, -1) for k, a in enumerate(call.arguments)]
            maps[size] = (call, ins, [r.reshape(size, -1) for r in call.results])
        return maps

    def build(self) -> None:
        """Compile the maps now (else on the first call): a solve that starts its clock after this times
        evaluations, never a compile."""
        with self._lock:
            self._maps  # noqa: B018 (the cached property is the build)

    def __call__(self, *args: np.ndarray) -> list[np.ndarray]:
        """Each output as (M, nnz) for per-row inputs (M, nnz_i) (shared inputs: (nnz_i,))."""
        shared = self.shared
        per_row = [(k, np.asarray(a, dtype=float).reshape(len(a), -1)) for k, a in enumerate(args) if k not in shared]
        M = len(per_row[0][1]) if per_row else 1
        outs = [np.empty((M, self.fn.nnz_out(k))) for k in range(self.fn.n_out())]
        big, small = self.chunks
        with self._lock:
            maps = self._maps
        i = 0
        while i < M:
            size = big if M - i > 3 * big // 4 else small
            m = min(size, M - i)
            call, ins, res = maps[size]
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
        return outs
