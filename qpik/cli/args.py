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
