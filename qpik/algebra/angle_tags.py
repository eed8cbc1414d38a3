r"""Angle tags for Taylor models: a value computed from an ``atan2`` keeps the vector it is the angle of.

An atan2 is discontinuous on its cut, and a closed form often turns it into a continuous angle
afterwards (adding π and wrapping, or choosing θ ± π by the sign of θ), which bounds evaluated
operation by operation cannot see. An :class:`Angle` records, for such a value, the vector
(x, y) (Taylor models), the constant added to :math:`\mathrm{atan2}(y, x)` and, when known, the
window (low, low + 2π] the value lies in; :func:`angle_rule` follows the tag through the forms
that keep it, and :func:`angle_model` gives the value's model as the atan2 of the vector turned
into that window (continuous unless the value leaves its window). Angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.algebra import interval_rules as iv
from qpik.algebra import taylor_models as tm


@dataclass(frozen=True)
class Angle:
    r"""What is known of an angle-valued value where ``valid`` (an SX boolean) holds: it equals
    :math:`\mathrm{atan2}(y, x) + \text{offset}` modulo 2π, and (``low`` not None) it lies in (low, low + 2π]."""

    y: tm.Model
    x: tm.Model
    offset: float
    low: float | None
    valid: ca.SX


_TWO_PI = 2.0 * iv.PI


def _near(a: float | None, b: float) -> bool:
    return a is not None and abs(a - b) < 1e-12 * (1.0 + abs(b))


def _rotated(y: tm.Model, x: tm.Model, cos: tm.Model, sin: tm.Model) -> tuple[tm.Model, tm.Model]:
    """The vector (x, y) turned by the angle with cosine ``cos`` and sine ``sin``: (y', x')."""
    yr = tm.add(tm.mul(x, sin, False), tm.mul(y, cos, False))
    xr = tm.sub(tm.mul(x, cos, False), tm.mul(y, sin, False))
    return yr, xr


def angle_model(a: Angle) -> tm.Model:
    r"""The model of an angle with a known window: :math:`\mathrm{atan2}(y'', x'') + low + π`, (x'', y'') the
    vector turned by offset − low − π, which is continuous wherever the value does not leave its window."""
    beta = a.offset - a.low - iv.PI
    cos, sin = tm.Model.of(ca.SX(float(np.cos(beta)))), tm.Model.of(ca.SX(float(np.sin(beta))))
    yr, xr = _rotated(a.y, a.x, cos, sin)
    shift = tm.Model.of(ca.SX(a.low + iv.PI))
    return tm.add(tm.atan2(yr, xr), shift)


def _wrapped_of(k: int, made: dict, consts: dict) -> int | None:
    """``x`` when instruction k is ``2π·floor((π − x)/2π)`` (the correction of
    :meth:`qpik.algebra.symbolic.Ops.wrap`)."""

    def split_const(i: int) -> tuple[float, int] | None:
        op, src = made[i]
        if op != ca.OP_MUL or len(src) != 2:
            return None
        a, b = src
        return (consts[a], b) if a in consts else ((consts[b], a) if b in consts else None)

    scaled = split_const(k)
    if scaled is None or not _near(scaled[0], _TWO_PI) or made[scaled[1]][0] != ca.OP_FLOOR:
        return None
    inner = made[scaled[1]][1][0]
    op, src = made[inner]
    if op == ca.OP_DIV and src[1] in consts and _near(consts[src[1]], _TWO_PI):
        top = src[0]
    else:
        found = split_const(inner)
        if found is None or not _near(found[0], 1.0 / _TWO_PI):
            return None
        top = found[1]
    op, src = made[top]
    if op != ca.OP_SUB or src[0] not in consts or not _near(consts[src[0]], iv.PI):
        return None
    return src[1]


def angle_rule(op: int, src: list[int], made: dict, consts: dict, value: dict, tags: dict) -> Angle | None:
    r"""The angle tag of an instruction (see :func:`~qpik.algebra.enclosure.taylor_function`), or None.

    Kept through: atan2 (the window (−π, π]); adding a constant (the window moves with it); adding an
    untagged value φ (the vector turns by φ; the window is lost); :meth:`~qpik.algebra.symbolic.Ops.wrap` (the
    window (−π, π]); ``where(t > −π, t, π)`` (the same angle); ``where(θ > c0, θ + α, θ + α + 2π)`` for θ
    in (−π, π] (the window (c0 + α, c0 + α + 2π], as the flip of a ZYZ triple); ``where(c, θ, 0)``
    (valid where c surely holds).
    """
    one = ca.SX(1.0)
    if op == ca.OP_ATAN2:
        return Angle(value[src[0]], value[src[1]], 0.0, -iv.PI, one)
    if op == ca.OP_IF_ELSE_ZERO and src[1] in tags:
        t = tags[src[1]]
        return Angle(t.y, t.x, t.offset, t.low, ca.logic_and(t.valid, iv.truth(value[src[0]].box)[0]))
    if op not in (ca.OP_ADD, ca.OP_SUB):
        return None
    a, b = src
    if op == ca.OP_ADD:
        ternary = iv.ternary(src, made)
        if ternary is not None:
            return _select_angle(*ternary, made, consts, tags)
        for x, w in ((a, b), (b, a)):
            if x in tags and _wrapped_of(w, made, consts) == x:
                t = tags[x]
                return Angle(t.y, t.x, t.offset, -iv.PI, t.valid)
    if op == ca.OP_SUB and b in consts and a in tags:
        t = tags[a]
        c = consts[b]
        return Angle(t.y, t.x, t.offset - c, None if t.low is None else t.low - c, t.valid)
    if op == ca.OP_ADD:
        for x, w in ((a, b), (b, a)):
            if x not in tags or w in tags:
                continue
            t = tags[x]
            if w in consts:
                c = consts[w]
                return Angle(t.y, t.x, t.offset + c, None if t.low is None else t.low + c, t.valid)
            turn = value[w]
            yr, xr = _rotated(t.y, t.x, tm.trig(turn, True), tm.trig(turn, False))
            return Angle(yr, xr, t.offset, None, t.valid)
    return None


def _select_angle(c: int, a: int, b: int, made: dict, consts: dict, tags: dict) -> Angle | None:
    """The angle tag of ``where(c, a, b)`` for the two forms of :func:`angle_rule`, or None."""
    cop, csrc = made[c]
    if cop != ca.OP_LT or csrc[0] not in consts:
        return None
    c0, theta = consts[csrc[0]], csrc[1]
    t = tags.get(theta)
    if t is None or not _near(t.low, -iv.PI):
        return None
    if a == theta and b in consts and _near(c0, -iv.PI) and _near(consts[b], iv.PI):
        return t  # where(t > −π, t, π): the same angle
    ta, tb = tags.get(a), tags.get(b)
    if ta is None or tb is None or ta.y is not t.y or tb.y is not t.y or ta.x is not t.x or tb.x is not t.x:
        return None
    alpha = ta.offset - t.offset
    if not _near(tb.offset - ta.offset, _TWO_PI):
        return None
    return Angle(t.y, t.x, ta.offset, c0 + alpha, t.valid)
