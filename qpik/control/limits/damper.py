r"""The bounds of velocity-damper rows ``A v ≥ l``, shared by the obstacle and self-collision limits.

:func:`damper_lower`: :math:`l = -\xi (h - d_s)/(d_i - d_s)` (+ the other body's approach speed) for rows of
height :math:`h < d_i`, capped so that each row alone can be met inside the velocity box, and with a
deceleration α (m/s²) lowered to what α can follow; :func:`damper_recovery`: the part of l that asks a row
below :math:`d_s` to separate; :func:`braked_xi`: ξ under α. Heights and distances in m, speeds in m/s.
"""

from __future__ import annotations

import casadi as ca


def damper_lower(
    A: ca.SX,
    h: ca.SX,
    gains,
    lb: ca.SX,
    ub: ca.SX,
    approach: ca.SX | float = 0.0,
    caps: tuple[ca.SX, ca.SX] | None = None,
    brake: ca.SX | None = None,
) -> ca.SX:
    r"""Lower bounds (m,) of velocity-damper rows ``A v ≥ l`` (A (m, n), heights h (m,), m, box ``lb ≤ v ≤ ub``):
    :math:`l = -\xi (h - d_s)/(d_i - d_s) + \text{approach}` where :math:`h < d_i` and a joint moves the row,
    else −∞ (``approach`` (m,): the other body's speed toward this one along the row, m/s). ``gains``: the
    limit's parameters (:meth:`~qpik.control.state.SymState.params_of`), :math:`d_i` ``d_influence`` and
    :math:`d_s` ``d_safe`` (m), ξ ``xi`` (m/s).

    The bound is capped so that each row alone can be met in the box widened toward ``v = 0`` within the
    caps' own box ``caps`` (:math:`B_0`: the velocity, acceleration and jerk limits; without ``caps``,
    widened to contain 0): at the larger of :math:`r_0 - \tfrac12 |r_0|` with
    :math:`r_0 = \max_{v \in B_0} a^T v` (half of it when :math:`r_0 \ge 0`, see
    :class:`~qpik.control.limits.obstacle.ObstacleLimit`) and
    :math:`\max_{v \in B} a^T v - \tfrac14 \sum_j |a_j| (ub_j - lb_j)`. The two agree for a box symmetric
    about 0; the second lets a narrow box around the last command
    (:class:`~qpik.control.limits_motion.AccelerationLimit`) grow the separating speed by half its width per
    step. Where the caps cannot stop an approach in time the row asks only what they allow (the clearance may
    then fall below :math:`d_s`; the acceleration and jerk limits are kept).

    With ``brake`` α (m/s², a deceleration along the row that the acceleration limits can give), the approach
    is one that a deceleration α can follow (the damper assumes an arm that can stop at once; with acceleration
    limits it cannot). Inside :math:`d_i` the damper's bound falls at the rate :math:`\xi/(d_i - d_s)` per unit
    of approach, so an approach on it decelerates by up to :math:`\xi^2/(d_i - d_s)`: ξ is lowered to
    :math:`\xi_\alpha = \min(\xi, \sqrt{\alpha (d_i - d_s)})`, which keeps that within α. Rows beyond
    :math:`d_i` apply too, with the braking profile :math:`\dot h \ge -\sqrt{\xi_\alpha^2 + 2\alpha (h - d_i)}`:
    an approach is slowed at α early enough to reach :math:`d_i` at :math:`\xi_\alpha`. Both only ask for a
    slower approach than without ``brake``.
    """
    m = A.shape[0]
    d_i, ds = gains.d_influence, gains.d_safe
    xi = braked_xi(gains.xi, d_i, ds, brake)
    lower = (-xi / (d_i - ds)) * (h - ds) + approach
    lo0, hi0 = ca.fmin(lb, 0.0), ca.fmax(ub, 0.0)
    if caps is not None:
        lo0, hi0 = ca.fmax(lo0, caps[0]), ca.fmin(hi0, caps[1])
    LB, UB = ca.repmat(lb.T, m, 1), ca.repmat(ub.T, m, 1)
    reach0 = ca.sum2(ca.fmax(A * ca.repmat(lo0.T, m, 1), A * ca.repmat(hi0.T, m, 1)))
    reach = ca.sum2(ca.fmax(A * LB, A * UB)) - 0.25 * ca.sum2(ca.fabs(A) * (UB - LB))
    cap = ca.fmax(reach0 - 0.5 * ca.fabs(reach0), reach)
    moved = ca.sum2(ca.fabs(A)) > 1e-12  # a row no joint moves is left out
    near = h < d_i
    if brake is not None:
        lower = ca.if_else(near, lower, -ca.sqrt(xi * xi + 2.0 * brake * ca.fmax(h - d_i, 0.0)) + approach)
        near = h == h  # every row applies
    return ca.if_else(ca.logic_and(near, moved), ca.fmin(lower, cap), -ca.inf)


def braked_xi(xi: ca.SX, d_i: ca.SX, ds: ca.SX, brake: ca.SX | None) -> ca.SX:
    r"""ξ (m/s) of a damper, lowered to :math:`\sqrt{\alpha (d_i - d_s)}` with ``brake`` α (:func:`damper_lower`)."""
    return xi if brake is None else ca.fmin(xi, ca.sqrt(brake * (d_i - ds)))


def damper_recovery(h: ca.SX, gains, brake: ca.SX | None = None) -> ca.SX:
    r"""The part (m,), m/s, ≥ 0, of the damper bounds of :func:`damper_lower` that asks rows of heights h (m,)
    below d_s to separate: :math:`\xi (d_s - h)/(d_i - d_s)` there, else 0 (the obstacle's approach excluded).
    ``gains``: as for :func:`damper_lower`."""
    d_i, ds = gains.d_influence, gains.d_safe
    return ca.fmax((braked_xi(gains.xi, d_i, ds, brake) / (d_i - ds)) * (ds - h), 0.0)
