"""What the viewer plays back: a :class:`qpik.Plan`, a :class:`qpik.sim.SimLog`, or a plan file of ``qpik plan``."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from qpik.core.errors import InputError
from qpik.planning.plan import Plan
from qpik.robots.robot import Robot
from qpik.sim.log import SimLog

PLAN_RATE = 20.0
"""Waypoints per second when a plan has no times."""


@dataclass(frozen=True)
class Track:
    """K records to play: times ``t`` (K,) s, configurations ``q`` (K, n) rad, target poses (K, 4, 4) (base
    frame), the redundancy parameter (K,) rad and branch (K,) of each record (None when unknown), and a
    status string per record (None when there is none)."""

    label: str
    t: np.ndarray
    q: np.ndarray
    poses: np.ndarray
    param: np.ndarray | None = None
    branch: np.ndarray | None = None
    status: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.t)


def as_track(play: Plan | SimLog | Track | str | os.PathLike, robot: Robot) -> Track:
    """A :class:`Track` from a plan, a simulation log or the ``*_plan.npz`` file ``qpik plan`` writes.

    A plan without times is played at :data:`PLAN_RATE` waypoints per second; a log without a target shows
    its end-effector poses as the target.

    Raises:
        InputError: not one of these, or a configuration count other than the robot's (the message names
            the file).
    """
    if isinstance(play, Track):
        track = play
    elif isinstance(play, Plan):
        k = len(play.q)
        t = play.times[:k] if play.times is not None else np.arange(k) / PLAN_RATE
        param = play.param[:k] if len(play.param) else None
        branch = play.branch[:k] if len(play.branch) else None
        track = Track(play.label or "plan", np.asarray(t, float), play.q, play.poses[:k], param, branch)
    elif isinstance(play, SimLog):
        poses = play.target if play.target is not None else play.ee
        status = play.status if np.any(play.status != "") else None
        track = Track(play.label, play.t, play.q, poses, status=status)
    elif isinstance(play, str | os.PathLike):
        track = _plan_file(Path(play))
    else:
        raise InputError(
            f"play: expected a qpik.Plan, a qpik.sim.SimLog or a plan file (.npz), got {type(play).__name__}"
        )
    if track.q.ndim != 2 or track.q.shape[1] != robot.dof or len(track.q) == 0:
        raise InputError(f"play ({track.label}): expected configurations (K, {robot.dof}) of {robot.name}, "
                         f"got shape {track.q.shape}")  # fmt: skip
    return track


def _plan_file(path: Path) -> Track:
    """The ``*_plan.npz`` file of ``qpik plan`` (arrays q, poses, times, param, branch)."""
    if path.suffix.lower() != ".npz":
        raise InputError(f"play: {path}: expected the .npz plan file that qpik plan writes")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: np.asarray(data[k]) for k in ("q", "poses", "times", "param", "branch") if k in data.files}
    except (OSError, ValueError) as exc:
        raise InputError(f"play: {path}: not a readable .npz file ({exc})") from None
    missing = [k for k in ("q", "poses") if k not in arrays]
    if missing:
        raise InputError(f"play: {path}: no array {', '.join(missing)}: not a plan file of qpik plan")
    q, poses = arrays["q"].astype(float), arrays["poses"].astype(float)
    k = len(q)
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) < k or not np.all(np.isfinite(q)):
        raise InputError(f"play: {path}: poses {poses.shape} and q {q.shape} do not make a plan")
    times = arrays.get("times", np.zeros(0))
    t = times[:k].astype(float) if len(times) >= k and k else np.arange(k) / PLAN_RATE
    param = arrays["param"][:k].astype(float) if len(arrays.get("param", ())) >= k and k else None
    branch = arrays["branch"][:k].astype(int) if len(arrays.get("branch", ())) >= k and k else None
    return Track(path.name, t, q, poses[:k], param, branch)
