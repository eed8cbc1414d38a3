r"""The kinematic state of one control step, computed once and shared by every task and limit.

:class:`State` runs the kinematics of ``q`` once (the compiled CasADi ``frames``
function of the DH chain, a few µs) and derives from the frames, on demand:

- the end-effector pose and geometric Jacobian ``J = [J_v; J_ω]`` (6, n), world frame;
- the kinematic Hessian ``H[k] = ∂J/∂q_k`` (n, 6, n), only if a task asks for it;
- the world end points of the link capsules (C, 2, 3);
- capsule–obstacle distances (:mod:`qpik.geometry`), per obstacle set;
- point Jacobians of witness points.

Joint ``j`` turns about the unit axis :math:`z_j` through the point :math:`o_j`
(world frame); a point :math:`p` rigidly attached to link ``k`` (the body moved by
joint ``k``, 1-based) moves with :math:`\dot p = \sum_{j \le k} z_j \times (p - o_j)\,\dot q_j`.
"""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from qpik.geometry.distance import Distances, ObstacleSet
    from qpik.robots.robot import Robot


class Kinematics:
    """Per-robot constants of :class:`State`: compiled frames, axis indices, capsule geometry.

    Built once per robot by :func:`kinematics_of`; a :class:`State` only reads it.
    """

    def __init__(self, robot: Robot):
        chain = robot.chain
        self.robot = robot
        self.n = chain.dof
        self.frames_fn = chain._compiled["frames"]
        self.jacobian_fn = chain._compiled["jacobian"]
        self.hessian_fn = chain._compiled["hessian"]
        # frame index of joint j's axis: standard DH turns about z of frame j-1, modified about z of frame j
        self.axis_frames = np.arange(self.n) if chain.convention == "standard" else np.arange(1, self.n + 1)
        caps = robot.capsules
        self.cap_link = np.array([c.link for c in caps], dtype=int)  # (C,) 1-based link of each capsule
        self.cap_pts = np.array([[c.p0, c.p1] for c in caps]).reshape(-1, 2, 3)  # (C, 2, 3) in link frames
        self.radii = np.array([c.radius for c in caps])
        # mask[c, j] = joint j moves capsule c's link
        self.cap_mask = (np.arange(self.n)[None, :] < self.cap_link[:, None]).astype(float)


_KIN: dict[int, Kinematics] = {}


def kinematics_of(robot: Robot) -> Kinematics:
    """The cached :class:`Kinematics` of ``robot`` (robots are immutable)."""
    k = _KIN.get(id(robot))
    if k is None or k.robot is not robot:
        k = _KIN[id(robot)] = Kinematics(robot)
    return k


class State:
    """Kinematics of one configuration, shared by the tasks and limits of one control step.

    Args:
        robot: the arm.
        q: joint positions (n,), rad (already validated).
        dt: control period, s.

    Attributes:
        q, dt: as given.
        frames: (n+2, 4, 4) world poses ``[base, frame_1..frame_n, ee]``.
        pose: (4, 4) end-effector pose (a view of ``frames[-1]``).
        J: (6, n) geometric Jacobian ``[v; ω]`` of the end-effector origin, world frame
            (compiled CasADi, from the same expressions as the frames).
    """

    def __init__(self, robot: Robot, q: np.ndarray, dt: float):
        kin = kinematics_of(robot)
        self.kin = kin
        self.robot = robot
        self.q = q
        self.dt = dt
        n = kin.n
        F = kin.frames_fn(q)[0]  # (4, 4(n+2)), blocks side by side
        self.frames = F.reshape(4, n + 2, 4).transpose(1, 0, 2).copy()
        self.pose = self.frames[-1]
        self.J = kin.jacobian_fn(q)[0].copy()
        self._distances: dict[int, Distances] = {}

    @cached_property
    def axes(self) -> np.ndarray:
        """(n, 3) unit joint axes z_j, world frame."""
        return self.frames[self.kin.axis_frames, :3, 2]

    @cached_property
    def origins(self) -> np.ndarray:
        """(n, 3) a point o_j on each joint axis, world frame, m."""
        return self.frames[self.kin.axis_frames, :3, 3]

    @cached_property
    def hessian(self) -> np.ndarray:
        """Kinematic Hessian ``H[k, :, j] = ∂J[:, j]/∂q_k``: (n, 6, n)."""
        n = self.kin.n
        return self.kin.hessian_fn(self.q)[0].reshape(n, 6, n).copy()

    @cached_property
    def segments(self) -> np.ndarray:
        """World end points of every link capsule: (C, 2, 3), m (order of ``robot.capsules``)."""
        Fk = self.frames[self.kin.cap_link]  # (C, 4, 4)
        return np.einsum("cij,cpj->cpi", Fk[:, :3, :3], self.kin.cap_pts) + Fk[:, None, :3, 3]

    def distances(self, obstacles: ObstacleSet) -> Distances:
        """Capsule–obstacle distances (C, O) for a packed obstacle set, computed once per step."""
        d = self._distances.get(id(obstacles))
        if d is None:
            from qpik.geometry.distance import distances

            d = self._distances[id(obstacles)] = distances(self.segments, self.kin.radii, obstacles)
        return d

    def normal_rows(self, points: np.ndarray, normals: np.ndarray, mask: np.ndarray) -> np.ndarray:
        r"""Rows :math:`n^T J_p(p)` (M, n) for world points ``points`` (M, 3) and unit normals (M, 3).

        ``mask`` (M, n) is 1 where joint j moves the link that carries point m
        (``kin.cap_mask[capsule]``), else 0.

        :math:`n^T (z_j \times (p - o_j)) = n^T [z_j]_\times p - n^T (z_j \times o_j)` for the
        joints that move the capsule's link, 0 for the others; the first term is
        :math:`\mathrm{vec}(n p^T) \cdot \mathrm{vec}([z_j]_\times)`, so all rows are two
        small matrix products.
        """
        z, o = self.axes, self.origins
        zero = np.zeros(len(z))
        skew = np.stack(  # (n, 9): rows of [z_j]_× flattened
            (zero, -z[:, 2], z[:, 1], z[:, 2], zero, -z[:, 0], -z[:, 1], z[:, 0], zero), axis=1
        )
        outer = (normals[:, :, None] * points[:, None, :]).reshape(-1, 9)  # (M, 9): n pᵀ flattened
        rows = outer @ skew.T - normals @ _cross(z, o).T
        return rows * mask


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b over the last axis (3), (k, 3) each; a few µs faster than ``np.cross`` on small arrays."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)
