"""``qpik bench``: speed of qpik beside its peers (same process, ratios)."""

from __future__ import annotations

import argparse
import importlib

from qpik.cli.args import Subcommands


def register(sub: Subcommands) -> None:
    from qpik.bench import BENCHES
    from qpik.bench.view import CLIENTS

    p = sub.add_parser("bench", help="time qpik next to mink, ssik and other solvers")
    p.add_argument("which", nargs="*", metavar="BENCH", help=f"benches to run: {', '.join(BENCHES)} (default: all)")
    p.add_argument(
        "--repeat",
        type=int,
        default=2000,
        help="the benches' size: timed calls of the fast rows, fewer of the slow ones (default: 2000)",
    )
    p.add_argument(
        "--client",
        choices=CLIENTS,
        default=CLIENTS[0],
        help="the view bench's client of the viewer: a websocket client in another process that receives and decodes "
        "every message, drawing nothing (socket), or the page in headless Chromium, drawn in software GL (browser); "
        f"default: {CLIENTS[0]}",
    )
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from qpik.bench import BENCHES, render
    from qpik.cli.args import at_least_one
    from qpik.core.errors import InputError

    unknown = sorted(set(args.which) - set(BENCHES))
    if unknown:
        raise InputError(f"unknown bench {', '.join(unknown)}; choose from {', '.join(BENCHES)}")
    at_least_one(args.repeat, "--repeat")
    for name in args.which or BENCHES:
        module = importlib.import_module(f"qpik.bench.{name}")
        print(render(module.TITLE, module.run(args)))
        print()
    return 0
