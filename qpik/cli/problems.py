"""``qpik problems``: the problem files of a folder, one line each."""

from __future__ import annotations

import argparse
from pathlib import Path

from qpik.cli.args import Subcommands


def register(sub: Subcommands) -> None:
    p = sub.add_parser("problems", help="list the problem files (default: the ones shipped with qpik)")
    p.add_argument(
        "folder", nargs="?", type=Path, help="folder of *.toml files (default: the problems shipped with qpik)"
    )
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from qpik.core.errors import ProblemFileError
    from qpik.problems import load, problem_files, problems_folder

    folder = args.folder or problems_folder()
    files = problem_files(folder)
    if not files:
        print(f"no problem files in {folder}")
        return 1
    print(f"{len(files)} problem(s) in {folder}\n")
    print(f"{'name':26} {'kind':6} {'robot':9} description")
    bad = 0
    for f in files:
        try:
            p = load(f)
        except ProblemFileError as exc:
            bad += 1
            print(f"{f.stem:26} {'!':6} {'':9} cannot load: {exc}")
            continue
        print(f"{p.name:26} {p.kind:6} {p.robot.name:9} {p.description}")
    return 1 if bad else 0
