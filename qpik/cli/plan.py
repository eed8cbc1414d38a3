"""``qpik plan``: plan the self-motion along the path of problem files (kind ``plan``).

``qpik plan FILE`` plans one file and prints its report (also written to ``OUT/<name>/report.md`` with the plan
as CSV and NPZ and its figures). ``qpik plan DIR`` (or several files) plans every ``plan`` file of the folder, in
parallel over local processes (``--workers``, default one per CPU) with a progress bar, and prints one line per
file; ``--scheduler tcp://HOST:8786`` runs the same jobs on a Dask cluster instead (``pip install 'qpik[cluster]'``;
every worker needs qpik installed, and shares no folder with this machine).

This process reads every file (and the robot's model and meshes), the workers compute, this process writes each
file's report and files to ``OUT/<name>/`` (:mod:`qpik.problems.plan`). Before anything runs, the output names
(each file's ``name``) are checked: a name that is empty, ``.`` or ``..``, or holds a path separator or a control
character, and two files of one name (ignoring case), are errors (exit code 2), so nothing is written outside
``OUT`` and no result overwrites another. A file that cannot be read is reported and the others still run.

Exit code: 0 when every plan passes its checks; 1 when a plan FAILs, a file cannot be read or a job fails (each
listed); 2 for a usage error (bad arguments, output names, no scheduler).
"""

from __future__ import annotations

import argparse
import sys
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
    p.add_argument("--retries", type=int, default=0, help="on a Dask cluster: run a job that raises again N times")
    p.set_defaults(func=_run)


def _problems(names: list[str]) -> tuple[list, list[str]]:
    """The ``plan`` problems of ``names`` (files, folders, shipped names) and one line per file that cannot be read.

    Raises:
        InputError: a folder without a plan file; a file named on its own that is not of kind ``plan``.
    """
    from qpik.core.errors import InputError, ProblemFileError
    from qpik.problems import find_problem, load, problem_files

    problems, bad = [], []
    for name in names:
        path = Path(name)
        if path.is_dir():
            found = 0
            for f in problem_files(path):
                try:
                    problem = load(f)
                except ProblemFileError as exc:
                    bad.append(" ".join(str(exc).split()))
                    continue
                if problem.kind == "plan":
                    problems.append(problem)
                    found += 1
            if not found and not bad:
                raise InputError(f"{name}: no problem file of kind 'plan' in this folder")
            continue
        file = find_problem(name)  # a missing file or unknown name: a usage error
        try:
            problem = load(file)
        except ProblemFileError as exc:
            bad.append(" ".join(str(exc).split()))
            continue
        if problem.kind != "plan":
            raise InputError(f'{file}: kind {problem.kind!r} is not a planning problem (kind = "plan")')
        problems.append(problem)
    return problems, bad


def _run(args: argparse.Namespace) -> int:
    from qpik.core.errors import InputError
    from qpik.planning.batch import JobFailure, run_batch
    from qpik.problems.plan import check_names, plan_job, solve

    if args.workers is not None and args.workers < 0:
        raise InputError(f"--workers: must be >= 0, got {args.workers}")
    if args.retries < 0:
        raise InputError(f"--retries: must be >= 0, got {args.retries}")
    problems, failures = _problems(args.files)
    check_names(problems)
    jobs = []
    for problem in problems:
        try:
            jobs.append(plan_job(problem))
        except InputError as exc:  # its robot's model files cannot be read
            failures.append(" ".join(str(exc).split()))
    single = len(jobs) == 1 and not failures and len(args.files) == 1 and not Path(args.files[0]).is_dir()
    failed = 0
    for i, result in run_batch(solve, jobs, workers=0 if single else args.workers, scheduler=args.scheduler,
                               retries=args.retries):  # fmt: skip
        job = jobs[i]
        if isinstance(result, JobFailure):
            failures.append(f"{job.file}: {result.error}")
            print(f"{job.name}: error: {result.error}")
            continue
        report = result.write(args.out / job.name)
        failed += not result.ok
        if single:
            print(result.text)
            print(f"\nreport written to {report}")
        else:
            print(f"{job.name}: {'PASS' if result.ok else 'FAIL'}: {result.plan.summary()}")
    if not single:
        print(f"\n{len(jobs)} file(s) planned, {failed} FAIL; reports in {args.out}/<name>/report.md")
    for line in failures:
        print(f"qpik plan: {line}", file=sys.stderr)
    if failures:
        print(f"qpik plan: {len(failures)} file(s) not planned", file=sys.stderr)
    return 1 if failed or failures else 0
