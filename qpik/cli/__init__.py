"""The ``qpik`` command.

Every module in this package that defines ``register(subparsers)`` adds one
subcommand; ``register`` calls ``subparsers.add_parser(...)`` and sets
``func`` (called with the parsed arguments, returns an exit code).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import pkgutil
import sys

from qpik.core.errors import QpikError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="qpik",
        description="Closed-form IK branches, QP whole-arm control and self-motion for redundant 7-DOF arms.",
        epilog="Start with `qpik demo`; `qpik COMMAND -h` tells more.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(module, "register"):
            module.register(sub)
    return parser


SERIAL_BLAS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""The variables that :func:`main` sets to 1 unless the user set them: qpik's matrices are a few rows wide, and a
BLAS thread pool only costs on them (on a busy machine a small ``scipy.linalg.expm`` then waits on its threads for
milliseconds). Set before numpy is first imported."""

PIPE_CLOSED = 141
"""The exit code when the reader of the output goes away (``qpik problems | head -1``): a program ended by
SIGPIPE exits with 128 + 13, as ``yes | head -1`` does."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``qpik`` console script.

    Every error ends the command with one line on stderr, ``qpik COMMAND: ...``, and exit
    code 2: qpik's own errors (bad input, problem files, solvers) and the operating
    system's (files that cannot be read or written) as they are; anything else, a bug,
    as ``internal error: <type>: <message>``. Argument syntax errors are argparse's (usage
    and message, exit code 2). A standard output closed by its reader ends the command
    quietly with :data:`PIPE_CLOSED`. BLAS runs on one thread (:data:`SERIAL_BLAS`).
    """
    for var in SERIAL_BLAS:
        os.environ.setdefault(var, "1")
    try:
        try:
            return _command(argv)
        finally:
            sys.stdout.flush()  # a closed pipe shows here, not as a message when the interpreter exits
    except BrokenPipeError:
        with contextlib.suppress(OSError, ValueError):  # the interpreter's last flush then writes nowhere
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return PIPE_CLOSED


def _command(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:
        raise
    except (QpikError, OSError) as exc:
        message = str(exc)
    except Exception as exc:  # a bug: still one line, never a traceback
        message = f"internal error: {type(exc).__name__}: {exc}"
    print(f"qpik {args.command}: {' '.join(message.split())}", file=sys.stderr)
    return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
