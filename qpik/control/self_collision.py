r"""Self-collision: velocity dampers that keep the arm's own link capsules apart.

One row per checked pair of capsules ``(c, e)`` on links ``k < l`` (:func:`checked_pairs`): with the
capsule–capsule distance ``d`` (m), the witness points :math:`p_c` on capsule ``c`` and :math:`p_e` on
capsule ``e`` and the unit normal ``n`` from ``e`` toward ``c`` (:func:`~qpik.geometry.distance.pair_expr`),
both points move with their links, so

.. math::  \dot d = n^T \big(J_c(p_c) - J_e(p_e)\big)\, v

with the point Jacobians of :meth:`~qpik.robots.chain.SerialChain.point_jacobian_expr` (zero columns for
joints beyond each link; the joints up to ``k`` move both points and their columns nearly cancel). The row
is the damper of :class:`~qpik.control.limits.ObstacleLimit`:

.. math::  n^T (J_c - J_e)\, v \;\ge\; -\xi\,\frac{d - d_s}{d_i - d_s}  \qquad (d < d_i)

with the same relaxation of a demand to separate (:func:`~qpik.control.limits.damper_lower`). A
capsule–capsule distance is not C¹ where the axes are parallel (the witness may jump along them);
``buffer`` δ raises d_s for the rows, as for obstacles, to absorb this and the second-order terms.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.control.limits import RowLimit, damper_lower
from qpik.control.state import SymState
from qpik.core.errors import InfeasibleError, InputError
from qpik.core.layout import Blocks, Layout
from qpik.core.validate import number
from qpik.robots.self_pairs import Pair, candidate_pairs, default_allowed

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


def checked_pairs(
    robot: Robot, allowed: frozenset[Pair] | None = None, srdf: str | os.PathLike | None = None
) -> tuple[Pair, ...]:
    """The capsule pairs the controller keeps apart: :func:`~qpik.robots.self_pairs.candidate_pairs` minus the
    allowed ones — ``allowed`` (capsule index pairs) if given, else the links an SRDF's ``disable_collisions``
    names (``srdf``), else :func:`~qpik.robots.self_pairs.default_allowed`."""
    if allowed is None and srdf is not None:
        from qpik.robots.srdf import disabled_links

        links = disabled_links(robot, srdf)
        caps = robot.capsules
        allowed = frozenset((c, e) for c, e in candidate_pairs(robot) if (caps[c].link, caps[e].link) in links)
    elif allowed is None:
        allowed = default_allowed(robot)
    else:
        allowed = frozenset(tuple(sorted(p)) for p in allowed)
    return tuple(p for p in candidate_pairs(robot) if p not in allowed)


def self_distance_expr(robot: Robot, q: ca.SX, pairs: tuple[Pair, ...]) -> list[tuple[ca.SX, list]]:
    """Per pair ``(d, row)``: the signed distance (m) and its rate :math:`n^T (J_c(p_c) - J_e(p_e))` (n,) at q."""
    from qpik.geometry.distance import pair_expr

    n = robot.dof
    frames = robot.chain.frames_expr([q[i] for i in range(n)], sy.CASADI)
    segments = robot.capsule_segments_expr(frames)
    radii, caps = robot.capsule_radii, robot.capsules
    out = []
    for c, e in pairs:
        (a, b), (qa, qb) = segments[c], segments[e]
        prm = [*qa, *sy.vsub(qb, qa), float(radii[e])]
        d, p_c, p_e, nrm, _ = pair_expr(a, b, float(radii[c]), "capsule", prm, sy.CASADI)
        jc = robot.chain.point_jacobian_expr(frames, p_c, caps[c].link)
        je = robot.chain.point_jacobian_expr(frames, p_e, caps[e].link)
        row = [sy.dot(nrm, jc[j]) if j < len(jc) else 0.0 for j in range(n)]
        row = [r - sy.dot(nrm, je[j]) if j < len(je) else r for j, r in enumerate(row)]
        out.append((d, row))
    return out


class SelfCollisionLimit(RowLimit):
    """Velocity dampers between the arm's own link capsules (module docstring).

    Args:
        allowed: capsule index pairs ``(c, e)`` never checked (None: from ``srdf``, else the default list of
            :func:`~qpik.robots.self_pairs.default_allowed`, computed once per robot).
        srdf: an SRDF file (path or text) whose ``disable_collisions`` give the allowed link pairs.
        d_influence: :math:`d_i`, m.
        d_safe: :math:`d_s`, m (< d_influence).
        xi: ξ, m/s (> 0), the largest approach speed, at :math:`d_i`.
        buffer: δ, m (≥ 0), added to d_s in the rows.
        brake: α, m/s² (None: off): with acceleration limits, rows beyond d_i slow an approach so that it
            reaches d_i at ξ (:func:`~qpik.control.limits.damper_lower`).
    """

    name = "self"

    def __init__(
        self,
        allowed: frozenset[Pair] | None = None,
        srdf: str | os.PathLike | None = None,
        d_influence: float = 0.06,
        d_safe: float = 0.01,
        xi: float = 0.5,
        buffer: float = 1e-3,
        brake: float | None = None,
    ):
        self.allowed = None if allowed is None else frozenset(allowed)
        self.srdf = srdf
        self.d_influence = number(d_influence, "d_influence", minimum=None)
        self.d_safe = number(d_safe, "d_safe", minimum=None)
        self.xi = number(xi, "xi", minimum=None)
        self.buffer = number(buffer, "buffer", minimum=None)
        if not self.d_safe + self.buffer < self.d_influence:
            raise InfeasibleError("SelfCollisionLimit: need d_safe + buffer < d_influence")
        if self.xi <= 0 or self.buffer < 0:
            raise InputError("SelfCollisionLimit: need xi > 0 and buffer >= 0")
        self.brake = None if brake is None else number(brake, "brake")
        self._checked: tuple[Pair, ...] = ()

    def pairs(self, robot: Robot) -> tuple[Pair, ...]:
        """The checked capsule pairs for ``robot`` (:func:`checked_pairs`, built once per robot: ``robot.cache``)."""
        srdf = None if self.srdf is None else str(self.srdf)
        key = ("self-collision pairs", self.allowed, srdf)
        return robot.cache.get(key, checked_pairs, robot, self.allowed, srdf)

    def check(self, robot: Robot, dt: float) -> None:
        self._checked = self.pairs(robot)
        if self.xi * dt > self.d_influence - self.d_safe - self.buffer:
            raise InfeasibleError("SelfCollisionLimit: xi·dt exceeds d_influence - d_safe - buffer")

    def size(self, robot: Robot) -> int:
        return len(self.pairs(robot))

    def row_names(self, robot: Robot) -> list[str]:
        """``"self link<k> / link<l>"`` per pair."""
        caps = robot.capsules
        return [f"self link{caps[c].link} / link{caps[e].link}" for c, e in self.pairs(robot)]

    def structure(self) -> tuple:
        return (self._checked, self.brake)

    def param_layout(self, n: int) -> Layout:
        return Layout(d_influence=(), d_safe=(), xi=())

    def param_values(self) -> dict[str, float]:
        return {"d_influence": self.d_influence, "d_safe": self.d_safe + self.buffer, "xi": self.xi}

    def distances_expr(self, s: SymState) -> ca.SX:
        """The checked pairs' signed distances (P,), m (SX)."""
        found = self_distance_expr(s.kin.robot, s.q, self.pairs(s.kin.robot))
        return ca.vertcat(*[d for d, _ in found]) if found else ca.SX(0, 1)

    def expr(self, s: SymState, p: Blocks, lb: ca.SX, ub: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        found = self_distance_expr(s.kin.robot, s.q, self.pairs(s.kin.robot))
        if not found:
            return ca.SX(0, s.n), ca.SX(0, 1), ca.SX(0, 1)
        A = ca.vertcat(*[ca.horzcat(*row) for _, row in found])
        h = ca.vertcat(*[d for d, _ in found])
        lower = damper_lower(A, h, p, lb, ub, caps=s.caps, brake=self.brake)
        return A, lower, ca.SX(A.shape[0], 1) + ca.inf

    def distances(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """The checked pairs' signed distances (P,), m, at q (n,), rad (numbers)."""
        from qpik.robots.self_pairs import pair_distances

        return pair_distances(robot, q, self.pairs(robot))[0]
