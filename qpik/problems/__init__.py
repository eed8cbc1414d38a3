"""Problem files (``problems/*.toml``): loading, named paths, and the runners of ``qpik run``."""

from qpik.geometry.paths import TargetPath
from qpik.problems.files import find_problem, list_problems, load, problem_files, problems_folder
from qpik.problems.paths import PATHS, path_formula
from qpik.problems.runners import RUNNERS, get_runner, run_problem, runner
from qpik.problems.schema import KINDS, Problem

__all__ = [
    "KINDS",
    "PATHS",
    "RUNNERS",
    "Problem",
    "TargetPath",
    "find_problem",
    "get_runner",
    "list_problems",
    "load",
    "path_formula",
    "problem_files",
    "problems_folder",
    "run_problem",
    "runner",
]
