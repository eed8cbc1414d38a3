"""Closed-loop runs in MuJoCo: :func:`simulate` a policy on an arm among obstacles, log it, plot it."""

from typing import TYPE_CHECKING

from qpik.core.lazy import exports

if TYPE_CHECKING:
    from qpik.geometry.paths import TimedPath
    from qpik.sim.log import SimLog, Summary, tracking_errors
    from qpik.sim.run import Scene, build_scene, follow, simulate

__getattr__, __dir__ = exports(
    __name__,
    {
        "qpik.geometry.paths": ("TimedPath",),
        "qpik.sim.log": ("SimLog", "Summary", "tracking_errors"),
        "qpik.sim.run": ("Scene", "build_scene", "follow", "simulate"),
    },
)

__all__ = ["Scene", "SimLog", "Summary", "TimedPath", "build_scene", "follow", "simulate", "tracking_errors"]
