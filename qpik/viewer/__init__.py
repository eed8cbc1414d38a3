"""``qpik view``: the arm in a web browser, with a target to drag, every branch, the feasible sets and the best answer.

:func:`view` starts a local web server (viser, ``pip install 'qpik[view]'``) and returns its
:class:`~qpik.viewer.server.Viewer`; ``http://127.0.0.1:8080`` then shows the scene described in
:mod:`qpik.viewer.server`. viser is imported when a viewer starts, never by ``import qpik``.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from qpik.core.errors import ViewerError

if TYPE_CHECKING:
    import numpy as np

    from qpik.robots.robot import Robot
    from qpik.viewer.server import Viewer

VIEW_EXTRA = "viser is not installed: pip install 'qpik[view]'"


def view(
    robot: Robot,
    target: np.ndarray | None = None,
    obstacles=(),
    objective: str = "margin",
    *,
    d_safe: float = 0.02,
    play=None,
    live: bool = False,
    host: str = "127.0.0.1",
    port: int = 8080,
    dt: float = 0.002,
    block: bool = True,
    screenshot: str | os.PathLike | None = None,
    size: tuple[int, int] = (1280, 800),
) -> Viewer:
    """Show ``robot`` in a web page at ``http://HOST:PORT``.

    Args:
        robot: any arm (:func:`qpik.load_robot`).
        target: (4, 4) the first target pose, base frame (default: the end effector at the home configuration).
        obstacles: shapes of :mod:`qpik.geometry` (world frame, m).
        objective: :func:`qpik.solve_best`'s objective, a name of :data:`qpik.objectives.NAMES`.
        d_safe: m, the clearance kept by :func:`qpik.solve_best` and by the controller in live mode.
        play: a :class:`qpik.Plan`, a :class:`qpik.sim.SimLog` or the ``*_plan.npz`` file of ``qpik plan`` to
            play back with a time slider.
        live: start with the QP controller tracking the target.
        host, port: where the server listens; the default serves this machine only (from another machine,
            forward the port: ``ssh -L 8080:localhost:8080 HOST``). Port 0 takes any free port.
        dt: s, the controller's period in live mode.
        block: serve until Ctrl-C (then stop the server); else return the running viewer at once.
        screenshot: write a PNG of the page, rendered by a headless browser (:mod:`qpik.viewer.browser`),
            to this path, then stop the server and return.
        size: (width, height) of the screenshot in pixels.

    Returns:
        The :class:`~qpik.viewer.server.Viewer` (stopped if ``block`` or ``screenshot``).

    Raises:
        ViewerError: viser is not installed, the port is taken, or (with ``screenshot``) no browser.
        InputError: bad arguments (naming them).
    """
    try:
        from qpik.viewer.server import Viewer
    except ImportError as exc:
        if exc.name is not None and exc.name.split(".")[0] == "viser":
            raise ViewerError(VIEW_EXTRA) from None
        raise
    viewer = Viewer(robot, target, obstacles, objective, d_safe, play, live, host, port, dt)
    if screenshot is not None:
        try:
            viewer.screenshot(screenshot, size)
        finally:
            viewer.close()
    elif block:
        viewer.serve_forever()
    return viewer
