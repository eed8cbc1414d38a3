r"""Velocity dampers between the link capsules and the obstacles: :class:`ObstacleLimit`.

One or two rows per (capsule, obstacle) pair, :math:`n^T J_p v \ge -\xi (h - d_s)/(d_i - d_s)` (heights h
and distances in m, ξ in m/s; their bounds: :mod:`qpik.control.limits.damper`), with the obstacles in the
base frame, standing still or moving at given or estimated velocities (m/s, rad/s).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.control.limits.base import RowLimit
from qpik.control.limits.damper import damper_lower, damper_recovery
from qpik.control.state import SymState, kinematics_of
from qpik.core.errors import InfeasibleError, InputError
from qpik.core.layout import Blocks, Layout
from qpik.core.validate import finite_array, joint_vector, number

if TYPE_CHECKING:
    from qpik.geometry.distance import ObstacleSet
    from qpik.geometry.shapes import Shape
    from qpik.robots.robot import Robot


class ObstacleLimit(RowLimit):
    r"""Velocity dampers that keep every link capsule away from every obstacle.

    Rows per (capsule c, obstacle o) pair (:meth:`~qpik.control.state.Kinematics.damper_layout`),
    each with a height :math:`h \ge d` (m) and its rate :math:`\dot h = n^T J_p(x)\, v`; a row is
    active when :math:`h < d_i` (influence distance):

    .. math::  n^T J_p(x)\, v \;\ge\; -\xi\,\frac{h - d_s}{d_i - d_s}

    with the unit normal ``n`` from the obstacle toward the capsule and the point Jacobian
    :math:`J_p` (the geometry contract :math:`\dot d = n^T J_p \dot q`,
    :mod:`qpik.geometry.distance`). ξ (m/s) is the largest approach speed, allowed at
    :math:`h = d_i`; it falls linearly to 0 at :math:`d_s`, and below :math:`d_s` the row
    demands a separating speed :math:`\xi (d_s - h)/(d_i - d_s)`.

    - A sphere (whose distance to a capsule is C¹ in q), or any obstacle against a link
      capsule that is a point, gets one row: the witness point :math:`x = p_{link}`, :math:`h = d`.
    - A box, a half-space or a capsule gets two: the capsule's axis end points against the
      separating plane through the obstacle's witness point :math:`p_{obs}` with normal ``n``,
      :math:`h_e = n^T(x_e - p_{obs}) - r`. With one witness point, a link sliding along a face
      (its axis nearly parallel to it) has its witness jump along the axis whenever the tilt
      changes sign, and the row of the old witness does not see the part that approaches
      next: a first-order error. The obstacle lies behind
      the plane, and the capsule's distance to the plane is :math:`\min_e h_e` (an affine
      function along the axis is least at an end), so :math:`d_{k+1} \ge \min_e h_e(q_{k+1})`
      whatever feature of the obstacle is nearest next; the witness row itself is a convex
      combination of the two and is implied. The price is caution: at :math:`h \approx d_s`
      neither end may approach the plane, so a link cannot pivot about an edge it touches.

    Discrete time: with :math:`q_{k+1} = q_k + v\,dt`, to first order
    :math:`h_{k+1} - d_s \ge (1 - \gamma)(h_k - d_s)` with :math:`\gamma = \xi\,dt/(d_i - d_s)`,
    so ``check`` requires γ ≤ 1 (no overshoot in one step). The second-order term of the
    motion (the curvature of the points' paths, ~|ω|²·r·dt² per step) is not linear in v;
    ``buffer`` (m) raises the safety distance seen by the rows to :math:`d_s + \delta` so that
    these terms, which accumulate to about (per-step term)/γ, stay above :math:`d_s`.

    Feasibility: ``v = 0`` meets every row with :math:`h \ge d_s + \delta`. A row that
    demands separation (:math:`h < d_s + \delta`, the arm starts inside the safety distance)
    is relaxed to what the box allows: its bound is capped at half of
    :math:`\max_{v \in B_0} a^T v = \sum_j \max(a_j lb_j^0, a_j ub_j^0)` over the box widened
    to contain ``v = 0``, :math:`lb^0 = \min(lb, 0)`, :math:`ub^0 = \max(ub, 0)` (it differs
    from the box only where a joint past a position limit is made to move back), so that the
    rows never demand what only a return from a limit could give: each row alone can be met
    inside :math:`B_0`. (Several separating rows at once, or rows against a box that forces a joint
    back from past its limit toward the obstacle, can still conflict: the controller then
    lets safety win, see :class:`~qpik.control.controller.Controller`.) A capsule that no joint
    moves (the base column, :attr:`~qpik.robots.robot.Robot.fixed_capsules`) has no rows, and a row
    that no joint moves at this configuration (a zero row) is left out.

    Args:
        obstacles: shapes of :mod:`qpik.geometry` (world frame).
        d_influence: :math:`d_i`, m.
        d_safe: :math:`d_s`, m (< d_influence).
        xi: ξ, m/s (> 0).
        buffer: δ, m (≥ 0).
        brake: α, m/s² (None: off): with acceleration limits, rows beyond d_i slow an approach so that it
            reaches d_i at ξ, lowered where α cannot follow it (:func:`~qpik.control.limits.damper.damper_lower`).
        moving: the rows take the obstacles' velocities (:meth:`set_velocities`, :meth:`move`,
            :meth:`translate`); off, the obstacles are taken as standing still and the rows cost less.

    Moving obstacles: an obstacle moving at :math:`v_o` and :math:`\omega_o` (:meth:`set_velocities`, or
    estimated from its poses by :meth:`move`) closes the row's height at :math:`n^T v_o(p_{obs})`, so the
    row is :math:`n^T (J_p v - v_o(p_{obs})) \ge -\xi (h - d_s)/(d_i - d_s)`. A row alone can hold only while
    the arm can move that part away at the obstacle's speed, :math:`\max_{v \in B} n^T J_p v \ge n^T v_o`
    within the box B of the velocity (and acceleration) limits. The rows share one ``v``: with an obstacle
    near several links (between two of them, or past links that few joints move, as the shoulder) the
    clearance holds only while one ``v`` within the limits meets every row at once, and the acceleration
    limits reach it before the obstacle covers its gap to d_s; each row meeting its own condition is not
    enough. When the rows cannot be met, each asks at most what the box allows and conflicting ones are
    relaxed (the least-bad motion: the fastest retreat the limits permit), the clearance falls, and the
    status says so: ``"recovering"`` inside d_s, ``"penetrating"`` at d < 0.
    """

    name = "obstacle"

    def __init__(
        self,
        obstacles: Sequence[Shape],
        d_influence: float = 0.10,
        d_safe: float = 0.02,
        xi: float = 0.5,
        buffer: float = 1e-3,
        brake: float | None = None,
        moving: bool = False,
    ):
        from qpik.geometry.distance import RECORDS, REFERENCE, ObstacleSet, set_layout

        self.obstacles = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
        self.d_influence = number(d_influence, "d_influence", minimum=None)
        self.d_safe = number(d_safe, "d_safe", minimum=None)
        self.xi = number(xi, "xi", minimum=None)
        self.buffer = number(buffer, "buffer", minimum=None)
        if not self.d_safe + self.buffer < self.d_influence:
            raise InfeasibleError("ObstacleLimit: need d_safe + buffer < d_influence")
        if self.xi <= 0 or self.buffer < 0:
            raise InputError("ObstacleLimit: need xi > 0 and buffer >= 0")
        self.moving = bool(moving)
        # per obstacle its reference point, a view into the packed parameters (None for a half-space), for translate
        kinds = self.obstacles.kinds
        records = set_layout(kinds).views(self.obstacles.params).values()
        self._points = [None if REFERENCE[k] is None else RECORDS[k].views(r)[REFERENCE[k]]
                        for k, r in zip(kinds, records)]  # fmt: skip
        self.velocities = np.zeros((len(self.obstacles), 6))
        self.brake = None if brake is None else number(brake, "brake")

    def check(self, robot: Robot, dt: float) -> None:
        if self.xi * dt > self.d_influence - self.d_safe - self.buffer:
            raise InfeasibleError(
                f"ObstacleLimit: xi·dt = {self.xi * dt:g} m exceeds d_influence - d_safe - buffer; "
                "the damper would overshoot d_safe in one step"
            )

    def size(self, robot: Robot) -> int:
        return len(kinematics_of(robot).damper_layout(self.obstacles.kinds))

    def row_names(self, robot: Robot) -> list[str]:
        """``"obstacle <name> / link<k>"``, with ``" end a"`` / ``" end b"`` for the two rows of a separating plane."""
        names = [sh.name or f"{type(sh).__name__.lower()}{o}" for o, sh in enumerate(self.obstacles.shapes)]
        ends = {-1: "", 0: " end a", 1: " end b"}
        layout = kinematics_of(robot).damper_layout(self.obstacles.kinds)
        return [f"obstacle {names[o]} / link{robot.capsules[c].link}{ends[e]}" for c, o, e in layout]

    def param_layout(self, n: int) -> Layout:
        moving = {"velocities": (len(self.obstacles), 6)} if self.moving else {}
        return Layout(d_influence=(), d_safe=(), xi=(), **moving)

    def param_values(self) -> dict[str, object]:
        return {
            "d_influence": self.d_influence,
            "d_safe": self.d_safe + self.buffer,
            "xi": self.xi,
            **({"velocities": self.velocities} if self.moving else {}),
        }

    def structure(self) -> tuple:
        return (self.obstacles.kinds, self.brake, self.moving)

    def distances_expr(self, s: SymState) -> ca.SX:
        """Signed distances (C·O,) of every capsule–obstacle pair, m (SX)."""
        return s.distances(self.obstacles)

    def set_velocities(self, velocities: np.ndarray) -> None:
        """Set the obstacles' velocities (O, 6) ``[v; ω]``, m/s and rad/s, world frame, ω about each shape's
        reference point (a sphere's centre, a capsule's ``p0``, a box's centre; a half-space's origin)."""
        self._need_moving()
        self.velocities = finite_array(velocities, "velocities", (len(self.obstacles), 6)).copy()

    def move(self, shapes: Sequence[Shape], dt: float | None = None, velocities: np.ndarray | None = None) -> None:
        """Move the obstacles to ``shapes`` (the same families in the same order; the rows keep their form).

        With ``velocities`` (O, 6) they are set as in :meth:`set_velocities`; else, with ``dt`` (s, the time
        since the last poses), the linear velocity of each reference point is estimated by the difference
        (angular velocity 0); with neither, the velocities are kept.
        """
        from qpik.geometry.distance import ObstacleSet

        new = ObstacleSet(shapes)
        if new.kinds != self.obstacles.kinds:
            raise InputError("move: shapes must keep the obstacles' families and order")
        if velocities is not None:
            self.set_velocities(velocities)
        elif dt is not None:
            dt = number(dt, "dt", minimum=None)
            if dt <= 0:
                raise InputError("dt: must be > 0")
            self._need_moving()
            v = np.zeros((len(new), 6))
            v[:, :3] = (_reference_points(new) - _reference_points(self.obstacles)) / dt
            self.velocities = v
        self.obstacles.params[:] = new.params  # read by the compiled step at every call

    def translate(self, o: int, point: np.ndarray, velocity: np.ndarray) -> None:
        """Move obstacle ``o`` (a sphere, capsule or box) rigidly so that its reference point (a sphere's centre,
        a capsule's ``p0``, a box's centre) is ``point`` (3,), m, moving at ``velocity`` (6,) ``[v; ω]``: the
        cheap update of one moving obstacle in a control loop (no shape is rebuilt)."""
        self._need_moving()
        if not 0 <= o < len(self._points) or self._points[o] is None:
            raise InputError(f"translate: obstacle {o} is not a sphere, capsule or box of this limit")
        point, many = joint_vector(point, 3, "point")  # a vector of 3 (one check in C), as velocity's of 6
        velocity, more = joint_vector(velocity, 6, "velocity")
        if many or more:
            raise InputError("translate: point must have shape (3,) and velocity (6,)")
        self._points[o][:] = point
        self.velocities[o] = velocity

    def _need_moving(self) -> None:
        if not self.moving:
            raise InputError("ObstacleLimit: give moving=True to use obstacle velocities (the rows' form is fixed)")

    def approach_expr(self, s: SymState, p: Blocks) -> ca.SX:
        r"""Per row, the obstacle's speed toward the link :math:`n^T (v_o + \omega_o \times (p_{obs} - c_o))` (R,),
        m/s, with the pair's normal and obstacle witness point (for the two rows of a separating plane, the
        plane's own motion)."""
        w = s.witnesses(self.obstacles)
        refs = _reference_points(self.obstacles, s.obstacle_params(self.obstacles))
        O = len(self.obstacles)
        out = []
        for c, o, _ in s.kin.damper_layout(self.obstacles.kinds):
            k = c * O + o
            n, p_obs = w.normal[3 * k : 3 * k + 3], w.p_obs[3 * k : 3 * k + 3]
            vel = p.velocities[o, :3].T + ca.cross(p.velocities[o, 3:].T, p_obs - refs[o])
            out.append(ca.dot(n, vel))
        return ca.vertcat(*out) if out else ca.SX(0, 1)

    def recovery_expr(self, s: SymState, p: Blocks) -> ca.SX:
        r"""The damper's separating speed below :math:`d_s + \delta` (R,), m/s
        (:func:`~qpik.control.limits.damper.damper_recovery`)."""
        return damper_recovery(s.damper_heights(self.obstacles), p, self.brake)

    def expr(self, s: SymState, p: Blocks, lb: ca.SX, ub: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        # every row (fixed shape, from the step's compiled kinematics); rows beyond d_i get l = -inf
        A = s.damper_rows(self.obstacles)
        h = s.damper_heights(self.obstacles)
        approach = self.approach_expr(s, p) if self.moving else 0.0
        lower = damper_lower(A, h, p, lb, ub, approach, s.caps, self.brake)
        return A, lower, ca.SX(A.shape[0], 1) + ca.inf


def _reference_points(obstacles: ObstacleSet, symbolic: ca.SX | None = None) -> list | np.ndarray:
    """Each obstacle's reference point: (O, 3) numbers, or with the packed parameters ``symbolic`` a list of
    (3,) SX (a half-space's is the origin)."""
    from qpik.geometry.distance import RECORDS, REFERENCE, set_layout

    layout, out = set_layout(obstacles.kinds), []
    if symbolic is None:
        for kind, record in zip(obstacles.kinds, layout.views(obstacles.params).values()):
            out.append(np.zeros(3) if REFERENCE[kind] is None else RECORDS[kind].views(record)[REFERENCE[kind]])
        return np.array(out, dtype=float).reshape(-1, 3)
    for kind, record in zip(obstacles.kinds, layout.symbols(symbolic).values()):
        out.append(ca.SX.zeros(3) if REFERENCE[kind] is None else RECORDS[kind].symbols(record)[REFERENCE[kind]])
    return out
