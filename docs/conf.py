"""Sphinx configuration of qpik's documentation.

Build (warnings as errors, the way CI does)::

    pip install -e ".[docs]"
    sphinx-build -W --keep-going -b html docs OUT

The API pages are autodoc of the real modules (nothing is mocked: building imports qpik, which needs
its run-time dependencies but compiles nothing). The guide pages include the README's sections: each
``## `` heading of README.md follows a ``<!-- docs:NAME -->`` marker, and docs/guide/NAME.md includes the
text from there to the next marker, so that the text lives in one place (tests/test_readme.py checks the
markers and pages).
"""

from __future__ import annotations

import importlib
import sys
import warnings
from pathlib import Path

from sphinx.ext.napoleon import Config, GoogleDocstring

sys.dont_write_bytecode = True  # building the docs writes nothing outside its output folder
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import qpik  # noqa: E402

# sphinx-autodoc-typehints 3.6 (the last for Python 3.11) calls an API that Sphinx 10 removes: not ours to fix
warnings.filterwarnings("ignore", message=".*set_application.* is deprecated", module="sphinx_autodoc_typehints")

project = "qpik"
author = "qpik's authors"
release = version = qpik.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx_autodoc_typehints",  # type hints into the parameter lists, ``if TYPE_CHECKING:`` imports resolved
    "myst_parser",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build"]
html_theme = "furo"
html_title = f"qpik {release}"

autodoc_default_options = {"show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_preserve_defaults = True
typehints_use_rtype = False

# the names ``import qpik`` gives, linked where they are documented (api/core.rst)
rst_prolog = ".. |qpik names| replace:: " + ", ".join(f":py:obj:`~qpik.{name}`" for name in sorted(qpik.__all__))

myst_heading_anchors = 2  # the README's "#numerical-ik" style links
suppress_warnings = ["myst.header"]  # a guide page is a README section: its title is an H2 heading


NAPOLEON = Config(
    napoleon_numpy_docstring=False,
    napoleon_use_rtype=False,
    # "Attributes:" as a field list like "Args:": entries that name several attributes ("q, dq: ...") stay whole
    napoleon_custom_sections=[("Attributes", "params_style")],
)


def _google_sections(app, what, name, obj, options, lines):
    """The "Args:", "Returns:", "Attributes:" sections of functions, classes and modules, by napoleon.

    Constants' and properties' docstrings are left as they are: napoleon would read their "X: Y" as
    "type: description".
    """
    if what not in ("attribute", "data", "property"):
        lines[:] = GoogleDocstring(lines, NAPOLEON, app, what, name, obj, options).lines()


def _documented_at(env, name: str) -> str | None:
    """Where the object that ``name`` (``qpik.ik``, ``qpik.CATALOG``) imports is documented.

    Its ``__module__.__qualname__`` (``qpik.analytic.api.ik``), else the qpik module that holds the same object
    (``qpik.robots.catalog.CATALOG``), if that name is documented.
    """
    parts = name.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        candidates = [f"{obj.__module__}.{obj.__qualname__}"] if hasattr(obj, "__qualname__") else []
        candidates += [f"{m}.{parts[-1]}" for m, mod in sys.modules.items()
                       if m.startswith("qpik.") and vars(mod).get(parts[-1]) is obj]  # fmt: skip
        documented = env.get_domain("py").objects
        return next((c for c in candidates if c != name and c in documented), None)
    return None


def _resolve_reexport(app, env, node, contnode):
    """Resolve a reference to a re-exported name (``:func:`qpik.solve_best```) where it is documented."""
    if node.get("refdomain") != "py" or not node.get("reftarget", "").startswith("qpik."):
        return None
    target = _documented_at(env, node["reftarget"])
    if target is None:
        return None
    node = node.deepcopy()
    node["reftarget"] = target
    return env.get_domain("py").resolve_xref(env, node["refdoc"], app.builder, node["reftype"], target, node, contnode)


def _no_object_base(app, name, obj, options, bases):
    """No "Bases: object" line under every class."""
    if bases == [object]:
        bases.clear()


def setup(app):
    app.connect("autodoc-process-docstring", _google_sections, priority=400)  # before the type hints
    app.connect("missing-reference", _resolve_reexport)
    app.connect("autodoc-process-bases", _no_object_base)
