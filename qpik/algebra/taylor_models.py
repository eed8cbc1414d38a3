r"""First-order Taylor models in one variable and their arithmetic: ``c + s·t ± r`` for t ∈ [−1, 1].

A :class:`Model` keeps a value over a box as its centre c, its slope s along the common variable
t and a remainder radius r (Makino & Berz 2003), beside its interval bounds
(:class:`~qpik.algebra.interval_rules.Range`); every rule intersects the two. Linear operations are
exact in (c, s, r); a product adds the product of the spreads :math:`|s| + r` to the remainder; a
smooth f uses Taylor's theorem about c, :math:`|R| \le \tfrac12 M (|s| + r)^2` with M a bound of
:math:`|f''|` over the argument's interval (1/x, √x and log where that interval excludes 0, sin,
cos, exp, atan2 away from its cut and the origin). Elsewhere (floor, comparisons, undecided
selections) a model is the interval bounds with no slope (:func:`hull`). :func:`rule` is the model
of one SX instruction.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from qpik.algebra import interval_rules as iv
from qpik.core.errors import InputError


@dataclass(frozen=True)
class Model:
    r"""A value over the box: :math:`c + s\,t + [-r, r]` for some :math:`t \in [-1, 1]`, and within ``box``.

    ``point``: a single value (c; s = r = 0; box = [c, c]).
    """

    c: ca.SX
    s: ca.SX
    r: ca.SX
    box: iv.Range
    point: bool

    @staticmethod
    def of(value: ca.SX) -> Model:
        return Model(value, ca.SX(0.0), ca.SX(0.0), iv.Range.of(value), True)


def affine(c: ca.SX, s: ca.SX, r: ca.SX, box: iv.Range) -> Model:
    """The model ``c + s t ± r`` with its bounds intersected with ``box``."""
    spread = ca.fabs(s) + r
    lo, hi = ca.fmax(box.lo, c - spread), ca.fmin(box.hi, c + spread)
    return Model(c, s, r, iv.pair(lo, hi), False)


def hull(box: iv.Range) -> Model:
    """No slope: the box itself as ``mid ± half width``."""
    if box.point:
        return Model.of(box.lo)
    return Model(0.5 * (box.lo + box.hi), ca.SX(0.0), 0.5 * (box.hi - box.lo), box, False)


def choose(cond: ca.SX, a: Model, b: Model) -> Model:
    """``a`` where ``cond`` (an SX boolean) holds, else ``b``, term by term (a selection, not a hull)."""
    box = iv.pair(ca.if_else(cond, a.box.lo, b.box.lo), ca.if_else(cond, a.box.hi, b.box.hi))
    return Model(ca.if_else(cond, a.c, b.c), ca.if_else(cond, a.s, b.s), ca.if_else(cond, a.r, b.r), box, False)


def spread(x: Model) -> ca.SX:
    r"""The largest :math:`|x - c|` over the box: :math:`|s| + r`."""
    return ca.fabs(x.s) + x.r


def smooth(x: Model, f, df, curvature: ca.SX, box: iv.Range) -> Model:
    r"""``f(x)`` by Taylor's theorem about c: :math:`f(c) + f'(c)(x - c) + R`, :math:`|R| \le \tfrac12 M (|s| + r)^2`.

    ``curvature`` is M, a bound of :math:`|f''|` over x's box; ``box`` the interval rule's bounds of f(x).
    """
    g = df(x.c)
    rho = spread(x)
    return affine(f(x.c), g * x.s, ca.fabs(g) * x.r + 0.5 * curvature * rho * rho, box)


def mul(x: Model, y: Model, same: bool) -> Model:
    box = iv.mul(x.box, y.box, same)
    if x.point and y.point:
        return Model.of(x.c * y.c)
    if same:  # x², with |x − c| ≤ ρ: c² + 2c(x − c) + (x − c)²
        rho = spread(x)
        return affine(x.c * x.c, 2.0 * x.c * x.s, 2.0 * ca.fabs(x.c) * x.r + rho * rho, box)
    if y.point:
        x, y = y, x
    if x.point:
        return affine(x.c * y.c, x.c * y.s, ca.fabs(x.c) * y.r, box)
    rest = ca.fabs(x.c) * y.r + ca.fabs(y.c) * x.r + spread(x) * spread(y)
    return affine(x.c * y.c, x.c * y.s + x.s * y.c, rest, box)


def add(x: Model, y: Model) -> Model:
    if x.point and y.point:
        return Model.of(x.c + y.c)
    return affine(x.c + y.c, x.s + y.s, x.r + y.r, iv.pair(x.box.lo + y.box.lo, x.box.hi + y.box.hi))


def sub(x: Model, y: Model) -> Model:
    if x.point and y.point:
        return Model.of(x.c - y.c)
    return affine(x.c - y.c, x.s - y.s, x.r + y.r, iv.pair(x.box.lo - y.box.hi, x.box.hi - y.box.lo))


def recip(y: Model) -> Model:
    """1/y: Taylor with :math:`|f''| = 2/|y|^3` at the end of y's box nearest 0; the hull where 0 is in it."""
    box = iv.div(iv.Range.of(ca.SX(1.0)), y.box)
    if y.point:
        return Model.of(1.0 / y.c)
    near = ca.fmin(ca.fabs(y.box.lo), ca.fabs(y.box.hi))
    zero = ca.logic_and(y.box.lo <= 0, y.box.hi >= 0)
    safe = ca.if_else(zero, 1.0, near)
    model = smooth(y, lambda v: 1.0 / v, lambda v: -1.0 / (v * v), 2.0 / (safe * safe * safe), box)
    return choose(zero, hull(box), model)


def positive(x: Model, op: int, f: Callable, df: Callable, curvature: Callable) -> Model:
    r"""A function defined for positive arguments (sqrt, log): its smooth model where the box is inside
    the domain, with ``curvature(lo)`` bounding :math:`|f''|` on the box (:math:`|f''|` decreases in the argument
    for both), else the hull of its interval bound."""
    box = iv.UNARY[op](x.box)
    if x.point:
        return Model.of(f(x.c))
    inside = x.box.lo > 0
    safe = ca.if_else(inside, x.box.lo, 1.0)
    return choose(inside, smooth(x, f, df, curvature(safe), box), hull(box))


def sqrt(x: Model) -> Model:
    return positive(x, ca.OP_SQRT, ca.sqrt, lambda v: 0.5 / ca.sqrt(v), lambda lo: 0.25 / (lo * ca.sqrt(lo)))


def log(x: Model) -> Model:
    return positive(x, ca.OP_LOG, ca.log, lambda v: 1.0 / v, lambda lo: 1.0 / (lo * lo))


def trig(x: Model, cosine: bool) -> Model:
    r"""sin or cos; :math:`|f''|` is :math:`|\sin|` or :math:`|\cos|` over the box (the interval rule's bounds)."""
    shift = iv.PI / 2 if cosine else 0.0
    box = iv.sin(x.box.lo + shift, x.box.hi + shift) if not x.box.point else iv.Range.of(ca.sin(x.box.lo + shift))
    if x.point:
        return Model.of(ca.cos(x.c) if cosine else ca.sin(x.c))
    bound = ca.fmax(ca.fabs(box.lo), ca.fabs(box.hi))
    if cosine:
        return smooth(x, ca.cos, lambda v: -ca.sin(v), bound, box)
    return smooth(x, ca.sin, ca.cos, bound, box)


def exp(x: Model) -> Model:
    box = iv.UNARY[ca.OP_EXP](x.box)
    if x.point:
        return Model.of(ca.exp(x.c))
    return smooth(x, ca.exp, ca.exp, ca.exp(x.box.hi), box)


def fabs(x: Model) -> Model:
    box = iv.UNARY[ca.OP_FABS](x.box)
    if x.point:
        return Model.of(ca.fabs(x.c))
    neg = affine(-x.c, -x.s, x.r, box)
    return choose(x.box.lo >= 0, x, choose(x.box.hi <= 0, neg, hull(box)))


def atan2(y: Model, x: Model) -> Model:
    r"""atan2 away from its cut and from 0: Taylor in (y, x) about the centres; the Hessian of atan2 has
    norm :math:`1/(x^2 + y^2)`, bounded over the box by its squared distance from the origin."""
    box = iv.atan2(y.box, x.box)
    if y.point and x.point:
        return Model.of(ca.atan2(y.c, x.c))
    dx = ca.fmax(ca.fmax(x.box.lo, -x.box.hi), 0.0)  # distance of the box from the origin, per axis
    dy = ca.fmax(ca.fmax(y.box.lo, -y.box.hi), 0.0)
    near = dx * dx + dy * dy
    cut = ca.logic_and(x.box.lo <= 0, ca.logic_and(y.box.lo <= 0, y.box.hi >= 0))
    bad = ca.logic_or(cut, near <= 0)
    safe = ca.if_else(bad, 1.0, near)
    n2 = x.c * x.c + y.c * y.c
    n2 = ca.if_else(bad, 1.0, n2)
    gy, gx = x.c / n2, -y.c / n2
    ry, rx = spread(y), spread(x)
    rest = ca.fabs(gy) * y.r + ca.fabs(gx) * x.r + 0.5 * (ry * ry + rx * rx) / safe
    model = affine(ca.atan2(y.c, x.c), gy * y.s + gx * x.s, rest, box)
    return choose(bad, hull(box), model)


def extreme(x: Model, y: Model, smallest: bool) -> Model:
    """fmin / fmax: the one that is surely smaller (larger), or the hull."""
    box = iv.binary_monotone(ca.fmin if smallest else ca.fmax, x.box, y.box)
    if x.point and y.point:
        return Model.of(ca.fmin(x.c, y.c) if smallest else ca.fmax(x.c, y.c))
    x_wins = x.box.hi <= y.box.lo if smallest else x.box.lo >= y.box.hi
    y_wins = y.box.hi <= x.box.lo if smallest else y.box.lo >= x.box.hi
    return choose(x_wins, x, choose(y_wins, y, hull(box)))


def if_else_zero(c: Model, a: Model) -> Model:
    box = iv.if_else_zero(c.box, a.box)
    if c.point and a.point:
        return Model.of(ca.if_else(c.c, a.c, 0.0))
    surely, maybe = iv.truth(c.box)
    return choose(surely, a, choose(ca.logic_not(maybe), Model.of(ca.SX(0.0)), hull(box)))


def select(c: Model, a: Model, b: Model) -> Model:
    if a is b:
        return a
    box = iv.select(c.box, a.box, b.box)
    if c.point and a.point and b.point:
        return Model.of(ca.if_else(c.c, a.c, b.c))
    surely, maybe = iv.truth(c.box)
    return choose(surely, a, choose(ca.logic_not(maybe), b, hull(box)))


def rule(op: int, src: list[int], made: dict, value: dict) -> Model:
    """The Taylor-model rule of one instruction with source instructions ``src``."""
    x = value[src[0]]
    y = value[src[1]] if len(src) > 1 else None
    if op == ca.OP_ASSIGN:
        return x
    if op == ca.OP_NEG:
        return Model.of(-x.c) if x.point else affine(-x.c, -x.s, x.r, iv.UNARY[op](x.box))
    if op == ca.OP_TWICE:
        return Model.of(2.0 * x.c) if x.point else affine(2.0 * x.c, 2.0 * x.s, 2.0 * x.r, iv.UNARY[op](x.box))
    if op == ca.OP_SQ:
        return mul(x, x, True)
    if op == ca.OP_SQRT:
        return sqrt(x)
    if op == ca.OP_LOG:
        return log(x)
    if op == ca.OP_EXP:
        return exp(x)
    if op in (ca.OP_SIN, ca.OP_COS):
        return trig(x, op == ca.OP_COS)
    if op == ca.OP_FABS:
        return fabs(x)
    if op == ca.OP_FLOOR:
        return hull(iv.UNARY[op](x.box))
    if op == ca.OP_ADD:
        ternary = iv.ternary(src, made)
        if ternary is not None:
            return select(*(value[t] for t in ternary))
        return add(x, y)
    if op == ca.OP_SUB:
        return sub(x, y)
    if op == ca.OP_MUL:
        return mul(x, y, src[0] == src[1])
    if op == ca.OP_DIV:
        if y.point:
            return mul(x, Model.of(1.0 / y.c), False)
        return mul(x, recip(y), False)
    if op in (ca.OP_FMIN, ca.OP_FMAX):
        return extreme(x, y, op == ca.OP_FMIN)
    if op == ca.OP_ATAN2:
        return atan2(x, y)
    if op in (ca.OP_LT, ca.OP_LE, ca.OP_EQ, ca.OP_NE):
        out = iv.compare(op, x.box, y.box)
        return Model.of(out.lo) if out.point else hull(out)
    if op in (ca.OP_NOT, ca.OP_AND, ca.OP_OR):
        out = iv.logic(op, x.box, y.box if y is not None else None)
        return Model.of(out.lo) if out.point else hull(out)
    if op == ca.OP_IF_ELSE_ZERO:
        return if_else_zero(x, y)
    names = {getattr(ca, n): n for n in dir(ca) if n.startswith("OP_")}
    raise InputError(f"fn: no Taylor-model rule for CasADi operation {names.get(op, op)}")
