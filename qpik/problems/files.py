r"""Where problem files are, and loading them: :func:`load`, :func:`find_problem`, :func:`list_problems`.

The shipped problems are the ``*.toml`` files of the package ``qpik.problem_files`` (the repository's
``problems/`` folder, :func:`problems_folder`); a problem is named by its file's stem. Loading
reads and checks a file (:mod:`qpik.problems.reader`) into a :class:`~qpik.problems.schema.Problem`.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from qpik.core.errors import ProblemFileError
from qpik.problems.reader import Reader
from qpik.problems.schema import Problem


def problems_folder() -> Path:
    """The folder of the problem files shipped with qpik (the package ``qpik.problem_files``)."""
    return Path(str(resources.files("qpik.problem_files")))


def problem_files(folder: Path | None = None) -> list[Path]:
    """The ``*.toml`` files of ``folder`` (default :func:`problems_folder`), sorted by name."""
    return sorted((folder or problems_folder()).glob("*.toml"))


def list_problems(folder: Path | None = None) -> list[Problem]:
    """Every problem of ``folder`` (default :func:`problems_folder`), loaded, sorted by file name."""
    return [load(f) for f in problem_files(folder)]


def _path(value: object, what: str) -> Path:
    if not isinstance(value, str | Path) or not str(value):
        raise ProblemFileError(f"{what}: expected a file path or a problem name, got {value!r}")
    return Path(value)


def find_problem(name_or_path: str | Path) -> Path:
    """A problem file: ``name_or_path`` itself if it is a file, else the shipped problem of that name.

    A name (no folder, no ``.toml`` suffix needed) is looked up among the shipped problems
    (:func:`problems_folder`), never in the working folder.
    """
    p = _path(name_or_path, "problem")
    if p.is_file():
        return p
    if p.parent != Path(".") or (p.suffix and p.suffix != ".toml"):
        raise ProblemFileError(f"{name_or_path}: no such file")
    candidate = problems_folder() / f"{p.stem}.toml"
    if candidate.is_file():
        return candidate
    shipped = ", ".join(f.stem for f in problem_files())
    raise ProblemFileError(f"{name_or_path}: no such file, and no shipped problem of that name (they are: {shipped})")


def load(path: str | Path) -> Problem:
    """Read and check one problem file; its format: :mod:`qpik.problems.schema`."""
    return Reader(_path(path, "problem file")).problem()
