r"""The kinematic state of one control step, computed once and shared by every task and limit.

:class:`State` evaluates, for a configuration ``q`` and the obstacles of the controller,
ONE natively compiled CasADi function (:class:`Kinematics`, :mod:`qpik.compiled`) traced
from the expression builders of the other layers — nothing here re-derives them:

- the frames (:meth:`~qpik.robots.dh.DHChain.frames_expr`), the end-effector pose and the
  geometric Jacobian ``J = [J_v; J_ω]`` (6, n), world frame;
- the manipulability gradient ∇m (n,), full and translational, from the kinematic
  Hessian (:func:`~qpik.robots.dh.manipulability_gradient_expr`);
- the world end points of the link capsules (C, 2, 3)
  (:meth:`~qpik.robots.robot.Robot.capsule_segments_expr`);
- for a packed obstacle set (:class:`~qpik.geometry.distance.ObstacleSet`), every
  capsule–obstacle distance and witness point (:func:`~qpik.geometry.distance.set_expr`)
  and the velocity-damper coefficients :math:`n^T J_p(p_{link})` (C·O, n), with the point
  Jacobian of :meth:`~qpik.robots.dh.DHChain.point_jacobian_expr`: joint ``j`` turns about
  :math:`z_j` through :math:`o_j`, and a point :math:`p` of link ``k`` moves with
  :math:`\dot p = \sum_{j \le k} z_j \times (p - o_j)\,\dot q_j`.

The tasks and limits then do only small numpy work on these arrays.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik import symbolic as sy
from qpik.compiled import Compiled
from qpik.robots.dh import _hessian_rows, _jacobian_rows, manipulability_gradient_expr

if TYPE_CHECKING:
    from qpik.geometry.distance import Distances, ObstacleSet
    from qpik.robots.robot import Robot


class Kinematics:
    """Per-robot compiled step functions, one per tuple of obstacle kernel families.

    ``function(kinds)`` maps ``q`` (n,) [and the obstacle parameters] to one flat vector:
    pose (16, row-major), J (6n, row-major), ∇m (n), translational ∇m (n), capsule end
    points (6C), then for C capsules × O obstacles: ``[d, p_link, p_obs, n, s]`` (11 per
    pair) and the damper rows (C·O × n, row-major). Built once per robot by :func:`kinematics_of`.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.n = robot.dof
        self.n_capsules = len(robot.capsules)
        self.base_size = 16 + 8 * self.n + 6 * self.n_capsules
        self._functions: dict[tuple[str, ...], Compiled] = {}

    def function(self, kinds: tuple[str, ...]) -> Compiled:
        """The compiled step function for obstacles of families ``kinds`` (``()``: no obstacles)."""
        fn = self._functions.get(kinds)
        if fn is None:
            fn = self._functions[kinds] = Compiled(self._build(kinds))
        return fn

    def _build(self, kinds: tuple[str, ...]) -> ca.Function:
        from qpik.geometry.distance import PARAMS, set_expr

        robot, chain, n = self.robot, self.robot.chain, self.n
        q = ca.SX.sym("q", n)
        frames = chain.frames_expr([q[i] for i in range(n)], sy.CASADI)
        jv, jw = chain.jacobian_expr(frames)
        Jr, Hr = _jacobian_rows(jv, jw), _hessian_rows(chain.hessian_expr(frames, (jv, jw)))
        R, p = frames[-1]
        out = [*R[0], p[0], *R[1], p[1], *R[2], p[2], 0.0, 0.0, 0.0, 1.0]
        out += [x for row in Jr for x in row]
        for rows in (6, 3):
            out += manipulability_gradient_expr(Jr[:rows], [Hk[:rows] for Hk in Hr])[0]
        segments = robot.capsule_segments_expr(frames)
        out += [x for ab in segments for end in ab for x in end]
        inputs = [q]
        if kinds:
            prm = ca.SX.sym("params", sum(PARAMS[k] for k in kinds))
            inputs.append(prm)
            pairs = set_expr(segments, robot.capsule_radii, kinds, [prm[i] for i in range(prm.numel())], sy.CASADI)
            out += [x for row in pairs for d, p_link, p_obs, nrm, s in row for x in (d, *p_link, *p_obs, *nrm, s)]
            for cap, row in zip(robot.capsules, pairs):
                for _, p_link, _, nrm, _ in row:
                    cols = chain.point_jacobian_expr(frames, p_link, cap.link)
                    out += [sy.dot(nrm, col) for col in cols] + [0.0] * (n - cap.link)
        name = f"step_{robot.name or 'robot'}_{'_'.join(kinds) or 'free'}"
        return ca.Function(name, inputs, [ca.vertcat(*out)])


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
        obstacles: the obstacle set evaluated with the kinematics in the same compiled
            call (others are evaluated on demand by :meth:`distances`).

    Attributes:
        q, dt: as given.
        pose: (4, 4) end-effector pose, world frame.
        J: (6, n) geometric Jacobian ``[v; ω]`` of the end-effector origin, world frame.
        segments: (C, 2, 3) world end points of every link capsule, m (order of ``robot.capsules``).

    The arrays are read-only views of one buffer owned by this state.
    """

    def __init__(self, robot: Robot, q: np.ndarray, dt: float, obstacles: ObstacleSet | None = None):
        kin = kinematics_of(robot)
        self.kin = kin
        self.robot = robot
        self.q = q
        self.dt = dt
        n, C = kin.n, kin.n_capsules
        out = self._evaluate(obstacles)
        self.pose = out[:16].reshape(4, 4)
        self.J = out[16 : 16 + 6 * n].reshape(6, n)
        self._grad = out[16 + 6 * n : 16 + 8 * n].reshape(2, n)
        self.segments = out[16 + 8 * n : kin.base_size].reshape(C, 2, 3)
        self._pairs: dict[int, tuple[ObstacleSet, Distances, np.ndarray]] = {}
        if obstacles is not None and len(obstacles):
            self._unpack(obstacles, out)

    def _evaluate(self, obstacles: ObstacleSet | None) -> np.ndarray:
        """A read-only copy of the step function's output for ``obstacles`` (None or empty: kinematics only)."""
        if obstacles is None or not len(obstacles):
            out = self.kin.function(())(self.q)[0].copy()
        else:
            out = self.kin.function(obstacles.kinds)(self.q, obstacles.params)[0].copy()
        out.flags.writeable = False
        return out

    def _unpack(self, obstacles: ObstacleSet, out: np.ndarray) -> tuple[ObstacleSet, Distances, np.ndarray]:
        from qpik.geometry.distance import Distances

        C, O, base = self.kin.n_capsules, len(obstacles), self.kin.base_size
        pairs = out[base : base + 11 * C * O].reshape(C, O, 11)
        dist = Distances(
            d=pairs[..., 0], p_link=pairs[..., 1:4], p_obs=pairs[..., 4:7], normal=pairs[..., 7:10], s=pairs[..., 10]
        )
        entry = self._pairs[id(obstacles)] = (obstacles, dist, out[base + 11 * C * O :].reshape(C * O, self.kin.n))
        return entry

    def _entry(self, obstacles: ObstacleSet) -> tuple[ObstacleSet, Distances, np.ndarray]:
        entry = self._pairs.get(id(obstacles))
        if entry is None or entry[0] is not obstacles:
            entry = self._unpack(obstacles, self._evaluate(obstacles))
        return entry

    def manipulability_gradient(self, translational: bool = False) -> np.ndarray:
        """∇m (n,), per rad, of Yoshikawa's index (``translational``: of J_v only)."""
        return self._grad[int(translational)]

    def distances(self, obstacles: ObstacleSet) -> Distances:
        """Capsule–obstacle distances and witness points (C, O) of a packed obstacle set, world frame."""
        return self._entry(obstacles)[1]

    def damper_rows(self, obstacles: ObstacleSet) -> np.ndarray:
        r"""Rows :math:`n^T J_p(p_{link})` (C·O, n), pair ``(c, o)`` at row ``c·O + o``.

        ``n`` and ``p_link`` are the pair's unit normal and witness point on the capsule
        (:meth:`distances`); ``J_p`` is the point Jacobian of capsule c's link (zero
        columns for the joints beyond it), so the row is :math:`\dot d` per unit ``v``.
        """
        return self._entry(obstacles)[2]
