"""Writing figures: one PNG per :class:`matplotlib.figure.Figure`, folders made as needed."""

from __future__ import annotations

import os
from pathlib import Path

from matplotlib.figure import Figure

from qpik.core.errors import InputError


def save(fig: Figure, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Write ``fig`` at ``path`` (parent folders are made) and return the path.

    The format is the file name's: ``.png`` (or another format matplotlib writes, e.g.
    ``.pdf``, ``.svg``); any other suffix raises :class:`~qpik.core.errors.InputError`. The
    figure is drawn on its own canvas: no pyplot state and no display are used, and the
    caller's matplotlib backend is left as it is.
    """
    path = Path(path)
    formats = fig.canvas.get_supported_filetypes()
    if path.suffix.lower().lstrip(".") not in formats:
        raise InputError(
            f"path: {path} does not name a picture format; use .png (or one of {', '.join(sorted(formats))})"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path
