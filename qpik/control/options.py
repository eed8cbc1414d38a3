"""The knobs of :meth:`qpik.Controller.for_scene`: task gains and weights, limit margins, as one value."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ControllerOptions:
    """The usual controller's tasks and limits (:meth:`qpik.Controller.for_scene`).

    Attributes:
        position_gain: the :class:`~qpik.control.tasks.FrameTask`'s position gain, 1/s.
        orientation_gain: its orientation gain, 1/s.
        posture_weight: the :class:`~qpik.control.tasks.PostureTask`'s weight, per rad².
        manipulability_weight: the :class:`~qpik.control.tasks.ManipulabilityTask`'s weight (0: no task effect).
        damping: the :class:`~qpik.control.tasks.DampingTask`'s weight, per (rad/s)².
        margin: the :class:`~qpik.control.limits.configuration.ConfigurationLimit`'s margin, rad.
        d_influence: the :class:`~qpik.control.limits.obstacle.ObstacleLimit`'s influence distance, m.
        xi: the obstacle dampers' gain, m/s.
        self_collision: add the :class:`~qpik.control.self_collision.SelfCollisionLimit` (arms with more than
            two capsules).
    """

    position_gain: float = 50.0
    orientation_gain: float = 50.0
    posture_weight: float = 1e-3
    manipulability_weight: float = 1e-3
    damping: float = 1e-4
    margin: float = 0.0
    d_influence: float = 0.10
    xi: float = 0.5
    self_collision: bool = True
