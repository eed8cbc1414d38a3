"""Argument types shared by the subcommands."""

from __future__ import annotations

import argparse
import re
from typing import Any, Protocol

import numpy as np


class Subcommands(Protocol):
    """What a command's ``register`` is given: argparse's sub-parsers, whose ``add_parser`` adds the command."""

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser: ...


def fields(text: str) -> list[str]:
    """The fields of a list separated by commas or spaces (``"a,b,c"``, ``"a b c"``, ``"a, b, c"``); an empty field
    (``"a,,c"``, a comma at either end) or no field at all is an ``ArgumentTypeError`` that names it."""
    parts = re.split(r"\s*,\s*|\s+", text.strip())
    if parts == [""]:
        raise argparse.ArgumentTypeError(f"expected values separated by commas or spaces, got {text!r}")
    if "" in parts:
        raise argparse.ArgumentTypeError(f"field {parts.index('') + 1} of {text!r} is empty")
    return parts


def floats(text: str) -> np.ndarray:
    """Comma- or space-separated floats: ``"0,0.5,0"`` or ``"0 0.5 0"`` (see :func:`fields`)."""
    parts = fields(text)
    for i, t in enumerate(parts):
        try:
            float(t)
        except ValueError:
            raise argparse.ArgumentTypeError(f"field {i + 1} of {text!r} is not a number: {t!r}") from None
    return np.array([float(t) for t in parts])


def add_robot(parser: argparse.ArgumentParser, required: bool = True) -> None:
    """``--robot`` (a catalog name or an MJCF/URDF file) and the options of :func:`qpik.load_robot` for a file."""
    from qpik.robots.catalog import CATALOG

    parser.add_argument(
        "--robot",
        "-r",
        required=required,
        metavar="NAME|FILE",
        help=f"arm of the catalog ({', '.join(sorted(CATALOG))}) or an MJCF (.xml, .mjcf) or URDF (.urdf) file",
    )
    g = parser.add_argument_group("model file options (with --robot FILE)")
    g.add_argument("--base", help="body or site the arm starts from; poses are relative to it (default: the world)")
    g.add_argument("--tip", help="body or site at the end effector (default: the end of the chain)")
    g.add_argument("--joints", type=fields, help='the arm\'s joints, "j1,j2,..."')
    g.add_argument(
        "--package",
        action="append",
        default=[],
        metavar="NAME=DIR",
        help="folder of a ROS package for package:// mesh paths (repeatable)",
    )
    g.add_argument("--collision-only", action="store_true", help="leave out visual geoms and their meshes")
    g.add_argument(
        "--allow-outside", action="store_true", help="read mesh files outside their package (absolute paths, ..)"
    )


def robot_from_args(args: argparse.Namespace):
    """The :class:`qpik.Robot` named by the :func:`add_robot` options."""
    from qpik import load_robot
    from qpik.core.errors import InputError
    from qpik.robots.model_files import MeshOptions

    options = {k: getattr(args, k) for k in ("base", "tip", "joints") if getattr(args, k) is not None}
    if args.package:
        bad = [p for p in args.package if "=" not in p]
        if bad:
            raise InputError(f"--package: expected NAME=DIR, got {bad[0]!r}")
    meshes = MeshOptions(
        package_map=dict(p.split("=", 1) for p in args.package) if args.package else None,
        collision_only=bool(args.collision_only),
        allow_outside=bool(getattr(args, "allow_outside", False)),
    )
    if meshes != MeshOptions():
        options["meshes"] = meshes
    return load_robot(args.robot, **options)


def whole(values: np.ndarray, option: str) -> list[int]:
    """The numbers of ``option`` as integers; :class:`InputError` if one is not a whole number."""
    from qpik.core.errors import InputError

    if np.any(values != np.round(values)):
        raise InputError(f"{option}: expected whole numbers, got {values.tolist()}")
    return [int(v) for v in values]


def at_least_one(value: int, option: str) -> int:
    """``value`` if it is >= 1, else :class:`InputError` naming ``option``."""
    from qpik.core.errors import InputError

    if value < 1:
        raise InputError(f"{option}: must be >= 1, got {value}")
    return value
