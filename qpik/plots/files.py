"""Writing figures: one PNG per :class:`matplotlib.figure.Figure`, folders made as needed."""

from __future__ import annotations

import os
from pathlib import Path

from matplotlib.figure import Figure


def save(fig: Figure, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Write ``fig`` as a PNG at ``path`` (parent folders are made) and return the path.

    The figure is drawn on its own Agg canvas: no pyplot state and no display are
    used, and the caller's matplotlib backend is left as it is.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path
