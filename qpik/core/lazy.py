"""Lazy public names of a package (PEP 562): a name's module is imported when the name is first used.

A package's ``__init__`` lists where each public name lives and keeps the imports for type checkers::

    if TYPE_CHECKING:
        from qpik.robots.catalog import CATALOG

    __getattr__, __dir__ = exports(__name__, {"qpik.robots.catalog": ("CATALOG",)})

so that ``import qpik`` (and every ``qpik`` command) imports only what it uses: the heavy dependencies
(SciPy's optimisers, MuJoCo, mink, Matplotlib, the QP solvers) come with the first name that needs them.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping, Sequence


def exports(
    package: str, where: Mapping[str, Sequence[str]]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package`` whose public names are ``where``: per module (a full
    dotted name), the names it defines. A name is imported on first use and then kept in the package's namespace."""
    home = {name: module for module, names in where.items() for name in names}

    def getattr_(name: str) -> object:
        module = home.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)  # later uses skip this function
        return value

    def dir_() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(home))

    return getattr_, dir_
