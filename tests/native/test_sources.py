"""qpik's own C (qpik.native.sources): one folder, headers followed into the cache key, every library compiled and
loaded by the one loader, and nothing loaded without a compiler."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import qpik
from qpik.analytic import arm_sets, intervals, polyroots
from qpik.control.solvers import osqp
from qpik.native import fastcall, sources
from qpik.native.build import compiler
from qpik.native.sources import SRC, fingerprint, headers, load_source
from qpik.nlp import levelset
from qpik.planning import dp, grid

LOADERS = {
    "intervals": intervals._library,
    "polyroots": polyroots._library,
    "delta sets": arm_sets._delta_library,
    "psi sets": arm_sets._psi_library,
    "grid": grid._library,
    "dp": dp._library,
    "levelset": levelset._library,
    "polish": osqp._compiled_polish,
    "fastcall": fastcall.extension,
}
"""Every caller's loader (each cached: ``__wrapped__`` is the uncached function)."""

needs_compiler = pytest.mark.skipif(compiler() is None, reason="no C compiler, or QPIK_NATIVE=0")


def test_every_c_file_of_qpik_is_in_the_source_folder():
    package = Path(qpik.__file__).parent
    files = [p for p in package.rglob("*") if p.suffix in (".c", ".h")]
    assert files
    assert all(p.parent == SRC for p in files), [str(p) for p in files if p.parent != SRC]


def test_headers_are_followed_through_other_headers():
    assert headers(["offset_shoulder_intervals.c"]) == [
        "casadi_call.h", "circle.h", "internal.h", "intervals.h", "polyroots.h"
    ]  # fmt: skip
    assert headers(["dp.c"]) == []


def test_a_header_change_changes_the_fingerprint(tmp_path):
    folder = tmp_path / "src"
    shutil.copytree(SRC, folder)
    before = fingerprint(["srs_intervals.c", "intervals.c"], folder)
    assert before == fingerprint(["srs_intervals.c", "intervals.c"], SRC)
    with open(folder / "casadi_call.h", "a") as header:  # included by intervals.h, not by the C files themselves
        header.write("/* changed */\n")
    assert fingerprint(["srs_intervals.c", "intervals.c"], folder) != before
    assert fingerprint(["dp.c"], folder) == fingerprint(["dp.c"], SRC)


@needs_compiler
def test_a_header_change_is_a_new_library(tmp_path, monkeypatch):
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "src"
    shutil.copytree(SRC, folder)
    parts, defines = intervals.INTERVALS["parts"], intervals.INTERVALS["defines"]
    first = load_source("qpik_test_intervals", "cdll", parts, defines=defines, folder=folder)
    again = load_source("qpik_test_intervals", "cdll", parts, defines=defines, folder=folder)
    assert first is not None and again._name == first._name  # cached: the same library file
    with open(folder / "circle.h", "a") as header:
        header.write("/* changed */\n")
    changed = load_source("qpik_test_intervals", "cdll", parts, defines=defines, folder=folder)
    assert changed is not None and changed._name != first._name
    assert len(list((tmp_path / "cache").glob("qpik_test_intervals_*.so"))) == 2


@needs_compiler
def test_every_source_compiles_and_loads(monkeypatch):
    compiled: list[Path] = []
    real = sources.shared_library

    def spy(name, source, flags=(), fatal=True, files=()):
        compiled.extend(files)
        return real(name, source, flags, fatal, files)

    monkeypatch.setattr(sources, "shared_library", spy)
    for what, loader in LOADERS.items():
        assert loader.__wrapped__() is not None, what
    assert {p.name for p in compiled} == {p.name for p in SRC.glob("*.c")}


def test_without_a_compiler_nothing_is_compiled(monkeypatch, tmp_path):
    monkeypatch.setenv("QPIK_NATIVE", "0")
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path))
    for what, loader in LOADERS.items():
        assert loader.__wrapped__() is None, what
    assert not any(tmp_path.iterdir())
