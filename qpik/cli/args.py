"""Argument types shared by the subcommands."""

from __future__ import annotations

import argparse

import numpy as np


def floats(text: str) -> np.ndarray:
    """Comma- or space-separated floats: ``"0,0.5,0"`` or ``"0 0.5 0"``."""
    try:
        return np.array([float(t) for t in text.replace(",", " ").split()])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None


def add_robot(parser: argparse.ArgumentParser, required: bool = True) -> None:
    from qpik.robots.catalog import CATALOG

    parser.add_argument("--robot", "-r", required=required, choices=sorted(CATALOG), help="arm of the catalog")


def whole(values: np.ndarray, option: str) -> list[int]:
    """The numbers of ``option`` as integers; :class:`InputError` if one is not a whole number."""
    from qpik.errors import InputError

    if np.any(values != np.round(values)):
        raise InputError(f"{option}: expected whole numbers, got {values.tolist()}")
    return [int(v) for v in values]


def at_least_one(value: int, option: str) -> int:
    """``value`` if it is >= 1, else :class:`InputError` naming ``option``."""
    from qpik.errors import InputError

    if value < 1:
        raise InputError(f"{option}: must be >= 1, got {value}")
    return value
