"""``qpik demo``: a tour of every capability, with pictures."""

from __future__ import annotations

import argparse
from pathlib import Path

from qpik.cli.args import Subcommands


def register(sub: Subcommands) -> None:
    from qpik.demo import ORDER

    p = sub.add_parser("demo", help="show what qpik does (tables and PNGs)")
    p.add_argument(
        "-o", "--out", type=Path, default=Path("qpik-out/demo"), help="folder for the pictures (default: qpik-out/demo)"
    )
    p.add_argument("--only", nargs="*", choices=ORDER, help="run only these sections")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from qpik.demo import run_all

    run_all(args.out, args.only)
    print(f"\npictures in {args.out}/")
    return 0
