"""``qpik run``: solve a problem file with the runner of its kind and print the report.

The report is also written to ``OUT/report.md``; the runner may write pictures
and data beside it. ``FILE`` may be a path or the name of a problem shipped with qpik (``qpik problems``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from qpik.cli.args import Subcommands


def register(sub: Subcommands) -> None:
    p = sub.add_parser("run", help="solve a problem file (*.toml) and write its report")
    p.add_argument(
        "file",
        help="problem file, or the name of one shipped with qpik (qpik problems lists them; e.g. nammoto2012_table4)",
    )
    p.add_argument("-o", "--out", type=Path, help="output folder (default: qpik-out/<problem name>)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from qpik.problems import find_problem, load, run_problem

    problem = load(find_problem(args.file))
    out = args.out or Path("qpik-out") / problem.name
    report = run_problem(problem, out)
    (out / "report.md").write_text(report if report.endswith("\n") else report + "\n")
    print(report)
    print(f"\nreport written to {out / 'report.md'}")
    return 0
