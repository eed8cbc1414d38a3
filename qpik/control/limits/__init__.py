"""Limits: the constraints of the QP over the joint velocity ``v`` (n,), rad/s, one module per limit.

- :mod:`~qpik.control.limits.base`: :class:`Limit`, :class:`BoxLimit` (bounds on v) and :class:`RowLimit`
  (rows ``l ≤ A v ≤ u``);
- :mod:`~qpik.control.limits.configuration`: :class:`ConfigurationLimit`, the joint position limits;
- :mod:`~qpik.control.limits.velocity`: :class:`VelocityLimit`, the joint velocity limits (the cap box);
- :mod:`~qpik.control.limits.obstacle`: :class:`ObstacleLimit`, velocity dampers against the obstacles;
- :mod:`~qpik.control.limits.damper`: the damper rows' bounds, shared with :mod:`qpik.control.self_collision`.

Acceleration, jerk and braking limits: :mod:`qpik.control.limits_motion`.
"""

from qpik.control.limits.base import BoxLimit, Limit, RowLimit
from qpik.control.limits.configuration import ConfigurationLimit
from qpik.control.limits.damper import braked_xi, damper_lower, damper_recovery
from qpik.control.limits.obstacle import ObstacleLimit
from qpik.control.limits.velocity import VelocityLimit

__all__ = [
    "BoxLimit",
    "ConfigurationLimit",
    "Limit",
    "ObstacleLimit",
    "RowLimit",
    "VelocityLimit",
    "braked_xi",
    "damper_lower",
    "damper_recovery",
]
