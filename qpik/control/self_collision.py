r"""Self-collision: velocity dampers that keep the arm's own link capsules apart.

Rows per checked pair of capsules ``(c, e)`` on links ``k < l`` (:func:`checked_pairs`), with the
capsule–capsule distance ``d`` (m), the witness point :math:`p_e` on the surface of capsule ``e`` and the unit
normal ``n`` from ``e`` toward ``c`` (:func:`~qpik.geometry.distance.pair_expr`). As for a box or a capsule
obstacle (:class:`~qpik.control.limits.obstacle.ObstacleLimit`), one witness row is not enough: where the axes are near
parallel the witness jumps along them from one step to the next, and the row of the old witness does not see the
part that approaches next. So each pair gets two rows, the end points :math:`x_0 = a`, :math:`x_1 = b` of
capsule ``c``'s axis against the *separating plane* of the step through :math:`p_e` with normal ``n``, **attached
to link l** (it moves with capsule ``e``):

.. math::  h_i = n^T (x_i - p_e) - r_c, \qquad \dot h_i = n^T \big(J_k(x_i) - J_l(x_i)\big)\, v

(the rate of a point's height over a plane moving with link l is the normal part of its velocity relative to
link l's motion at that point: :math:`\dot n^T (x - p) = -n^T (\omega_l \times (x - p))`; the point Jacobians
are those of :meth:`~qpik.robots.chain.SerialChain.point_jacobian_expr`, zero columns for the joints beyond each
link). Capsule ``e`` is convex and :math:`p_e` its point nearest to ``c``'s axis, so ``e`` lies behind the plane,
and stays so as the plane moves with it; the distance of ``c``'s axis to the plane is :math:`\min_i h_i + r_c`
(an affine function along a segment is least at an end), so :math:`d \ge \min_i h_i` after any motion. The
witness row is a convex combination of the two, implied. A pair of which capsule ``c`` is a point swaps the
roles; two points (a C¹ distance) get one witness row, :math:`h = d`. Each row is the damper of
:class:`~qpik.control.limits.obstacle.ObstacleLimit`:

.. math::  \dot h_i \;\ge\; -\xi\,\frac{h_i - d_s}{d_i - d_s}  \qquad (h_i < d_i)

with the same relaxation of a demand to separate (:func:`~qpik.control.limits.damper.damper_lower`); ``buffer`` δ
raises d_s for the rows, as for obstacles, to absorb the second-order terms of the motion.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.control.limits.base import RowLimit
from qpik.control.limits.damper import damper_lower, damper_recovery
from qpik.control.state import SymState
from qpik.core.errors import InfeasibleError, InputError
from qpik.core.layout import Blocks, Layout
from qpik.core.validate import number
from qpik.robots.self_pairs import Pair, checked_pairs

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


def row_layout(robot: Robot, pairs: tuple[Pair, ...]) -> tuple[tuple[int, int, int], ...]:
    """``(pair index, end, swapped)`` per row (module docstring): ``end`` 0 or 1 for the ends of the capsule
    against the other's plane, -1 for a witness row; ``swapped`` 1 when the pair's second capsule gives the ends
    (its first is a point)."""
    point = [not np.any(np.asarray(cap.p0) != np.asarray(cap.p1)) for cap in robot.capsules]
    out = []
    for k, (c, e) in enumerate(pairs):
        if point[c] and point[e]:
            out.append((k, -1, 0))
        else:
            out += [(k, 0, int(point[c])), (k, 1, int(point[c]))]
    return tuple(out)


def self_distance_expr(robot: Robot, q: ca.SX, pairs: tuple[Pair, ...]) -> tuple[list, list[tuple[ca.SX, list]]]:
    r"""``(d, rows)``: per pair the signed distance (m) at q, and per row of :func:`row_layout` ``(h, rate)``,
    its height (m) and :math:`\dot h` per unit v (n,) (module docstring)."""
    from qpik.geometry.distance import pair_expr

    n, chain = robot.dof, robot.chain
    frames = chain.frames_expr([q[i] for i in range(n)], sy.CASADI)
    segments = robot.capsule_segments_expr(frames)
    radii, caps = robot.capsule_radii, robot.capsules
    layout = row_layout(robot, pairs)
    found = {}  # pair index -> (first, second, pair_expr of first's axis to second)
    for k, _, swapped in layout:
        first, second = pairs[k][::-1] if swapped else pairs[k]
        (a, b), (qa, qb) = segments[first], segments[second]
        prm = [*qa, *sy.vsub(qb, qa), float(radii[second])]
        found[k] = (first, second, pair_expr(a, b, float(radii[first]), "capsule", prm, sy.CASADI))
    rows = []
    for k, end, _ in layout:
        first, second, (d, p_first, p_second, nrm, _) = found[k]
        point = p_first if end < 0 else segments[first][end]
        h = d if end < 0 else sy.dot(nrm, sy.vsub(point, p_second)) - float(radii[first])
        own = chain.point_jacobian_expr(frames, point, caps[first].link)
        other = chain.point_jacobian_expr(frames, point if end >= 0 else p_second, caps[second].link)
        rate = [sy.dot(nrm, own[j]) if j < len(own) else 0.0 for j in range(n)]
        rate = [r - sy.dot(nrm, other[j]) if j < len(other) else r for j, r in enumerate(rate)]
        rows.append((h, rate))
    return [found[k][2][0] for k in range(len(pairs))], rows


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
            reaches d_i at ξ, lowered where α cannot follow it (:func:`~qpik.control.limits.damper.damper_lower`).
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
        return len(row_layout(robot, self.pairs(robot)))

    def row_names(self, robot: Robot) -> list[str]:
        """``"self link<k> / link<l>"`` per row, with ``" end a"`` / ``" end b"`` (of the capsule whose ends the
        row holds: link k's, or link l's where link k's capsule is a point)."""
        caps, pairs = robot.capsules, self.pairs(robot)
        ends = {-1: "", 0: " end a", 1: " end b"}
        return [f"self link{caps[pairs[k][0]].link} / link{caps[pairs[k][1]].link}{ends[e]}"
                for k, e, _ in row_layout(robot, pairs)]  # fmt: skip

    def structure(self) -> tuple:
        return (self._checked, self.brake)

    def param_layout(self, n: int) -> Layout:
        return Layout(d_influence=(), d_safe=(), xi=())

    def param_values(self) -> dict[str, float]:
        return {"d_influence": self.d_influence, "d_safe": self.d_safe + self.buffer, "xi": self.xi}

    def distances_expr(self, s: SymState) -> ca.SX:
        """The checked pairs' signed distances (P,), m (SX)."""
        found = self_distance_expr(s.kin.robot, s.q, self.pairs(s.kin.robot))[0]
        return ca.vertcat(*found) if found else ca.SX(0, 1)

    def expr(self, s: SymState, p: Blocks, lb: ca.SX, ub: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        rows = self_distance_expr(s.kin.robot, s.q, self.pairs(s.kin.robot))[1]
        if not rows:
            return ca.SX(0, s.n), ca.SX(0, 1), ca.SX(0, 1)
        A = ca.vertcat(*[ca.horzcat(*rate) for _, rate in rows])
        h = ca.vertcat(*[height for height, _ in rows])
        lower = damper_lower(A, h, p, lb, ub, caps=s.caps, brake=self.brake)
        return A, lower, ca.SX(A.shape[0], 1) + ca.inf

    def recovery_expr(self, s: SymState, p: Blocks) -> ca.SX:
        r"""The damper's separating speed below :math:`d_s + \delta` (R,), m/s
        (:func:`~qpik.control.limits.damper.damper_recovery`)."""
        rows = self_distance_expr(s.kin.robot, s.q, self.pairs(s.kin.robot))[1]
        if not rows:
            return ca.SX(0, 1)
        h = ca.vertcat(*[height for height, _ in rows])
        return damper_recovery(h, p, self.brake)

    def heights(self, robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(h, A)``: the rows' heights (R,), m, and rates (R, n) at q (n,), rad (numbers; :func:`row_layout`)."""
        fn = robot.cache.get(("self-collision rows", self.pairs(robot)), _rows_function, robot, self.pairs(robot))
        h, A = fn(np.asarray(q, dtype=float))
        return np.asarray(h).reshape(-1), np.asarray(A)

    def distances(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """The checked pairs' signed distances (P,), m, at q (n,), rad (numbers)."""
        from qpik.robots.self_pairs import pair_distances

        return pair_distances(robot, q, self.pairs(robot))[0]


def _rows_function(robot: Robot, pairs: tuple[Pair, ...]) -> ca.Function:
    """CasADi ``q -> (h (R,), A (R, n))`` of :func:`self_distance_expr`'s rows."""
    q = ca.SX.sym("q", robot.dof)
    rows = self_distance_expr(robot, q, pairs)[1]
    A = ca.vertcat(*[ca.horzcat(*rate) for _, rate in rows]) if rows else ca.SX(0, robot.dof)
    h = ca.vertcat(*[height for height, _ in rows]) if rows else ca.SX(0, 1)
    return ca.Function("self_rows", [q], [h, A])
