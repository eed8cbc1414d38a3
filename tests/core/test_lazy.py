"""qpik.core.lazy: ``import qpik``, the ``qpik`` command's parser and a first closed-form call import none of the heavy
dependencies, and every public name of the lazy packages still resolves (each in a fresh interpreter)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

HEAVY = (
    *("scipy.optimize", "scipy.spatial", "mujoco", "mink", "matplotlib"),
    *("qpsolvers", "osqp", "toppra", "dask", "tqdm"),
)
LAZY = ("qpik", "qpik.robots", "qpik.sim")


def _run(code: str) -> dict:
    """The JSON that ``code`` prints last, run in a fresh interpreter with this checkout's qpik."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = {**os.environ, "PYTHONPATH": root}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1])


def _heavy(modules: list[str]) -> list[str]:
    return sorted(m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY))


@pytest.mark.parametrize(
    "code",
    [
        "import qpik",
        "from qpik.cli import build_parser; build_parser()",  # `qpik --help` and every command's parser
        "import qpik; r = qpik.load_robot('iiwa14'); qpik.ik(r, r.fk(r.q_home), 0.2); qpik.CATALOG",
        "from qpik.robots.catalog import CATALOG; from qpik.sim.log import SimLog; "
        "from qpik.geometry.paths import TargetPath",
        "from qpik.cli import main; main(['ik', '-r', 'iiwa14', '--q', '0,0.5,0,-1,0,0.8,0'])",  # `qpik ik`
    ],
)
def test_no_heavy_dependency_is_imported(code: str) -> None:
    modules = _run(f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))")
    assert "qpik" in modules
    assert _heavy(modules) == []


def test_the_public_names_resolve() -> None:
    """Every name in ``__all__`` of a lazy package is the object that its import for type checkers (the ``if
    TYPE_CHECKING:`` block) names, ``dir`` lists it, ``from ... import *`` gives it, and an unknown name is an
    AttributeError naming it."""
    code = f"""
import ast, importlib, json
found = {{}}
for name in {LAZY!r}:
    pkg = importlib.import_module(name)
    tree = ast.parse(open(pkg.__file__, encoding="utf-8").read())
    block = next(n for n in tree.body if isinstance(n, ast.If) and getattr(n.test, "id", "") == "TYPE_CHECKING")
    typed = {{a.name: n.module for n in block.body if isinstance(n, ast.ImportFrom) for a in n.names}}
    found[name] = sorted(typed) == sorted(pkg.__all__)
    star = {{}}
    exec(f"from {{name}} import *", star)
    for attr in pkg.__all__:
        obj = getattr(pkg, attr)
        found[f"{{name}}.{{attr}}"] = [
            obj is getattr(importlib.import_module(typed.get(attr, name)), attr),
            attr in dir(pkg),
            star.get(attr) is obj,
        ]
    try:
        getattr(pkg, "no_such_name")
        found[name + ".no_such_name"] = "resolved"
    except AttributeError as exc:
        found[name + ".no_such_name"] = str(exc)
print(json.dumps(found))
"""
    found = _run(code)
    for name in LAZY:
        assert found.pop(name) is True  # the names for type checkers are the public ones
        assert found.pop(f"{name}.no_such_name") == f"module {name!r} has no attribute 'no_such_name'"
    assert {"qpik.ik", "qpik.Controller", "qpik.CATALOG", "qpik.robots.load_robot", "qpik.sim.simulate"} <= set(found)
    assert {k: v for k, v in found.items() if v != [True, True, True]} == {}
