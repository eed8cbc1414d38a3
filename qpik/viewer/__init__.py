"""``qpik view``: the arm in a web browser, with a target to drag, every branch, the feasible sets and the best answer.

:func:`view` starts a local web server (viser, ``pip install 'qpik[view]'``) and returns its
:class:`~qpik.viewer.server.Viewer`; ``http://127.0.0.1:8080`` then shows the scene described in
:mod:`qpik.viewer.server`. viser is imported when a viewer starts, never by ``import qpik``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from qpik.core.errors import ViewerError
from qpik.viewer.options import ViewOptions

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
    options: ViewOptions | None = None,
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
        options: live mode and its period, the address, blocking and a screenshot
            (:class:`~qpik.viewer.options.ViewOptions`; default its defaults: http://127.0.0.1:8080, blocking).

    Returns:
        The :class:`~qpik.viewer.server.Viewer` (stopped if ``options.block`` or ``options.screenshot``).

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
    options = ViewOptions() if options is None else options
    viewer = Viewer(robot, target, obstacles, objective, d_safe=d_safe, play=play, options=options)
    if options.screenshot is not None:
        try:
            viewer.screenshot(options.screenshot, options.size)
        finally:
            viewer.close()
    elif options.block:
        viewer.serve_forever()
    return viewer
