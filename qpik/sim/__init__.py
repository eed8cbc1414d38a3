"""Closed-loop runs in MuJoCo: :func:`simulate` a policy on an arm among obstacles, log it, plot it."""

from typing import TYPE_CHECKING

from qpik.core.lazy import exports

if TYPE_CHECKING:
    from qpik.geometry.paths import TimedPath
    from qpik.robots.mujoco_scene import MjScene, build_scene
    from qpik.sim.log import SimLog, Summary
    from qpik.sim.options import SimOptions
    from qpik.sim.run import follow, simulate

__getattr__, __dir__ = exports(
    __name__,
    {
        "qpik.geometry.paths": ("TimedPath",),
        "qpik.robots.mujoco_scene": ("MjScene", "build_scene"),
        "qpik.sim.log": ("SimLog", "Summary"),
        "qpik.sim.options": ("SimOptions",),
        "qpik.sim.run": ("follow", "simulate"),
    },
)

__all__ = ["MjScene", "SimLog", "SimOptions", "Summary", "TimedPath", "build_scene", "follow", "simulate"]
