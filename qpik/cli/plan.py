"""``qpik plan``: plan the self-motion along the path of problem files (kind ``plan``).

``qpik plan FILE`` plans one file and prints its report (also written to ``OUT/report.md`` with the plan
as CSV and NPZ and its figures). ``qpik plan DIR`` (or several files) plans every ``plan`` file of the
folder, in parallel over local processes (``--workers``, default one per CPU) with a progress bar, and
prints one line per file; ``--scheduler tcp://HOST:8786`` runs the same calls on a Dask cluster instead
(``pip install 'qpik[cluster]'``; every worker needs qpik installed). Each file's report and files go to
``OUT/<name>/``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from qpik.cli.args import Subcommands


def register(sub: Subcommands) -> None:
    p = sub.add_parser("plan", help="plan the joint motion along a path (problem files of kind plan)")
    p.add_argument("files", nargs="+", metavar="FILE|DIR", help="problem files or folders of them (or problem names)")
    p.add_argument(
        "-o", "--out", type=Path, default=Path("qpik-out/plan"), help="output folder (default: qpik-out/plan)"
    )
    p.add_argument("--workers", type=int, help="local processes for several files (default: one per CPU; 0: none)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler (tcp://host:8786): plan the files there")
    p.set_defaults(func=_run)


def _files(names: list[str]) -> list[Path]:
    from qpik.errors import InputError
    from qpik.problems import find_problem, load, problem_files

    out: list[Path] = []
    for name in names:
        path = Path(name)
        if path.is_dir():
            found = [f for f in problem_files(path) if load(f).kind == "plan"]
            if not found:
                raise InputError(f"{name}: no problem file of kind 'plan' in this folder")
            out += found
        else:
            out.append(find_problem(name))
    return out


def _run(args: argparse.Namespace) -> int:
    from qpik.errors import InputError
    from qpik.planning.batch import run_batch
    from qpik.problems import load
    from qpik.problems.plan import plan_file

    files = _files(args.files)
    if args.workers is not None and args.workers < 0:
        raise InputError(f"--workers: must be >= 0, got {args.workers}")
    if len(files) == 1 and args.scheduler is None:
        problem = load(files[0])
        result = plan_file((str(files[0]), str(args.out / problem.name)))
        print(result["report"])
        print(f"\nreport written to {args.out / problem.name / 'report.md'}")
        return 0
    jobs = [(str(f), str(args.out / load(f).name)) for f in files]
    failed = 0
    for (path, _), result in run_batch(plan_file, jobs, workers=args.workers, scheduler=args.scheduler):
        if isinstance(result, Exception):
            failed += 1
            print(f"{Path(path).stem}: error: {' '.join(str(result).split())}")
            continue
        verdict = "PASS" if result["ok"] else "FAIL"
        print(f"{result['name']}: {verdict}: {result['summary']}")
    print(f"\n{len(jobs)} file(s); reports in {args.out}/<name>/report.md")
    return 2 if failed else 0
