r"""End-effector paths: the protocol the controller, the simulator, the planner and the problem files share.

A *timed path* (:class:`TimedPath`) gives, for ``0 <= t <= duration`` (s), the end-effector pose
``pose(t)`` (4, 4) and the feed-forward twist ``twist(t)`` ``[v; ω]`` (6,), both in the base
frame. Two implementations:

- :class:`TargetPath`: a position formula with a constant orientation (the named paths of
  problem files, :mod:`qpik.problems.paths`);
- :class:`WaypointPath`: poses at given times, between them the position linear and the
  rotation turning at a constant rate about a fixed axis (``scipy.spatial.transform.Slerp``).

Both accept a scalar ``t`` or an array ``t`` (K,), which gives (K, 4, 4) and (K, 6). This module
imports nothing of qpik's simulator, controller or problem files, so every layer can use it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import finite_array
from qpik.core.validate import pose as check_pose


@runtime_checkable
class TimedPath(Protocol):
    """A timed end-effector path: pose (4, 4) and twist ``[v; ω]`` (6,) in the base frame at t (s)."""

    duration: float

    def pose(self, t: float) -> np.ndarray: ...

    def twist(self, t: float) -> np.ndarray: ...


@dataclass(frozen=True)
class TargetPath:
    """A position path with a constant orientation (the form of every registered formula).

    Attributes:
        name: the formula's registry name.
        duration: end time (s).
        q0: initial configuration (rad) the path starts from, shape (7,), or ``None``.
        rotation: the constant end-effector orientation, (3, 3), base frame.
        position: ``t -> p(t)``, maps (K,) times to (K, 3) positions (m, base frame).
        velocity: ``t -> ṗ(t)``, (K,) -> (K, 3) (m/s, base frame).
    """

    name: str
    duration: float
    q0: np.ndarray | None
    rotation: np.ndarray
    position: Callable[[np.ndarray], np.ndarray]
    velocity: Callable[[np.ndarray], np.ndarray]

    def pose(self, t: float | np.ndarray) -> np.ndarray:
        """Target pose at time ``t`` (s): (4, 4), or (K, 4, 4) for ``t`` of shape (K,)."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        T = np.zeros((len(ts), 4, 4))
        T[:, :3, :3] = self.rotation
        T[:, :3, 3] = self.position(ts)
        T[:, 3, 3] = 1.0
        return T[0] if np.ndim(t) == 0 else T

    def twist(self, t: float | np.ndarray) -> np.ndarray:
        """Feed-forward twist ``[v; ω]`` (m/s, rad/s, base frame) at ``t``: (6,) or (K, 6)."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        V = np.zeros((len(ts), 6))
        V[:, :3] = self.velocity(ts)
        return V[0] if np.ndim(t) == 0 else V


class WaypointPath:
    r"""Poses (N, 4, 4) at increasing times (N,) (s), as a :class:`TimedPath`.

    Between waypoints k and k+1 the position moves linearly and the rotation turns at a constant
    rate about a fixed axis (spherical linear interpolation): the twist there is
    :math:`v = (p_{k+1} - p_k)/\Delta t_k`, :math:`\omega = \log(R_{k+1} R_k^T)/\Delta t_k`
    (world frame). At a waypoint the twist is that of the segment that starts there (the last
    waypoint: the segment that ends there). Times before the first waypoint or after the last
    give the end poses.

    Args:
        poses: (N, 4, 4) end-effector poses in the base frame, N ≥ 2 (rotations orthonormal within 1e-6).
        times: (N,) strictly increasing times (s); default ``0, 1, ..., N - 1``.
    """

    def __init__(self, poses: np.ndarray, times: np.ndarray | None = None):
        from scipy.spatial.transform import Rotation, Slerp  # SciPy's spatial package: only for this class

        T, batched = check_pose(poses, "poses")
        if not batched or len(T) < 2:
            raise InputError(f"poses: a waypoint path needs (N, 4, 4) poses with N >= 2, got {np.shape(poses)}")
        t = np.arange(len(T), dtype=float) if times is None else finite_array(times, "times", (len(T),))
        if np.any(np.diff(t) <= 0):
            raise InputError("times: must be strictly increasing")
        self.poses, self.times = T.copy(), t.copy()
        self.start, self.duration = float(t[0]), float(t[-1] - t[0])
        rot = Rotation.from_matrix(T[:, :3, :3])
        self._slerp = Slerp(t, rot)
        dt = np.diff(t)
        self._v = np.diff(T[:, :3, 3], axis=0) / dt[:, None]
        self._w = (rot[1:] * rot[:-1].inv()).as_rotvec() / dt[:, None]

    def _at(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ts = np.clip(np.atleast_1d(np.asarray(t, dtype=float)) + self.start, self.times[0], self.times[-1])
        seg = np.clip(np.searchsorted(self.times, ts, side="right") - 1, 0, len(self.times) - 2)
        return ts, seg

    def pose(self, t: float | np.ndarray) -> np.ndarray:
        """Pose at ``t`` (s after the first waypoint): (4, 4), or (K, 4, 4) for ``t`` (K,)."""
        ts, seg = self._at(t)
        frac = (ts - self.times[seg]) / (self.times[seg + 1] - self.times[seg])
        out = np.zeros((len(ts), 4, 4))
        out[:, :3, :3] = self._slerp(ts).as_matrix()
        p = self.poses[:, :3, 3]
        out[:, :3, 3] = p[seg] + frac[:, None] * (p[seg + 1] - p[seg])
        out[:, 3, 3] = 1.0
        return out[0] if np.ndim(t) == 0 else out

    def twist(self, t: float | np.ndarray) -> np.ndarray:
        """Twist ``[v; ω]`` (m/s, rad/s, base frame) at ``t``: (6,), or (K, 6)."""
        _, seg = self._at(t)
        out = np.concatenate([self._v[seg], self._w[seg]], axis=1)
        return out[0] if np.ndim(t) == 0 else out
