r"""The interval rule of every CasADi SX operation: bounds ``[lo, hi]`` of its result from bounds of its arguments.

A :class:`Range` is a pair of SX expressions (lower, upper bound) or a single value (``point``: no
interval overhead for what depends on no interval input). The rules (the *natural interval
extension*, Moore, Kearfott & Cloud 2009, ch. 5):

- ``x + y = [a + c, b + d]``, ``x − y = [a − d, b − c]``, ``x · y`` the hull of the four
  products (two when one factor is a single value, a square rule for ``x · x``),
  ``x / y`` the product with ``[1/d, 1/c]``, or ``[−BIG, BIG]`` when ``0 ∈ y``;
- monotone functions (sqrt, floor, exp, log, fmin, fmax) at the ends; ``|x|`` with its kink;
- ``sin`` and ``cos``: the values at the ends, widened to ±1 where a crest
  ``π/2 + 2πk`` (trough ``−π/2 + 2πk``) lies inside;
- ``atan2(y, x)``: the hull of the four corners, or ``[−π, π]`` when the box touches the
  cut ``{y = 0, x ≤ 0}`` (the angle of a box away from it is extreme at its corners);
- comparisons and logic give ``[0, 1]`` when undecided; ``if_else(c, a, b)`` (which SX
  stores as ``if_else_zero(c, a) + if_else_zero(!c, b)``, recognised by :func:`ternary`) gives
  ``a``, ``b`` or their hull, not the wider sum of the two halves.

Endpoints are computed in round-to-nearest floating point (no outward rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.core.errors import InputError

BIG = 1e300
"""Stands for an unbounded end (a division by an interval that contains 0)."""

PI = float(np.pi)


@dataclass(frozen=True)
class Range:
    """Bounds ``[lo, hi]`` of one value (SX); ``point``: a single value (``lo is hi``)."""

    lo: ca.SX
    hi: ca.SX
    point: bool

    @staticmethod
    def of(value: ca.SX) -> Range:
        return Range(value, value, True)


def pair(lo: ca.SX, hi: ca.SX) -> Range:
    return Range(lo, hi, False)


def hull(*values: ca.SX) -> tuple[ca.SX, ca.SX]:
    lo = hi = values[0]
    for v in values[1:]:
        lo, hi = ca.fmin(lo, v), ca.fmax(hi, v)
    return lo, hi


def truth(x: Range) -> tuple[ca.SX, ca.SX]:
    """``(surely, maybe)`` nonzero, as SX booleans."""
    if x.point:
        t = x.lo != 0
        return t, t
    return ca.logic_or(x.lo > 0, x.hi < 0), ca.logic_not(ca.logic_and(x.lo == 0, x.hi == 0))


def mul(x: Range, y: Range, same: bool) -> Range:
    if x.point and y.point:
        return Range.of(x.lo * y.lo)
    if same:
        return square(x)
    if y.point:
        x, y = y, x
    if x.point:
        a, b = x.lo * y.lo, x.lo * y.hi
        return pair(ca.fmin(a, b), ca.fmax(a, b))
    return pair(*hull(x.lo * y.lo, x.lo * y.hi, x.hi * y.lo, x.hi * y.hi))


def square(x: Range) -> Range:
    if x.point:
        return Range.of(x.lo * x.lo)
    a, b = x.lo, x.hi
    return pair(ca.if_else(a >= 0, a * a, ca.if_else(b <= 0, b * b, 0.0)), ca.fmax(a * a, b * b))


def div(x: Range, y: Range) -> Range:
    if x.point and y.point:
        return Range.of(x.lo / y.lo)
    if y.point:
        return mul(x, Range.of(1.0 / y.lo), False)
    q = mul(x, pair(1.0 / y.hi, 1.0 / y.lo), False)
    zero = ca.logic_and(y.lo <= 0, y.hi >= 0)
    return pair(ca.if_else(zero, -BIG, q.lo), ca.if_else(zero, BIG, q.hi))


def sin(a: ca.SX, b: ca.SX) -> Range:
    """sin over [a, b]: the ends, or ±1 where a crest/trough lies inside."""
    sa, sb = ca.sin(a), ca.sin(b)
    crest = ca.floor((b - PI / 2) / (2 * PI)) - ca.floor((a - PI / 2) / (2 * PI))
    trough = ca.floor((b + PI / 2) / (2 * PI)) - ca.floor((a + PI / 2) / (2 * PI))
    return pair(ca.if_else(trough >= 1, -1.0, ca.fmin(sa, sb)), ca.if_else(crest >= 1, 1.0, ca.fmax(sa, sb)))


def atan2(y: Range, x: Range) -> Range:
    if y.point and x.point:
        return Range.of(ca.atan2(y.lo, x.lo))
    cut = ca.logic_and(x.lo <= 0, ca.logic_and(y.lo <= 0, y.hi >= 0))
    ys = [y.lo] if y.point else [y.lo, y.hi]
    xs = [x.lo] if x.point else [x.lo, x.hi]
    lo, hi = hull(*[ca.atan2(a, b) for a in ys for b in xs])
    return pair(ca.if_else(cut, -PI, lo), ca.if_else(cut, PI, hi))


def monotone(fn, x: Range) -> Range:
    return Range.of(fn(x.lo)) if x.point else pair(fn(x.lo), fn(x.hi))


def binary_monotone(fn, x: Range, y: Range) -> Range:
    if x.point and y.point:
        return Range.of(fn(x.lo, y.lo))
    return pair(fn(x.lo, y.lo), fn(x.hi, y.hi))


def compare(op: int, x: Range, y: Range) -> Range:
    if x.point and y.point:
        exact = {ca.OP_LT: x.lo < y.lo, ca.OP_LE: x.lo <= y.lo, ca.OP_EQ: x.lo == y.lo, ca.OP_NE: x.lo != y.lo}
        return Range.of(exact[op])
    if op == ca.OP_LT:
        yes, no = x.hi < y.lo, x.lo >= y.hi
    elif op == ca.OP_LE:
        yes, no = x.hi <= y.lo, x.lo > y.hi
    else:
        apart = ca.logic_or(x.hi < y.lo, y.hi < x.lo)
        same = ca.logic_and(ca.logic_and(x.lo == x.hi, y.lo == y.hi), x.lo == y.lo)
        yes, no = (same, apart) if op == ca.OP_EQ else (apart, same)
    return pair(ca.if_else(yes, 1.0, 0.0), ca.if_else(no, 0.0, 1.0))


def logic(op: int, x: Range, y: Range | None) -> Range:
    if op == ca.OP_NOT:
        if x.point:
            return Range.of(ca.logic_not(x.lo))
        surely, maybe = truth(x)
        return pair(ca.if_else(maybe, 0.0, 1.0), ca.if_else(surely, 0.0, 1.0))
    if x.point and y.point:
        return Range.of(ca.logic_and(x.lo, y.lo) if op == ca.OP_AND else ca.logic_or(x.lo, y.lo))
    (s1, m1), (s2, m2) = truth(x), truth(y)
    join = ca.logic_and if op == ca.OP_AND else ca.logic_or
    return pair(ca.if_else(join(s1, s2), 1.0, 0.0), ca.if_else(join(m1, m2), 1.0, 0.0))


def select(c: Range, a: Range, b: Range) -> Range:
    """``if_else(c, a, b)``: a, b or (undecided c) their hull."""
    if c.point and a.point and b.point:
        return Range.of(ca.if_else(c.lo, a.lo, b.lo))
    surely, maybe = truth(c)
    if c.point:
        return pair(ca.if_else(surely, a.lo, b.lo), ca.if_else(surely, a.hi, b.hi))
    return pair(
        ca.if_else(surely, a.lo, ca.if_else(maybe, ca.fmin(a.lo, b.lo), b.lo)),
        ca.if_else(surely, a.hi, ca.if_else(maybe, ca.fmax(a.hi, b.hi), b.hi)),
    )


def if_else_zero(c: Range, a: Range) -> Range:
    if c.point and a.point:
        return Range.of(ca.if_else(c.lo, a.lo, 0.0))
    surely, maybe = truth(c)
    return pair(
        ca.if_else(surely, a.lo, ca.if_else(maybe, ca.fmin(a.lo, 0.0), 0.0)),
        ca.if_else(surely, a.hi, ca.if_else(maybe, ca.fmax(a.hi, 0.0), 0.0)),
    )


UNARY = {
    ca.OP_SQRT: lambda x: monotone(lambda v: ca.sqrt(ca.fmax(v, 0.0)), x) if not x.point else Range.of(ca.sqrt(x.lo)),
    ca.OP_FLOOR: lambda x: monotone(ca.floor, x),
    ca.OP_EXP: lambda x: monotone(ca.exp, x),
    ca.OP_LOG: lambda x: monotone(ca.log, x),
    ca.OP_TWICE: lambda x: monotone(lambda v: 2.0 * v, x),
    ca.OP_NEG: lambda x: Range.of(-x.lo) if x.point else pair(-x.hi, -x.lo),
    ca.OP_SQ: square,
    ca.OP_ASSIGN: lambda x: x,
    ca.OP_SIN: lambda x: Range.of(ca.sin(x.lo)) if x.point else sin(x.lo, x.hi),
    ca.OP_COS: lambda x: Range.of(ca.cos(x.lo)) if x.point else sin(x.lo + PI / 2, x.hi + PI / 2),
    ca.OP_FABS: lambda x: (
        Range.of(ca.fabs(x.lo))
        if x.point
        else pair(ca.if_else(x.lo >= 0, x.lo, ca.if_else(x.hi <= 0, -x.hi, 0.0)), ca.fmax(-x.lo, x.hi))
    ),
}


def rule(op: int, src: list[int], made: dict, value: dict) -> Range:
    """The interval rule of one instruction with source instructions ``src``."""
    x = value[src[0]]
    if op in UNARY:
        return UNARY[op](x)
    y = value[src[1]] if len(src) > 1 else None
    if op == ca.OP_ADD:
        parts = ternary(src, made)
        if parts is not None:
            c, a, b = (value[t] for t in parts)
            return select(c, a, b)
        return Range.of(x.lo + y.lo) if x.point and y.point else pair(x.lo + y.lo, x.hi + y.hi)
    if op == ca.OP_SUB:
        return Range.of(x.lo - y.lo) if x.point and y.point else pair(x.lo - y.hi, x.hi - y.lo)
    if op == ca.OP_MUL:
        return mul(x, y, src[0] == src[1])
    if op == ca.OP_DIV:
        return div(x, y)
    if op == ca.OP_FMIN:
        return binary_monotone(ca.fmin, x, y)
    if op == ca.OP_FMAX:
        return binary_monotone(ca.fmax, x, y)
    if op == ca.OP_ATAN2:
        return atan2(x, y)
    if op in (ca.OP_LT, ca.OP_LE, ca.OP_EQ, ca.OP_NE):
        return compare(op, x, y)
    if op in (ca.OP_NOT, ca.OP_AND, ca.OP_OR):
        return logic(op, x, y)
    if op == ca.OP_IF_ELSE_ZERO:
        return if_else_zero(x, y)
    names = {getattr(ca, n): n for n in dir(ca) if n.startswith("OP_")}
    raise InputError(f"fn: no interval rule for CasADi operation {names.get(op, op)}")


def ternary(src: list[int], made: dict) -> tuple[int, int, int] | None:
    """``(c, a, b)`` when the two sources are ``if_else_zero(c, a)`` and ``if_else_zero(!c, b)``, else None."""
    (op1, s1), (op2, s2) = made[src[0]], made[src[1]]
    if op1 != ca.OP_IF_ELSE_ZERO or op2 != ca.OP_IF_ELSE_ZERO:
        return None
    c1, c2 = s1[0], s2[0]
    if made[c2][0] == ca.OP_NOT and made[c2][1][0] == c1:
        return c1, s1[1], s2[1]
    if made[c1][0] == ca.OP_NOT and made[c1][1][0] == c2:
        return c2, s2[1], s1[1]
    return None
