"""Derived CasADi functions kept on disk, so that a process loads what another one derived.

A Taylor-model or interval extension (:mod:`qpik.algebra.enclosure`) of a closed form is a pure function of that
closed form's expression graph, and it takes the interpreter seconds to derive: every test worker, script or
``qpik`` command that certifies a result would derive the same function again. :func:`derived` derives it once per
machine and keeps it (CasADi's own serialization) in :func:`qpik.native.build.cache_dir`, keyed by

- the serialization of the function it is derived from (its whole expression graph),
- what the derivation is told besides (``how``: its options, as text),
- the source text of the modules that derive it, and CasADi's version,

so a changed closed form, option or derivation gives another key. A stored file that cannot be read or written is
derived again (the cache is an accelerator, never a source of answers of its own).
"""

from __future__ import annotations

import contextlib
import hashlib
import inspect
from collections.abc import Callable, Sequence
from functools import cache
from types import ModuleType

import casadi as ca

from qpik.native.build import cache_dir, keep

FOLDER = "derived"
"""The sub-folder of the cache where derived functions are kept."""


def derived(fn: ca.Function, how: str, derive: Callable[[], ca.Function], modules: Sequence[ModuleType]) -> ca.Function:
    """``derive()``, the function derived from ``fn`` by the code of ``modules`` as ``how`` says (text), or its copy
    stored on this machine by an earlier call with the same ``fn``, ``how`` and ``modules`` source.

    The copy is the same function: CasADi's serialization keeps every operation and constant bit for bit.
    """
    try:
        digest = hashlib.sha256(fn.serialize().encode())
    except RuntimeError:  # a function CasADi cannot serialize: derived in this process only
        return derive()
    digest.update(how.encode())
    for module in modules:
        digest.update(_source_digest(module))
    digest.update(ca.__version__.encode())
    path = cache_dir() / FOLDER / f"{fn.name()}_{digest.hexdigest()[:24]}.casadi"
    if path.exists():
        try:
            return ca.Function.deserialize(path.read_text())
        except (OSError, RuntimeError, UnicodeDecodeError):
            pass
    result = derive()
    with contextlib.suppress(OSError, RuntimeError):
        keep(path, result.serialize().encode())
    return result


@cache
def _source_digest(module: ModuleType) -> bytes:
    """The SHA-256 of ``module``'s source text."""
    return hashlib.sha256(inspect.getsource(module).encode()).digest()
