"""What a user installs: the wheel built from this checkout holds every module, C source and problem file
that qpik reads at run time, and the package list of pyproject.toml names every package of qpik/."""

from __future__ import annotations

import subprocess
import sys
import tomllib
import zipfile
from fnmatch import fnmatch
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SETUPTOOLS = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def source_packages() -> set[str]:
    """Every folder of qpik/ that is a package, as a dotted name."""
    return {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "qpik").rglob("__init__.py")}


def test_the_package_list_is_every_package_of_the_source_tree():
    listed = set(SETUPTOOLS["packages"])
    assert listed - {"qpik.problem_files"} == source_packages()
    assert SETUPTOOLS["package-dir"] == {"qpik.problem_files": "problems"}


def test_every_c_source_is_package_data():
    """The C sources and headers compiled at first use (qpik.native.sources) match a package-data glob."""
    globs = SETUPTOOLS["package-data"]["qpik"]
    sources = [p.relative_to(ROOT / "qpik").as_posix() for p in (ROOT / "qpik").rglob("*") if p.suffix in (".c", ".h")]
    assert sources
    for source in sources:
        assert any(fnmatch(source, g) and source.count("/") == g.count("/") for g in globs), source


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> zipfile.ZipFile:
    out = tmp_path_factory.mktemp("dist")
    cmd = [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--wheel-dir", str(out), str(ROOT)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0 and "Could not find a version that satisfies" in done.stderr:
        pytest.skip("no package index: the wheel's build requirements cannot be installed")
    assert done.returncode == 0, done.stderr
    (path,) = out.glob("qpik-*.whl")
    return zipfile.ZipFile(path)


def test_the_wheel_holds_every_module_source_and_problem_file(wheel):
    names = set(wheel.namelist())
    files = [p.relative_to(ROOT).as_posix() for p in [*(ROOT / "qpik").rglob("*"), *(ROOT / "problems").glob("*")]]
    wanted = {
        "qpik/problem_files/" + f.removeprefix("problems/") if f.startswith("problems/") else f
        for f in files
        if f.endswith((".py", ".c", ".h", ".toml")) and "__pycache__" not in f
    }
    assert any(n.startswith("qpik/problem_files/") and n.endswith(".toml") for n in wanted)
    assert wanted <= names, sorted(wanted - names)
    assert not any(n.startswith(("tests/", "problems/", "examples/")) for n in names)
