"""How :func:`qpik.view` serves its page: live mode, the address, blocking, a screenshot; one value."""

from __future__ import annotations

import os
from dataclasses import dataclass


@dataclass(frozen=True)
class ViewOptions:
    """The server of :func:`qpik.view` and :class:`~qpik.viewer.server.Viewer` (each checked when it starts,
    :class:`~qpik.core.errors.InputError` naming the field).

    Attributes:
        live: start with the QP controller tracking the target.
        dt: the controller's period in live mode, s (> 0).
        host: where the server listens; the default serves this machine only (from another machine, forward the
            port: ``ssh -L 8080:localhost:8080 HOST``).
        port: its port, 0..65535 (0: any free port).
        block: :func:`qpik.view` serves until Ctrl-C (then stops the server); else it returns the running viewer at
            once.
        screenshot: :func:`qpik.view` writes a PNG of the page, rendered by a headless browser
            (:mod:`qpik.viewer.browser`), to this path, then stops the server and returns (None: no picture).
        size: (width, height) of the screenshot, pixels.
    """

    live: bool = False
    dt: float = 0.002
    host: str = "127.0.0.1"
    port: int = 8080
    block: bool = True
    screenshot: str | os.PathLike | None = None
    size: tuple[int, int] = (1280, 800)
