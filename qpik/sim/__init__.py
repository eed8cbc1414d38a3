"""Closed-loop runs in MuJoCo: :func:`simulate` a policy on an arm among obstacles, log it, plot it."""

from qpik.paths import TimedPath
from qpik.sim.log import SimLog, Summary, tracking_errors
from qpik.sim.run import Scene, build_scene, follow, simulate

__all__ = ["Scene", "SimLog", "Summary", "TimedPath", "build_scene", "follow", "simulate", "tracking_errors"]
