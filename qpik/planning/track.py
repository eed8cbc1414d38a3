"""The QP controller tracking a plan's waypoints: the start of the joint NLP for arms without a closed form, and
the online baseline (:func:`qpik.planning.baselines.online`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra.lie import tracking_errors
from qpik.control.controller import Controller
from qpik.control.options import ControllerOptions
from qpik.core.stopwatch import Stopwatch
from qpik.geometry.paths import WaypointPath

if TYPE_CHECKING:
    from qpik.planning.setup import Setup

TRACK_DT = 0.002
"""s: control period of the QP controller's tracking run."""
TRACK_SPEED = (0.1, 0.5)
"""m/s and rad/s: the end-effector speeds at which an untimed path is tracked by the QP controller."""


def track(setup: Setup, q0: np.ndarray, watch: Stopwatch | None = None) -> np.ndarray:
    r"""The QP controller's configurations (N, n), rad, at the waypoints of ``setup``, tracking them from ``q0``.

    The controller is :meth:`qpik.Controller.for_robot` with the setup's obstacles and ``d_safe``, posture reference
    ``q0``, no manipulability task, at :data:`TRACK_DT`; its target at :math:`t_k = k\,\Delta t` is the pose and
    feed-forward twist of :class:`qpik.geometry.paths.WaypointPath` through the waypoints at their ``times`` (without
    times: at the speeds of :data:`TRACK_SPEED`), and :math:`q_{k+1} = q_k + v_k \Delta t` (the kinematic integration
    of :func:`qpik.sim.simulate`). ``watch``: paused while the controller is built, so that it times the run.
    """
    times = setup.times if setup.times is not None else nominal_times(setup.poses)
    path = WaypointPath(setup.poses, times)
    with (watch or Stopwatch()).paused():
        options = ControllerOptions(manipulability_weight=0.0)
        ctrl = Controller.for_robot(setup.robot, obstacles=setup.obstacles, dt=TRACK_DT, q_ref=q0,
                                    d_safe=setup.d_safe, options=options)  # fmt: skip
    steps = round(path.duration / TRACK_DT)
    q = np.empty((steps + 1, setup.robot.dof))
    q[0] = q0
    for k in range(steps):
        t = k * TRACK_DT
        q[k + 1] = q[k] + ctrl.step(q[k], path.pose(t), path.twist(t)) * TRACK_DT
    return q[np.clip(np.round((times - times[0]) / TRACK_DT).astype(int), 0, steps)]


def nominal_times(poses: np.ndarray) -> np.ndarray:
    """Times (N,), s, that move the end effector at :data:`TRACK_SPEED` between waypoints (N, 4, 4) (at least one
    control period)."""
    dp, dr = tracking_errors(poses[1:], poses[:-1])
    dt = np.maximum(np.maximum(dp / TRACK_SPEED[0], dr / TRACK_SPEED[1]), TRACK_DT)
    return np.concatenate([[0.0], np.cumsum(dt)])
