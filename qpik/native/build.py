"""Building and loading compiled code: the C compiler, the on-disk cache, shared libraries.

:func:`native` has CasADi generate C for a function, compiles it once with the system C compiler (``cc``)
and caches the shared library on disk, keyed by a hash of the source. CasADi's SX virtual machine costs a
few ns per instruction; machine code is several times faster, which matters for the large functions (IK of
all branches, distances of all capsule/obstacle pairs, mapped sweeps). Where no compiler works, or with
``QPIK_NATIVE=0``, the virtual machine is used: same results, slower. qpik's own C (:mod:`qpik.native.sources`:
its libraries and CPython extensions) is built and cached the same way (:func:`shared_library`).
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
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path

import casadi as ca

from qpik.core.errors import InputError
from qpik.core.progress import QUIET, TICK

CFLAGS = ("-shared", "-fPIC")
"""Flags of every library."""
INLINE_FLAGS = ("-fno-semantic-interposition",)
"""Flags of a library whose caller asks for them (``inline``), where the compiler accepts them (:func:`accepts`).
``-fno-semantic-interposition`` lets it inline the small helpers that CasADi's generated C defines with external
linkage (``casadi_fmin``, ``casadi_fabs``, ``casadi_sq``, ...), which a position-independent library otherwise calls
through its procedure linkage table at every use: a Taylor model's code is mostly such calls. It changes no result
(no arithmetic is reordered or contracted by it), but at ``-O2`` it multiplies the compile time of a map of many
rows, so only maps called often enough to repay it ask for it (the 1-D search's)."""
_native_failed: str | None = None  # why native compilation is off in this process


def cache_dir() -> Path:
    """Where compiled functions are kept: ``$QPIK_CACHE``, else ``$XDG_CACHE_HOME/qpik``, else ``~/.cache/qpik``."""
    if os.environ.get("QPIK_CACHE"):
        return Path(os.environ["QPIK_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "qpik"


def keep(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` in the cache (its folder made if missing) atomically: a concurrent reader sees the
    whole file or none. Raises OSError where it cannot be written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


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


@cache
def accepts(cc: str, flag: str) -> bool:
    """Whether the compiler ``cc`` accepts ``flag``: it compiles an empty C unit with it (once per process)."""
    try:
        subprocess.run([cc, flag, "-x", "c", "-c", "-o", os.devnull, "-"], input=b"", capture_output=True,
                       check=True, timeout=60)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return False
    return True


def shared_library(
    name: str,
    source: bytes,
    flags: Sequence[str] = (),
    fatal: bool = True,
    files: Sequence[Path] = (),
    large: int | None = None,
    inline: bool = False,
) -> Path | None:
    """C ``source`` compiled once into a shared library cached in :func:`cache_dir`, or None.

    With ``files``, those C files are compiled together instead (:func:`qpik.native.sources.load_source`), and
    ``source`` is only what identifies them: their text and that of every header they include. The library is keyed by a
    hash of the source, the flags (:func:`optimisation` for the source's size and ``large``, :data:`CFLAGS`, with
    ``inline`` the :data:`INLINE_FLAGS` the compiler accepts, and ``flags``, e.g. include folders) and CasADi's version.
    Processes that need the same library at once compile it once: the others wait on a lock file beside it. A
    compilation that takes longer than :data:`QUIET` seconds says so on stderr, and again every :data:`TICK` seconds.
    None when :func:`compiler` is None or compilation fails: then a warning says why, once, and with ``fatal`` native
    code stays off in this process (without it only this library is missing).
    """
    global _native_failed
    cc = compiler()
    if cc is None:
        return None
    extra = (f for f in INLINE_FLAGS if inline and accepts(cc, f))
    cflags = (optimisation(len(source), large), *CFLAGS, *extra, *flags)
    key = hashlib.sha256(source + " ".join(cflags).encode() + ca.__version__.encode()).hexdigest()[:20]
    try:
        folder = cache_dir()
        folder.mkdir(parents=True, exist_ok=True)
        lib = folder / f"{name}_{key}.so"
        if not lib.exists():
            with _locked(folder / f"{lib.name}.lock"):  # another process compiling it: wait for its library
                if not lib.exists():
                    _compile(cc, cflags, name, source, lib, files)
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


LARGE = 256_000
"""Bytes of C above which :func:`optimisation` gives ``-O1``."""


LEVELS = ("-O0", "-O1", "-O2", "-O3", "-Os")
"""The values ``$QPIK_OPTIMISE`` may take."""


def optimisation(size: int, large: int | None = None) -> str:
    """The optimisation flag for a C source of ``size`` bytes: ``-O2``, or ``-O1`` for a source over ``large``
    bytes (default :data:`LARGE`). The large sources are CasADi's straight-line code of big expressions (the
    Taylor models of a distance kernel), for which gcc's ``-O2`` costs several times the time and memory of
    ``-O1`` and gives no faster code; a caller whose code runs often enough to repay ``-O2`` over a larger
    size gives its own ``large`` (the controller's QP, :data:`qpik.control.qp.LARGE`).

    ``$QPIK_OPTIMISE`` (one of :data:`LEVELS`) sets the flag of every source instead: ``-O0`` and ``-O1`` compile
    faster than ``-O2`` and give slower code (the test suite uses ``-O0``). The arithmetic is the same IEEE
    arithmetic at every level (no fast-math), so the results are too. Raises :class:`~qpik.core.errors.InputError`
    naming the variable for another value."""
    forced = os.environ.get("QPIK_OPTIMISE")
    if forced:
        if forced not in LEVELS:
            raise InputError(f"QPIK_OPTIMISE: {forced!r} is not one of {', '.join(LEVELS)}")
        return forced
    return "-O1" if size > (LARGE if large is None else large) else "-O2"


def _compile(cc: str, cflags: Sequence[str], name: str, source: bytes, lib: Path, files: Sequence[Path]) -> None:
    """Compile ``files``, or else ``source``, into ``lib`` (atomically: concurrent readers never see a partial
    library), saying on stderr what it builds when it takes longer than :data:`QUIET` seconds."""
    with tempfile.TemporaryDirectory() as tmp:
        if not files:
            files = (Path(tmp, f"{name}.c"),)
            files[0].write_bytes(source)
        partial = lib.with_name(f"{lib.name}.{os.getpid()}.tmp")
        with subprocess.Popen(
            [cc, *cflags, *map(str, files), "-o", str(partial), "-lm"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
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


PRELUDE = b"""#include <math.h>
static inline double qpik_fmin(double x, double y) { return y < x ? y : (x != x ? y : x); }
static inline double qpik_fmax(double x, double y) { return y > x ? y : (x != x ? y : x); }
#define fmin qpik_fmin
#define fmax qpik_fmax
"""
"""C put before CasADi's generated code (:func:`native_library`): its ``casadi_fmin`` and ``casadi_fmax`` call C99's
``fmin`` and ``fmax``, which compilers leave as calls into the maths library (inline only under fast-math), a
Taylor model's most frequent operations. These inline versions give glibc's results for every argument: the other
argument where one is NaN, the first of two equal ones (so −0 or +0 as given, which C99 leaves open)."""


def native_library(*fns: ca.Function, large: int | None = None, inline: bool = False) -> Path | None:
    """The shared library holding ``fns`` as machine code (each exported under its ``name()``; the functions
    they call are emitted once; :data:`PRELUDE` first), or None. ``large``: as in :func:`optimisation`; ``inline``:
    with :data:`INLINE_FLAGS`.

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
            return shared_library(name, PRELUDE + Path(tmp, f"{name}.c").read_bytes(), large=large, inline=inline)
    except RuntimeError as exc:  # CasADi's code generation failed
        return _off(exc)


def concurrently(*builds: Callable[[], object]) -> None:
    """Run ``builds`` (functions that compile, e.g. :meth:`qpik.native.compiled.RowMap.build`) on the worker threads of
    this process, one per core: while one waits for its compiler, another traces or compiles; CasADi's own calls
    keep the interpreter's lock, so they run one at a time. A build that is the method of an object already
    ``built`` (:attr:`qpik.native.compiled.RowMap.built`) is left out. Called from a worker thread, or with one build
    left, the builds run in the caller's thread. The first exception is raised once all have finished."""
    builds = tuple(b for b in builds if not getattr(getattr(b, "__self__", None), "built", False))
    if len(builds) < 2 or getattr(_WORKER, "inside", False):
        for build in builds:
            build()
        return
    futures = [_pool().submit(_as_worker, build) for build in builds]
    for future in futures:
        future.result()


_WORKER = threading.local()


def _as_worker(build: Callable[[], object]) -> object:
    _WORKER.inside = True
    return build()


@cache
def _pool():
    from concurrent.futures import ThreadPoolExecutor

    return ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1), thread_name_prefix="qpik-build")


def native(fn: ca.Function) -> ca.Function:
    """``fn`` as machine code (cached shared library), or ``fn`` itself when that is not possible.

    The result computes the same outputs (IEEE arithmetic, no fast-math) and
    has the same inputs and outputs, so callers cannot tell the difference
    except by speed.
    """
    return load(fn, native_library(fn))


def load(fn: ca.Function, lib: Path | None) -> ca.Function:
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


@cache
def entry_point(library: Path, name: str) -> tuple[int, ctypes.CDLL] | None:
    """The address of the generated function ``name`` in the shared library ``library`` and the loaded library
    (the address is valid while it lives), or None when the function's integers are not the 64-bit
    ``casadi_int`` that qpik's C callers (``casadi_call.h`` in :data:`qpik.native.sources.SRC`) pass (the library's
    size query is named after its first function, :func:`native_library`'s file name)."""
    dll = ctypes.CDLL(str(library))
    if getattr(dll, f"{library.stem.rsplit('_', 1)[0]}_casadi_int_size")() != 8:
        return None
    return ctypes.cast(getattr(dll, name), ctypes.c_void_p).value, dll
