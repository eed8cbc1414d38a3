"""The knobs of :func:`qpik.plan_self_motion` as one value: joint-step bounds, the DP's grid, the NLP, the checks."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from qpik.robots.robot import Robot

WAYPOINTS = 101
"""Waypoints sampled from a timed path when no ``times`` are given."""
RESOLUTION = 720
"""``resolution`` None: the grid's values per branch of an arm whose branches are expressions of the parameter."""
SEARCH_RESOLUTION = 64
"""``resolution`` None for an arm whose branches the 1-D search finds: each value of each waypoint is a search
(milliseconds)."""


def default_resolution(robot: Robot) -> int:
    """``resolution`` None for ``robot``: :data:`RESOLUTION`, or :data:`SEARCH_RESOLUTION` where its branches are
    found by the 1-D search (``Robot.branch_functions`` False)."""
    return RESOLUTION if robot.branch_functions else SEARCH_RESOLUTION


@dataclass(frozen=True)
class PlanOptions:
    r"""How :func:`qpik.plan_self_motion` plans (each checked when a plan is made, :class:`~qpik.core.errors.InputError`
    naming the field).

    Attributes:
        max_joint_step: the largest move of any joint between consecutive waypoints, rad (a number or (n,)).
        reconfigure: ``"forbid"`` (report the first waypoint with no continuous continuation) or ``"fewest"``
            (the fewest reconfigurations, then the least J).
        a_max: (n,) or a number, rad/s² (needs ``times``), or None.
        resolution: parameter values per branch in the DP's grid (even, ≥ 8; None: 720, or 64 on an arm whose
            branches the 1-D search finds, where each value at each waypoint is a search of milliseconds).
        window: the largest parameter change (rad) between consecutive waypoints the DP searches on one branch
            (None: three times the largest joint-step bound: on an S-R-S arm
            :math:`\sum_{j \le 3} |\Delta q_j| \ge |\Delta\psi|` allows a change of up to three bounds); moves to
            another branch are searched whatever their size.
        branches: public branch ids the plan may use (None: all).
        refine: run the NLP after the DP.
        waypoints: samples of a timed path without ``times``.
        project: project non-orthonormal rotations of the waypoints onto SO(3).
        mujoco: also measure the clearance with MuJoCo (:func:`qpik.planning.plan.measure`).
    """

    max_joint_step: float | np.ndarray = 0.1
    reconfigure: str = "forbid"
    a_max: float | np.ndarray | None = None
    resolution: int | None = None
    window: float | None = None
    branches: Sequence[int] | None = None
    refine: bool = True
    waypoints: int = WAYPOINTS
    project: bool = False
    mujoco: bool = True
