"""qpik's own C code: the files of :data:`SRC`, compiled at first use and loaded by :func:`load_source`.

Every hand-written C file of qpik is in ``qpik/native/src``. What one file uses of another is declared in a
header there and joined by ``#include``: ``casadi_call.h`` (the types of CasADi's generated C and the
:class:`~qpik.native.compiled.Kernel` struct), ``circle.h`` (π and the wrap to (−π, π]), ``intervals.h`` (the gap
classification of ``intervals.c``), ``polyroots.h`` (the root finder of ``polyroots.c``) and ``internal.h`` (what a
library's files share without exporting it). A library is one or more of these files compiled together by
:func:`qpik.native.build.shared_library` (its progress lines, its lock file, its cache in
:func:`~qpik.native.build.cache_dir`), keyed by the text of the files and of every header they include
(:func:`fingerprint`), their defines and their flags. Without a compiler, or with ``QPIK_NATIVE=0``,
:func:`load_source` gives None and every caller keeps its path in Python (numpy or CasADi).
"""

from __future__ import annotations

import ctypes
import importlib.util
import platform
import re
import sysconfig
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Literal

import numpy as np

from qpik.native.build import compiler, shared_library

SRC = Path(__file__).with_name("src")
"""The folder of qpik's C files and headers."""

Kind = Literal["cdll", "pydll", "extension"]
"""How a library is loaded: ``cdll`` (:class:`ctypes.CDLL`: its calls release the interpreter's lock), ``pydll``
(:class:`ctypes.PyDLL`: its calls keep it, for C that works on buffers one thread owns at a time) or ``extension``
(a CPython extension module, compiled against this Python's and numpy's headers)."""

Signature = tuple[type | None, Sequence[type]]
"""A C function's ctypes result type (None for ``void``) and argument types."""

_INCLUDE = re.compile(rb'^[ \t]*#[ \t]*include[ \t]*"([^"]+)"', re.MULTILINE)


def headers(parts: Sequence[str], folder: Path = SRC) -> list[str]:
    """The names of the headers that the C files ``parts`` of ``folder`` include, directly or through another
    header of ``folder`` (``#include "name.h"``), sorted."""
    seen: set[str] = set()
    todo = list(parts)
    while todo:
        for name in _INCLUDE.findall((folder / todo.pop()).read_bytes()):
            header = name.decode()
            if header not in seen:
                seen.add(header)
                todo.append(header)
    return sorted(seen)


def fingerprint(parts: Sequence[str], folder: Path = SRC) -> bytes:
    """What identifies the library of the C files ``parts`` of ``folder``: the name and text of each, then of each
    header they include (:func:`headers`). A change in any of them is a new library."""
    return b"".join(
        name.encode() + b"\0" + (folder / name).read_bytes() + b"\0" for name in [*parts, *headers(parts, folder)]
    )


def load_source(
    name: str,
    kind: Kind,
    parts: Sequence[str],
    *,
    defines: Mapping[str, float | int | str] | None = None,
    flags: Sequence[str] = (),
    signatures: Mapping[str, Signature] | None = None,
    folder: Path = SRC,
) -> ctypes.CDLL | ModuleType | None:
    """The library ``name`` of the C files ``parts`` (names in ``folder``), compiled at first use (cached on disk)
    and loaded as ``kind`` says; None without a compiler, with ``QPIK_NATIVE=0``, or where it does not compile or
    load (a warning says why).

    Args:
        name: the library's name (for an extension, its module's: the C files define ``PyInit_<name>``).
        kind: how it is loaded (:data:`Kind`).
        parts: the C files compiled together into it.
        defines: macros given on the compiler's command line (``-DNAME=value``; a float as its ``repr``).
        flags: other compiler flags (besides :data:`qpik.native.build.CFLAGS`).
        signatures: for ``cdll`` and ``pydll``, each exported function's :data:`Signature`, set on the loaded
            library.
        folder: where ``parts`` and their headers are (:data:`SRC`; another folder in the tests).
    """
    if compiler() is None:
        return None
    cflags = [*flags, *(f"-D{key}={value!r}" if isinstance(value, float) else f"-D{key}={value}"
                        for key, value in (defines or {}).items())]  # fmt: skip
    source = fingerprint(parts, folder)
    if kind == "extension":
        include = sysconfig.get_paths()["include"]
        if not Path(include, "Python.h").exists():
            warnings.warn(f"qpik: no Python headers in {include}: {name} is not compiled", stacklevel=2)
            return None
        source += f"CPython {platform.python_version()}, numpy {np.__version__}".encode()
        cflags += ["-I", include, "-I", np.get_include()]
    files = [folder / part for part in parts]
    lib = shared_library(name, source, cflags, fatal=kind != "extension", files=files)
    if lib is None:
        return None
    if kind == "extension":
        return _import(name, lib)
    dll = (ctypes.PyDLL if kind == "pydll" else ctypes.CDLL)(str(lib))
    for function, (restype, argtypes) in (signatures or {}).items():
        entry = getattr(dll, function)
        entry.restype, entry.argtypes = restype, list(argtypes)
    return dll


def _import(name: str, lib: Path) -> ModuleType | None:
    """The extension module ``name`` of the shared library ``lib``, or None (with a warning) where it does not load."""
    try:
        spec = importlib.util.spec_from_file_location(name, lib)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except ImportError as exc:
        warnings.warn(f"qpik: {name} does not load ({exc})", stacklevel=3)
        return None
    return module
