"""context: see :mod:`qpik.objectives`."""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.geometry.distance import ObstacleSet, distances, set_expr
from qpik.robots.manipulability import hessian_rows, jacobian_rows, manipulability_gradient_expr
from qpik.robots.self_pairs import Pair, pair_distance_expr

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


def pair_count(robot: Robot, obstacles: Sequence | ObstacleSet) -> int:
    """C'·O: the capsule–obstacle pairs of :attr:`Context.distances`, those of the capsules a joint moves."""
    return int(np.count_nonzero(~robot.fixed_capsules)) * len(obstacles)


def clearance(robot: Robot, q: np.ndarray, obstacles: Sequence | ObstacleSet) -> np.ndarray:
    """(M,) the smallest distance of the pairs of :attr:`Context.distances` at configurations q (M, n), m
    (numpy; inf without pairs)."""
    moving = ~robot.fixed_capsules
    if not pair_count(robot, obstacles):
        return np.full(len(q), np.inf)
    d = distances(robot.capsule_segments(q)[:, moving], robot.capsule_radii[moving], obstacles).d
    return d.reshape(len(q), -1).min(axis=1)


class Context:
    """The symbols an objective is written against (CasADi SX).

    Args:
        robot: the arm.
        q: (n,) joint positions, rad.
        q_ref: (n,) reference configuration, rad (an input of the compiled function).
        obstacles: the obstacles of the problem (their families fix the expression's form).
        obstacle_params: their packed parameters (:attr:`ObstacleSet.params`), an input.
        witness: (n,) a second symbol for q, or None; see :attr:`distances`.
        distances: (C'·O,) symbols standing for :attr:`distances`, or None (then they are built from q):
            an objective's split written against them is a function of q and the distances.
        self_pairs: the capsule pairs of :attr:`self_distances` (:func:`~qpik.robots.self_pairs.checked_pairs`).

    The kinematics are built on first use, so an objective that needs none costs nothing.
    """

    def __init__(
        self,
        robot: Robot,
        q: ca.SX,
        q_ref: ca.SX,
        obstacles: ObstacleSet,
        obstacle_params: ca.SX,
        witness: ca.SX | None = None,
        distances: ca.SX | None = None,
        self_pairs: tuple[Pair, ...] = (),
    ):
        self.robot, self.q, self.q_ref, self.self_pairs = robot, q, q_ref, self_pairs
        self.obstacles, self.obstacle_params, self.witness = obstacles, obstacle_params, witness
        self.n = robot.dof
        self._given_distances = distances

    @cached_property
    def frames(self) -> list:
        """The chain's frames ``[base, frame_1..frame_n, ee]`` (:meth:`DHChain.frames_expr`)."""
        return self.robot.chain.frames_expr([self.q[i] for i in range(self.n)], sy.CASADI)

    @cached_property
    def _jacobian(self) -> tuple[list, list]:
        chain = self.robot.chain
        jv, jw = chain.jacobian_expr(self.frames)
        return jacobian_rows(jv, jw), hessian_rows(chain.hessian_expr(self.frames, (jv, jw)))

    def manipulability(self, translational: bool = False) -> ca.SX:
        """Yoshikawa's :math:`\\sqrt{\\det J J^T}` (``translational``: of J_v), from the QR of
        :func:`~qpik.robots.dh.manipulability_gradient_expr`."""
        J, H = self._jacobian
        rows = 3 if translational else 6
        return manipulability_gradient_expr(J[:rows], [Hk[:rows] for Hk in H])[1]

    @cached_property
    def distances(self) -> ca.SX:
        r"""Signed distances (C'·O,) of the pairs of the C' capsules a joint moves (:func:`pair_count`), m.

        Pair (c, o) is at k·O + o with k the rank of capsule c among those that are not
        :attr:`~qpik.robots.robot.Robot.fixed_capsules`: a fixed capsule's distance is a constant no
        configuration changes (the base column standing on a table), so it constrains nothing.

        With a ``witness`` symbol w, the closest points are found at w and the distance is
        written :math:`n^T(x_s(q) - p_{obs}) - r` with the unit normal n, the obstacle's witness
        point and the capsule-axis parameter s taken at w, and :math:`x_s(q)` the axis point at q.
        At w = q this equals the distance, and (Danskin's theorem) its gradient in q is the
        gradient of the distance, :math:`n^T J_p` (:mod:`qpik.geometry.distance`), at a fraction of
        the cost of differentiating the closest-point kernels; substitute w = q after differentiating.
        Exact wherever the closest points are unique, which holds for every pair clear of its
        obstacle; for a capsule axis inside a box it is the rate of the deepest point's depth
        with that point held (the kernel's own normal), not a derivative of the depth.
        """
        if self._given_distances is not None:
            return self._given_distances
        if not len(self.obstacles):
            return ca.SX(0, 1)
        prm = [self.obstacle_params[i] for i in range(self.obstacle_params.numel())]
        moving = np.flatnonzero(~self.robot.fixed_capsules)
        radii, kinds = self.robot.capsule_radii[moving], self.obstacles.kinds
        at = self.frames if self.witness is None else self._frames_of(self.witness)
        segments = self.robot.capsule_segments_expr(at)
        pairs = set_expr([segments[c] for c in moving], radii, kinds, prm, sy.CASADI)
        if self.witness is None:
            return ca.vertcat(*[d for row in pairs for d, *_ in row])
        out = []
        segments = self.robot.capsule_segments_expr(self.frames)
        for (a, b), r, row in zip([segments[c] for c in moving], radii, pairs):
            for _, _, p_obs, normal, s in row:
                x = sy.vadd(a, sy.vscale(s, sy.vsub(b, a)))
                out.append(sy.dot(normal, sy.vsub(x, p_obs)) - r)
        return ca.vertcat(*out)

    @cached_property
    def self_distances(self) -> ca.SX:
        """Signed distances (P,) of the capsule pairs :attr:`self_pairs` at q, m
        (:func:`~qpik.robots.self_pairs.pair_distance_expr`, written from q: CasADi differentiates the kernel
        itself)."""
        if not self.self_pairs:
            return ca.SX(0, 1)
        segments = self.robot.capsule_segments_expr(self.frames)
        radii = [float(r) for r in self.robot.capsule_radii]
        return ca.vertcat(*[pair_distance_expr(segments, radii, p, sy.CASADI) for p in self.self_pairs])

    @property
    def clearances(self) -> ca.SX:
        """(C'·O + P,) every distance the clearance constraint keeps ≥ d_s, m: :attr:`distances` (capsule–obstacle),
        then :attr:`self_distances` (capsule–capsule)."""
        return ca.vertcat(self.distances, self.self_distances)

    def _frames_of(self, q: ca.SX) -> list:
        return self.robot.chain.frames_expr([q[i] for i in range(self.n)], sy.CASADI)
