"""qpik's own C (qpik.native.sources): one folder, headers followed into the cache key, every library compiled and
loaded by the one loader, and nothing loaded without a compiler."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import qpik
from qpik.analytic import arm_sets, intervals, polyroots
from qpik.control.solvers import osqp
from qpik.native import fastcall
from qpik.native.build import compiler
from qpik.native.sources import SRC, fingerprint, headers
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


HEADER_CHANGE = """
import sys
from pathlib import Path
from qpik.analytic import intervals
from qpik.native.sources import load_source
folder, cache = Path(sys.argv[1]), Path(sys.argv[2])
parts, defines = intervals.INTERVALS["parts"], intervals.INTERVALS["defines"]
first = load_source("qpik_test_intervals", "cdll", parts, defines=defines, folder=folder)
again = load_source("qpik_test_intervals", "cdll", parts, defines=defines, folder=folder)
assert first is not None and again._name == first._name  # cached: the same library file
with open(folder / "circle.h", "a") as header:
    header.write("/* changed */\\n")
changed = load_source("qpik_test_intervals", "cdll", parts, defines=defines, folder=folder)
assert changed is not None and changed._name != first._name
assert len(list(cache.glob("qpik_test_intervals_*.so"))) == 2
"""
"""A copy of ``intervals.c`` built twice, in an interpreter of its own (its exported names must not meet the
test process's own libraries)."""


@needs_compiler
def test_a_header_change_is_a_new_library(tmp_path):
    folder = tmp_path / "src"
    shutil.copytree(SRC, folder)
    env = {**os.environ, "QPIK_CACHE": str(tmp_path / "cache")}
    run = subprocess.run([sys.executable, "-c", HEADER_CHANGE, str(folder), str(tmp_path / "cache")], env=env,
                         capture_output=True, text=True, timeout=600)  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]


EVERY_SOURCE = """
import sys
sys.path.insert(0, sys.argv[1])
from test_sources import LOADERS, SRC
from qpik.native import sources
compiled = []
real = sources.shared_library
def spy(name, source, flags=(), fatal=True, files=()):
    compiled.extend(files)
    return real(name, source, flags, fatal, files)
sources.shared_library = spy
missing = [what for what, loader in LOADERS.items() if loader.__wrapped__() is None]
assert not missing, missing
assert {p.name for p in compiled} == {p.name for p in SRC.glob("*.c")}, sorted(p.name for p in compiled)
"""
"""Every loader run uncached, spying on what it compiles (in an interpreter of its own: :data:`LOADERS` loaded a
second time into the test process would initialise again the libraries its other tests are using)."""


@needs_compiler
def test_every_source_compiles_and_loads():
    run = subprocess.run([sys.executable, "-c", EVERY_SOURCE, str(Path(__file__).parent)], capture_output=True,
                         text=True, timeout=600)  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]


def test_without_a_compiler_nothing_is_compiled(monkeypatch, tmp_path):
    monkeypatch.setenv("QPIK_NATIVE", "0")
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path))
    for what, loader in LOADERS.items():
        assert loader.__wrapped__() is None, what
    assert not any(tmp_path.iterdir())
