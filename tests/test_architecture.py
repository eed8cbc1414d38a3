"""The house rules, measured on the code: no import circle, no cache keyed by ``id()``, no write into another
object's ``__dict__``, no read of another object's private attribute (one documented exception), no module over
450 lines, no offset arithmetic on flat buffers."""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "qpik"
MODULES = sorted(PACKAGE.rglob("*.py"))

PRIVATE_READS_ALLOWED = {
    # OSQP's extension object: its public wrappers cost more per step than OSQP's own work (the README's
    # "OSQP" note); pyproject.toml pins the one minor version whose object this is
    ("control/solvers/osqp.py", "self._solver._solver"),
}


@cache
def parsed() -> tuple[tuple[str, ast.Module], ...]:
    return tuple((path.relative_to(PACKAGE).as_posix(), ast.parse(path.read_text(), str(path))) for path in MODULES)


def trees():
    yield from parsed()


def test_the_rules_see_every_module():
    assert len(MODULES) > 100 and all(name for name, _ in trees())


def test_no_id_keyed_cache():
    """What is built for an object lives on that object (``robot.cache``, ``Traced.evaluators``) or is keyed
    by the object itself: ``id()`` is reused once the object dies, so a cache keyed by it can answer for
    another object, and it never frees anything."""
    found = [
        f"{name}:{node.lineno}"
        for name, tree in trees()
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "id"
    ]
    assert not found, found


def test_no_write_into_another_objects_dict():
    found = [
        f"{name}:{node.lineno}: {ast.unparse(node)}"
        for name, tree in trees()
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and node.attr == "__dict__"
        and not (isinstance(node.value, ast.Name) and node.value.id == "self")
    ]
    assert not found, found


def test_no_read_of_another_objects_private_attribute():
    """``a._x`` only for ``a`` = self or cls (a class's own); every exception is listed with its reason."""
    found = {
        (name, ast.unparse(node))
        for name, tree in trees()
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and node.attr.startswith("_")
        and not node.attr.startswith("__")
        and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
    }
    assert not found - PRIVATE_READS_ALLOWED, sorted(found - PRIVATE_READS_ALLOWED)
    assert found >= PRIVATE_READS_ALLOWED, "an exception that no longer exists: drop it from the list"


def imports_of(name: str, tree: ast.Module) -> set[str]:
    """The qpik modules ``name`` imports when it runs: at module level or inside a function (a lazy import is
    still an import), not under ``if TYPE_CHECKING:`` (annotations only)."""
    typing_only = {
        id(x) for n in ast.walk(tree) if isinstance(n, ast.If) and "TYPE_CHECKING" in ast.unparse(n.test)
        for x in ast.walk(n)
    }  # fmt: skip
    modules = {m for m, _ in trees()}
    out = set()
    for node in ast.walk(tree):
        if (
            id(node) in typing_only
            or not isinstance(node, ast.ImportFrom)
            or not (node.module or "").startswith("qpik")
        ):
            continue
        for alias in node.names:
            for target in (f"{node.module}.{alias.name}", node.module):
                path = target[5:].replace(".", "/") if target != "qpik" else ""
                found = next((p for p in (f"{path}.py", f"{path}/__init__.py".lstrip("/")) if p in modules), None)
                if found:
                    out.add(found)
                    break
    return out - {name}


def test_no_import_circle():
    """Tarjan's strongly connected components of the runtime import graph: every component is one module.
    A package's ``__init__`` that re-exports its modules counts as importing them."""
    graph = {name: imports_of(name, tree) for name, tree in trees()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    assert sum(len(g) for g in graph.values()) > 300  # the graph was read
    assert not circles, circles


MAX_PARAMETERS = 8


def test_no_function_takes_more_than_eight_parameters():
    """Parameters that travel together are one value (a :class:`~qpik.scene.Scene`, an options dataclass), so no
    function of qpik takes more than :data:`MAX_PARAMETERS` (``self`` and ``cls`` not counted)."""
    found = []
    for name, tree in trees():
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                a = node.args
                names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs if x.arg not in ("self", "cls")]
                if len(names) > MAX_PARAMETERS:
                    found.append(f"{name}:{node.lineno} {node.name} {len(names)}")
    assert not found, found


MATHS = ("planning", "nlp", "analytic", "control", "core", "algebra", "geometry")
"""The maths stack: what it computes never depends on how it is shown or run."""
APPLICATIONS = ("qpik.sim", "qpik.viewer", "qpik.plots", "qpik.render", "qpik.cli")


def qpik_imports(tree: ast.Module) -> set[str]:
    """Every qpik module ``tree`` names in an import statement: at module level, inside functions (lazy) and under
    ``if TYPE_CHECKING:``; ``from qpik import x`` counts as ``qpik.x``."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("qpik"))
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("qpik"):
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
    return out


def test_the_maths_stack_imports_no_application():
    found = sorted(
        f"{name}: {target}"
        for name, tree in trees()
        if name.split("/")[0] in MATHS
        for target in qpik_imports(tree)
        if any(target == app or target.startswith(app + ".") for app in APPLICATIONS)
    )
    assert not found, found


def test_core_imports_only_core():
    """``qpik.core`` is the bottom layer: errors, validation, layouts, the lazy loader, the stopwatch."""
    found = sorted(
        f"{name}: {target}"
        for name, tree in trees()
        if name.startswith("core/")
        for target in qpik_imports(tree)
        if not (target == "qpik.core" or target.startswith("qpik.core."))
    )
    assert not found, found


def test_the_import_checks_see_a_lazy_import():
    tree = ast.parse("def f():\n    from qpik.sim.log import x\n    import qpik.viewer\n")
    assert {"qpik.sim.log", "qpik.sim.log.x", "qpik.viewer"} <= qpik_imports(tree)


MAX_LINES = 450


def test_no_module_is_longer_than_450_lines():
    """Short modules, one concept each, named for what they hold: no module of qpik is longer than
    :data:`MAX_LINES` lines."""
    lines = {path.relative_to(PACKAGE).as_posix(): len(path.read_text().splitlines()) for path in MODULES}
    assert len(lines) > 100
    found = sorted(f"{name}: {n}" for name, n in lines.items() if n > MAX_LINES)
    assert not found, found


OFFSET_SLICE = re.compile(r"\[\s*([A-Za-z_][\w.]*)\s*:\s*\1\s*\+")
"""``buffer[start : start + size]``: a block read at an offset computed by hand."""
OFFSET_STEP = re.compile(r"\b(start|offset|pos)\s*\+=\s*(size\b|PARAMS\[|len\()")
"""An offset advanced by hand over the records of a flat buffer."""
CHUNKED = {
    # a batch walked in chunks of a compiled call's fixed size (rows of one array, not blocks of a record)
    "analytic/solver.py",
    "native/compiled.py",
    "planning/dp.py",
    # MuJoCo's own mesh arrays, read with the addresses and counts its model gives (mesh_vertadr, mesh_vertnum)
    "viewer/geometry.py",
    "robots/link_capsules.py",
}


def test_no_offset_arithmetic_on_flat_buffers():
    """Flat buffers are read through :class:`qpik.core.layout.Layout` by name: no module slices a buffer at an
    offset it computes (``x[a : a + k]``) or advances one by hand, except the batch loops and MuJoCo arrays of
    :data:`CHUNKED`."""
    found = []
    for path in MODULES:
        name = path.relative_to(PACKAGE).as_posix()
        if name == "core/layout.py" or name in CHUNKED:
            continue
        for k, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#", 1)[0]
            if OFFSET_SLICE.search(code) or OFFSET_STEP.search(code):
                found.append(f"{name}:{k}: {line.strip()}")
    assert not found, found
    assert any(OFFSET_SLICE.search(line) for line in (PACKAGE / "analytic/solver.py").read_text().splitlines())
