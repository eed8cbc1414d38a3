r"""Interval extensions and Taylor models of CasADi SX functions: rigorous ranges over boxes of inputs.

:func:`interval_function` turns an SX :class:`casadi.Function` ``f`` into another SX
function that, given lower and upper bounds of some of its inputs, returns lower and
upper bounds of every output: for every input in the box, every output lies within
them. It replays ``f``'s instruction list once, replacing each operation by its
interval rule (the *natural interval extension*, Moore, Kearfott & Cloud 2009, ch. 5):

- ``x + y = [a + c, b + d]``, ``x − y = [a − d, b − c]``, ``x · y`` the hull of the four
  products (two when one factor is a single value, a square rule for ``x · x``),
  ``x / y`` the product with ``[1/d, 1/c]``, or ``[−BIG, BIG]`` when ``0 ∈ y``;
- monotone functions (sqrt, floor, fmin, fmax) at the ends; ``|x|`` with its kink;
- ``sin`` and ``cos``: the values at the ends, widened to ±1 where a crest
  ``π/2 + 2πk`` (trough ``−π/2 + 2πk``) lies inside;
- ``atan2(y, x)``: the hull of the four corners, or ``[−π, π]`` when the box touches the
  cut ``{y = 0, x ≤ 0}`` (the angle of a box away from it is extreme at its corners);
- comparisons and logic give ``[0, 1]`` when undecided; ``if_else(c, a, b)`` (which SX
  stores as ``if_else_zero(c, a) + if_else_zero(!c, b)``) is recognised and gives ``a``, ``b``
  or their hull, not the wider sum of the two halves.

Inputs that are not intervals stay single values, and so does everything computed from
them alone (no interval overhead). The result is an ordinary SX function: evaluate it,
map it, or compile it (:mod:`qpik.native.compiled`).

Soundness: in exact arithmetic the bounds contain the true range; the endpoints are
computed in round-to-nearest floating point (no outward rounding), so they may miss it by
a few units in the last place of the values involved. Callers that need proofs keep a
tolerance well above that (:mod:`qpik.nlp.certificate` uses 1e-9 and more). The
extension is only as tight as the expression allows: a variable that appears several
times is treated as independent each time (the dependency problem), so the width of the
bounds is a small multiple of the true range for narrow boxes and can be much more for
wide ones.

:func:`taylor_function` removes most of that for ranges along one variable t ∈ [−1, 1] (a
δ/ψ range of the closed form): every value is kept as ``c + s·t ± r`` (first-order Taylor
models, Makino & Berz 2003, in one variable) beside its interval bounds, so that the
correlation of every value with t survives, and the width of the bounds is second order in
the range's size.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.core.errors import InputError

BIG = 1e300
"""Stands for an unbounded end (a division by an interval that contains 0)."""

_PI = float(np.pi)


@dataclass(frozen=True)
class _Range:
    """Bounds ``[lo, hi]`` of one value (SX); ``point``: a single value (``lo is hi``)."""

    lo: ca.SX
    hi: ca.SX
    point: bool

    @staticmethod
    def of(value: ca.SX) -> _Range:
        return _Range(value, value, True)


def _pair(lo: ca.SX, hi: ca.SX) -> _Range:
    return _Range(lo, hi, False)


def _hull(*values: ca.SX) -> tuple[ca.SX, ca.SX]:
    lo = hi = values[0]
    for v in values[1:]:
        lo, hi = ca.fmin(lo, v), ca.fmax(hi, v)
    return lo, hi


def _truth(x: _Range) -> tuple[ca.SX, ca.SX]:
    """``(surely, maybe)`` nonzero, as SX booleans."""
    if x.point:
        t = x.lo != 0
        return t, t
    return ca.logic_or(x.lo > 0, x.hi < 0), ca.logic_not(ca.logic_and(x.lo == 0, x.hi == 0))


def _mul(x: _Range, y: _Range, same: bool) -> _Range:
    if x.point and y.point:
        return _Range.of(x.lo * y.lo)
    if same:
        return _square(x)
    if y.point:
        x, y = y, x
    if x.point:
        a, b = x.lo * y.lo, x.lo * y.hi
        return _pair(ca.fmin(a, b), ca.fmax(a, b))
    return _pair(*_hull(x.lo * y.lo, x.lo * y.hi, x.hi * y.lo, x.hi * y.hi))


def _square(x: _Range) -> _Range:
    if x.point:
        return _Range.of(x.lo * x.lo)
    a, b = x.lo, x.hi
    return _pair(ca.if_else(a >= 0, a * a, ca.if_else(b <= 0, b * b, 0.0)), ca.fmax(a * a, b * b))


def _div(x: _Range, y: _Range) -> _Range:
    if x.point and y.point:
        return _Range.of(x.lo / y.lo)
    if y.point:
        return _mul(x, _Range.of(1.0 / y.lo), False)
    q = _mul(x, _pair(1.0 / y.hi, 1.0 / y.lo), False)
    zero = ca.logic_and(y.lo <= 0, y.hi >= 0)
    return _pair(ca.if_else(zero, -BIG, q.lo), ca.if_else(zero, BIG, q.hi))


def _sin(a: ca.SX, b: ca.SX) -> _Range:
    """sin over [a, b]: the ends, or ±1 where a crest/trough lies inside."""
    sa, sb = ca.sin(a), ca.sin(b)
    crest = ca.floor((b - _PI / 2) / (2 * _PI)) - ca.floor((a - _PI / 2) / (2 * _PI))
    trough = ca.floor((b + _PI / 2) / (2 * _PI)) - ca.floor((a + _PI / 2) / (2 * _PI))
    return _pair(ca.if_else(trough >= 1, -1.0, ca.fmin(sa, sb)), ca.if_else(crest >= 1, 1.0, ca.fmax(sa, sb)))


def _atan2(y: _Range, x: _Range) -> _Range:
    if y.point and x.point:
        return _Range.of(ca.atan2(y.lo, x.lo))
    cut = ca.logic_and(x.lo <= 0, ca.logic_and(y.lo <= 0, y.hi >= 0))
    ys = [y.lo] if y.point else [y.lo, y.hi]
    xs = [x.lo] if x.point else [x.lo, x.hi]
    lo, hi = _hull(*[ca.atan2(a, b) for a in ys for b in xs])
    return _pair(ca.if_else(cut, -_PI, lo), ca.if_else(cut, _PI, hi))


def _monotone(fn, x: _Range) -> _Range:
    return _Range.of(fn(x.lo)) if x.point else _pair(fn(x.lo), fn(x.hi))


def _binary_monotone(fn, x: _Range, y: _Range) -> _Range:
    if x.point and y.point:
        return _Range.of(fn(x.lo, y.lo))
    return _pair(fn(x.lo, y.lo), fn(x.hi, y.hi))


def _compare(op: int, x: _Range, y: _Range) -> _Range:
    if x.point and y.point:
        exact = {ca.OP_LT: x.lo < y.lo, ca.OP_LE: x.lo <= y.lo, ca.OP_EQ: x.lo == y.lo, ca.OP_NE: x.lo != y.lo}
        return _Range.of(exact[op])
    if op == ca.OP_LT:
        yes, no = x.hi < y.lo, x.lo >= y.hi
    elif op == ca.OP_LE:
        yes, no = x.hi <= y.lo, x.lo > y.hi
    else:
        apart = ca.logic_or(x.hi < y.lo, y.hi < x.lo)
        same = ca.logic_and(ca.logic_and(x.lo == x.hi, y.lo == y.hi), x.lo == y.lo)
        yes, no = (same, apart) if op == ca.OP_EQ else (apart, same)
    return _pair(ca.if_else(yes, 1.0, 0.0), ca.if_else(no, 0.0, 1.0))


def _logic(op: int, x: _Range, y: _Range | None) -> _Range:
    if op == ca.OP_NOT:
        if x.point:
            return _Range.of(ca.logic_not(x.lo))
        surely, maybe = _truth(x)
        return _pair(ca.if_else(maybe, 0.0, 1.0), ca.if_else(surely, 0.0, 1.0))
    if x.point and y.point:
        return _Range.of(ca.logic_and(x.lo, y.lo) if op == ca.OP_AND else ca.logic_or(x.lo, y.lo))
    (s1, m1), (s2, m2) = _truth(x), _truth(y)
    join = ca.logic_and if op == ca.OP_AND else ca.logic_or
    return _pair(ca.if_else(join(s1, s2), 1.0, 0.0), ca.if_else(join(m1, m2), 1.0, 0.0))


def _select(c: _Range, a: _Range, b: _Range) -> _Range:
    """``if_else(c, a, b)``: a, b or (undecided c) their hull."""
    if c.point and a.point and b.point:
        return _Range.of(ca.if_else(c.lo, a.lo, b.lo))
    surely, maybe = _truth(c)
    if c.point:
        return _pair(ca.if_else(surely, a.lo, b.lo), ca.if_else(surely, a.hi, b.hi))
    return _pair(
        ca.if_else(surely, a.lo, ca.if_else(maybe, ca.fmin(a.lo, b.lo), b.lo)),
        ca.if_else(surely, a.hi, ca.if_else(maybe, ca.fmax(a.hi, b.hi), b.hi)),
    )


def _if_else_zero(c: _Range, a: _Range) -> _Range:
    if c.point and a.point:
        return _Range.of(ca.if_else(c.lo, a.lo, 0.0))
    surely, maybe = _truth(c)
    return _pair(
        ca.if_else(surely, a.lo, ca.if_else(maybe, ca.fmin(a.lo, 0.0), 0.0)),
        ca.if_else(surely, a.hi, ca.if_else(maybe, ca.fmax(a.hi, 0.0), 0.0)),
    )


_UNARY = {
    ca.OP_SQRT: lambda x: _monotone(lambda v: ca.sqrt(ca.fmax(v, 0.0)), x) if not x.point else _Range.of(ca.sqrt(x.lo)),
    ca.OP_FLOOR: lambda x: _monotone(ca.floor, x),
    ca.OP_EXP: lambda x: _monotone(ca.exp, x),
    ca.OP_LOG: lambda x: _monotone(ca.log, x),
    ca.OP_TWICE: lambda x: _monotone(lambda v: 2.0 * v, x),
    ca.OP_NEG: lambda x: _Range.of(-x.lo) if x.point else _pair(-x.hi, -x.lo),
    ca.OP_SQ: _square,
    ca.OP_ASSIGN: lambda x: x,
    ca.OP_SIN: lambda x: _Range.of(ca.sin(x.lo)) if x.point else _sin(x.lo, x.hi),
    ca.OP_COS: lambda x: _Range.of(ca.cos(x.lo)) if x.point else _sin(x.lo + _PI / 2, x.hi + _PI / 2),
    ca.OP_FABS: lambda x: (
        _Range.of(ca.fabs(x.lo))
        if x.point
        else _pair(ca.if_else(x.lo >= 0, x.lo, ca.if_else(x.hi <= 0, -x.hi, 0.0)), ca.fmax(-x.lo, x.hi))
    ),
}


def interval_function(fn: ca.Function, intervals: Sequence[int], name: str | None = None) -> ca.Function:
    """The interval extension of the SX function ``fn`` in its inputs ``intervals`` (indices).

    Returns a function of ``fn``'s inputs, where each input ``i`` in ``intervals`` stands for its
    lower bound, followed by the upper bounds of those inputs (in the order of ``intervals``);
    its outputs are the lower bounds of ``fn``'s outputs, then their upper bounds. Inputs not in
    ``intervals`` are single values. For every input inside the box, each output of ``fn`` lies
    within the returned bounds (see the module docstring for the rules and the rounding caveat).

    Raises:
        InputError: ``fn`` is not an SX function, or uses an operation without an interval rule
            here (its CasADi op code is named).
    """
    if not fn.is_a("SXFunction"):
        raise InputError(f"fn: interval_function needs an SX function, got {fn.class_name()}")
    boxed = list(dict.fromkeys(int(i) for i in intervals))
    lo_in = [
        ca.SX.sym(f"{fn.name_in(i)}_lo" if i in boxed else fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())
    ]
    hi_in = {i: ca.SX.sym(f"{fn.name_in(i)}_hi", fn.sparsity_in(i)) for i in boxed}
    out_lo = [ca.SX.zeros(fn.sparsity_out(i)) for i in range(fn.n_out())]
    out_hi = [ca.SX.zeros(fn.sparsity_out(i)) for i in range(fn.n_out())]
    slot: dict[int, int] = {}  # work-vector slot -> instruction that last wrote it
    made: dict[int, tuple[int, list[int]]] = {}  # instruction -> (op, source instructions)
    value: dict[int, _Range] = {}
    for k in range(fn.n_instructions()):
        op, args, res = fn.instruction_id(k), fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:
            i, nz = args
            r = _Range.of(lo_in[i].nz[nz]) if i not in hi_in else _pair(lo_in[i].nz[nz], hi_in[i].nz[nz])
            src: list[int] = []
        elif op == ca.OP_CONST:
            r, src = _Range.of(ca.SX(fn.instruction_constant(k))), []
        else:
            src = [slot[a] for a in args]
            if op == ca.OP_OUTPUT:
                out_lo[res[0]].nz[res[1]], out_hi[res[0]].nz[res[1]] = value[src[0]].lo, value[src[0]].hi
                continue
            r = _rule(op, src, made, value)
        made[k] = (op, src)
        value[k] = r
        slot[res[0]] = k
    inputs = lo_in + [hi_in[i] for i in boxed]
    return ca.Function(name or f"{fn.name()}_interval", inputs, out_lo + out_hi)


def _rule(op: int, src: list[int], made: dict, value: dict) -> _Range:
    """The interval rule of one instruction with source instructions ``src``."""
    x = value[src[0]]
    if op in _UNARY:
        return _UNARY[op](x)
    y = value[src[1]] if len(src) > 1 else None
    if op == ca.OP_ADD:
        ternary = _ternary(src, made)
        if ternary is not None:
            c, a, b = (value[t] for t in ternary)
            return _select(c, a, b)
        return _Range.of(x.lo + y.lo) if x.point and y.point else _pair(x.lo + y.lo, x.hi + y.hi)
    if op == ca.OP_SUB:
        return _Range.of(x.lo - y.lo) if x.point and y.point else _pair(x.lo - y.hi, x.hi - y.lo)
    if op == ca.OP_MUL:
        return _mul(x, y, src[0] == src[1])
    if op == ca.OP_DIV:
        return _div(x, y)
    if op == ca.OP_FMIN:
        return _binary_monotone(ca.fmin, x, y)
    if op == ca.OP_FMAX:
        return _binary_monotone(ca.fmax, x, y)
    if op == ca.OP_ATAN2:
        return _atan2(x, y)
    if op in (ca.OP_LT, ca.OP_LE, ca.OP_EQ, ca.OP_NE):
        return _compare(op, x, y)
    if op in (ca.OP_NOT, ca.OP_AND, ca.OP_OR):
        return _logic(op, x, y)
    if op == ca.OP_IF_ELSE_ZERO:
        return _if_else_zero(x, y)
    names = {getattr(ca, n): n for n in dir(ca) if n.startswith("OP_")}
    raise InputError(f"fn: no interval rule for CasADi operation {names.get(op, op)}")


def _ternary(src: list[int], made: dict) -> tuple[int, int, int] | None:
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


# ---- first-order Taylor models in one variable ----------------------------------------------------


@dataclass(frozen=True)
class _Model:
    r"""A value over the box: :math:`c + s\,t + [-r, r]` for some :math:`t \in [-1, 1]`, and within ``box``.

    ``point``: a single value (c; s = r = 0; box = [c, c]).
    """

    c: ca.SX
    s: ca.SX
    r: ca.SX
    box: _Range
    point: bool

    @staticmethod
    def of(value: ca.SX) -> _Model:
        return _Model(value, ca.SX(0.0), ca.SX(0.0), _Range.of(value), True)


def _model(c: ca.SX, s: ca.SX, r: ca.SX, box: _Range) -> _Model:
    """The model ``c + s t ± r`` with its bounds intersected with ``box``."""
    spread = ca.fabs(s) + r
    lo, hi = ca.fmax(box.lo, c - spread), ca.fmin(box.hi, c + spread)
    return _Model(c, s, r, _pair(lo, hi), False)


def _hull_model(box: _Range) -> _Model:
    """No slope: the box itself as ``mid ± half width``."""
    if box.point:
        return _Model.of(box.lo)
    return _Model(0.5 * (box.lo + box.hi), ca.SX(0.0), 0.5 * (box.hi - box.lo), box, False)


def _choose(cond: ca.SX, a: _Model, b: _Model) -> _Model:
    """``a`` where ``cond`` (an SX boolean) holds, else ``b``, term by term (a selection, not a hull)."""
    box = _pair(ca.if_else(cond, a.box.lo, b.box.lo), ca.if_else(cond, a.box.hi, b.box.hi))
    return _Model(ca.if_else(cond, a.c, b.c), ca.if_else(cond, a.s, b.s), ca.if_else(cond, a.r, b.r), box, False)


def _spread(x: _Model) -> ca.SX:
    """The largest |x − c| over the box: |s| + r."""
    return ca.fabs(x.s) + x.r


def _smooth(x: _Model, f, df, curvature: ca.SX, box: _Range) -> _Model:
    r"""``f(x)`` by Taylor's theorem about c: :math:`f(c) + f'(c)(x - c) + R`, :math:`|R| \le \tfrac12 M (|s| + r)^2`.

    ``curvature`` is M, a bound of :math:`|f''|` over x's box; ``box`` the interval rule's bounds of f(x).
    """
    g = df(x.c)
    rho = _spread(x)
    return _model(f(x.c), g * x.s, ca.fabs(g) * x.r + 0.5 * curvature * rho * rho, box)


def _tm_mul(x: _Model, y: _Model, same: bool) -> _Model:
    box = _mul(x.box, y.box, same)
    if x.point and y.point:
        return _Model.of(x.c * y.c)
    if same:  # x², with |x − c| ≤ ρ: c² + 2c(x − c) + (x − c)²
        rho = _spread(x)
        return _model(x.c * x.c, 2.0 * x.c * x.s, 2.0 * ca.fabs(x.c) * x.r + rho * rho, box)
    if y.point:
        x, y = y, x
    if x.point:
        return _model(x.c * y.c, x.c * y.s, ca.fabs(x.c) * y.r, box)
    rest = ca.fabs(x.c) * y.r + ca.fabs(y.c) * x.r + _spread(x) * _spread(y)
    return _model(x.c * y.c, x.c * y.s + x.s * y.c, rest, box)


def _tm_add(x: _Model, y: _Model) -> _Model:
    if x.point and y.point:
        return _Model.of(x.c + y.c)
    return _model(x.c + y.c, x.s + y.s, x.r + y.r, _pair(x.box.lo + y.box.lo, x.box.hi + y.box.hi))


def _tm_sub(x: _Model, y: _Model) -> _Model:
    if x.point and y.point:
        return _Model.of(x.c - y.c)
    return _model(x.c - y.c, x.s - y.s, x.r + y.r, _pair(x.box.lo - y.box.hi, x.box.hi - y.box.lo))


def _tm_recip(y: _Model) -> _Model:
    """1/y: Taylor with :math:`|f''| = 2/|y|^3` at the end of y's box nearest 0; the hull where 0 is in it."""
    box = _div(_Range.of(ca.SX(1.0)), y.box)
    if y.point:
        return _Model.of(1.0 / y.c)
    near = ca.fmin(ca.fabs(y.box.lo), ca.fabs(y.box.hi))
    zero = ca.logic_and(y.box.lo <= 0, y.box.hi >= 0)
    safe = ca.if_else(zero, 1.0, near)
    model = _smooth(y, lambda v: 1.0 / v, lambda v: -1.0 / (v * v), 2.0 / (safe * safe * safe), box)
    return _choose(zero, _hull_model(box), model)


def _tm_positive(x: _Model, op: int, f: Callable, df: Callable, curvature: Callable) -> _Model:
    """A function defined for positive arguments (sqrt, log): its smooth model where the box is inside
    the domain, with ``curvature(lo)`` bounding |f''| on the box (|f''| decreases in the argument for
    both), else the hull of its interval bound."""
    box = _UNARY[op](x.box)
    if x.point:
        return _Model.of(f(x.c))
    inside = x.box.lo > 0
    safe = ca.if_else(inside, x.box.lo, 1.0)
    return _choose(inside, _smooth(x, f, df, curvature(safe), box), _hull_model(box))


def _tm_sqrt(x: _Model) -> _Model:
    return _tm_positive(x, ca.OP_SQRT, ca.sqrt, lambda v: 0.5 / ca.sqrt(v), lambda lo: 0.25 / (lo * ca.sqrt(lo)))


def _tm_log(x: _Model) -> _Model:
    return _tm_positive(x, ca.OP_LOG, ca.log, lambda v: 1.0 / v, lambda lo: 1.0 / (lo * lo))


def _tm_trig(x: _Model, cosine: bool) -> _Model:
    """sin or cos; |f''| is |sin| or |cos| over the box (the interval rule's bounds)."""
    shift = _PI / 2 if cosine else 0.0
    box = _sin(x.box.lo + shift, x.box.hi + shift) if not x.box.point else _Range.of(ca.sin(x.box.lo + shift))
    if x.point:
        return _Model.of(ca.cos(x.c) if cosine else ca.sin(x.c))
    bound = ca.fmax(ca.fabs(box.lo), ca.fabs(box.hi))
    if cosine:
        return _smooth(x, ca.cos, lambda v: -ca.sin(v), bound, box)
    return _smooth(x, ca.sin, ca.cos, bound, box)


def _tm_exp(x: _Model) -> _Model:
    box = _UNARY[ca.OP_EXP](x.box)
    if x.point:
        return _Model.of(ca.exp(x.c))
    return _smooth(x, ca.exp, ca.exp, ca.exp(x.box.hi), box)


def _tm_fabs(x: _Model) -> _Model:
    box = _UNARY[ca.OP_FABS](x.box)
    if x.point:
        return _Model.of(ca.fabs(x.c))
    neg = _model(-x.c, -x.s, x.r, box)
    return _choose(x.box.lo >= 0, x, _choose(x.box.hi <= 0, neg, _hull_model(box)))


def _tm_atan2(y: _Model, x: _Model) -> _Model:
    r"""atan2 away from its cut and from 0: Taylor in (y, x) about the centres; the Hessian of atan2 has
    norm :math:`1/(x^2 + y^2)`, bounded over the box by its squared distance from the origin."""
    box = _atan2(y.box, x.box)
    if y.point and x.point:
        return _Model.of(ca.atan2(y.c, x.c))
    dx = ca.fmax(ca.fmax(x.box.lo, -x.box.hi), 0.0)  # distance of the box from the origin, per axis
    dy = ca.fmax(ca.fmax(y.box.lo, -y.box.hi), 0.0)
    near = dx * dx + dy * dy
    cut = ca.logic_and(x.box.lo <= 0, ca.logic_and(y.box.lo <= 0, y.box.hi >= 0))
    bad = ca.logic_or(cut, near <= 0)
    safe = ca.if_else(bad, 1.0, near)
    n2 = x.c * x.c + y.c * y.c
    n2 = ca.if_else(bad, 1.0, n2)
    gy, gx = x.c / n2, -y.c / n2
    ry, rx = _spread(y), _spread(x)
    rest = ca.fabs(gy) * y.r + ca.fabs(gx) * x.r + 0.5 * (ry * ry + rx * rx) / safe
    model = _model(ca.atan2(y.c, x.c), gy * y.s + gx * x.s, rest, box)
    return _choose(bad, _hull_model(box), model)


def _tm_extreme(x: _Model, y: _Model, smallest: bool) -> _Model:
    """fmin / fmax: the one that is surely smaller (larger), or the hull."""
    box = _binary_monotone(ca.fmin if smallest else ca.fmax, x.box, y.box)
    if x.point and y.point:
        return _Model.of(ca.fmin(x.c, y.c) if smallest else ca.fmax(x.c, y.c))
    x_wins = x.box.hi <= y.box.lo if smallest else x.box.lo >= y.box.hi
    y_wins = y.box.hi <= x.box.lo if smallest else y.box.lo >= x.box.hi
    return _choose(x_wins, x, _choose(y_wins, y, _hull_model(box)))


def _tm_if_else_zero(c: _Model, a: _Model) -> _Model:
    box = _if_else_zero(c.box, a.box)
    if c.point and a.point:
        return _Model.of(ca.if_else(c.c, a.c, 0.0))
    surely, maybe = _truth(c.box)
    return _choose(surely, a, _choose(ca.logic_not(maybe), _Model.of(ca.SX(0.0)), _hull_model(box)))


def _tm_select(c: _Model, a: _Model, b: _Model) -> _Model:
    if a is b:
        return a
    box = _select(c.box, a.box, b.box)
    if c.point and a.point and b.point:
        return _Model.of(ca.if_else(c.c, a.c, b.c))
    surely, maybe = _truth(c.box)
    return _choose(surely, a, _choose(ca.logic_not(maybe), b, _hull_model(box)))


@dataclass(frozen=True)
class _Angle:
    r"""What is known of an angle-valued value where ``valid`` (an SX boolean) holds: it equals
    :math:`\mathrm{atan2}(y, x) + \text{offset}` modulo 2π, and (``low`` not None) it lies in (low, low + 2π]."""

    y: _Model
    x: _Model
    offset: float
    low: float | None
    valid: ca.SX


_TWO_PI = 2.0 * _PI


def _near(a: float | None, b: float) -> bool:
    return a is not None and abs(a - b) < 1e-12 * (1.0 + abs(b))


def _rotated(y: _Model, x: _Model, cos: _Model, sin: _Model) -> tuple[_Model, _Model]:
    """The vector (x, y) turned by the angle with cosine ``cos`` and sine ``sin``: (y', x')."""
    yr = _tm_add(_tm_mul(x, sin, False), _tm_mul(y, cos, False))
    xr = _tm_sub(_tm_mul(x, cos, False), _tm_mul(y, sin, False))
    return yr, xr


def _angle_model(a: _Angle) -> _Model:
    r"""The model of an angle with a known window: :math:`\mathrm{atan2}(y'', x'') + low + π`, (x'', y'') the
    vector turned by offset − low − π, which is continuous wherever the value does not leave its window."""
    beta = a.offset - a.low - _PI
    cos, sin = _Model.of(ca.SX(float(np.cos(beta)))), _Model.of(ca.SX(float(np.sin(beta))))
    yr, xr = _rotated(a.y, a.x, cos, sin)
    shift = _Model.of(ca.SX(a.low + _PI))
    return _tm_add(_tm_atan2(yr, xr), shift)


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
    if op != ca.OP_SUB or src[0] not in consts or not _near(consts[src[0]], _PI):
        return None
    return src[1]


def _angle_rule(op: int, src: list[int], made: dict, consts: dict, value: dict, tags: dict) -> _Angle | None:
    r"""The angle tag of an instruction (see :func:`taylor_function`), or None.

    Kept through: atan2 (the window (−π, π]); adding a constant (the window moves with it); adding an
    untagged value φ (the vector turns by φ; the window is lost); :meth:`~qpik.algebra.symbolic.Ops.wrap` (the
    window (−π, π]); ``where(t > −π, t, π)`` (the same angle); ``where(θ > c0, θ + α, θ + α + 2π)`` for θ
    in (−π, π] (the window (c0 + α, c0 + α + 2π], as the flip of a ZYZ triple); ``where(c, θ, 0)``
    (valid where c surely holds).
    """
    one = ca.SX(1.0)
    if op == ca.OP_ATAN2:
        return _Angle(value[src[0]], value[src[1]], 0.0, -_PI, one)
    if op == ca.OP_IF_ELSE_ZERO and src[1] in tags:
        t = tags[src[1]]
        return _Angle(t.y, t.x, t.offset, t.low, ca.logic_and(t.valid, _truth(value[src[0]].box)[0]))
    if op not in (ca.OP_ADD, ca.OP_SUB):
        return None
    a, b = src
    if op == ca.OP_ADD:
        ternary = _ternary(src, made)
        if ternary is not None:
            return _select_angle(*ternary, made, consts, tags)
        for x, w in ((a, b), (b, a)):
            if x in tags and _wrapped_of(w, made, consts) == x:
                t = tags[x]
                return _Angle(t.y, t.x, t.offset, -_PI, t.valid)
    if op == ca.OP_SUB and b in consts and a in tags:
        t = tags[a]
        c = consts[b]
        return _Angle(t.y, t.x, t.offset - c, None if t.low is None else t.low - c, t.valid)
    if op == ca.OP_ADD:
        for x, w in ((a, b), (b, a)):
            if x not in tags or w in tags:
                continue
            t = tags[x]
            if w in consts:
                c = consts[w]
                return _Angle(t.y, t.x, t.offset + c, None if t.low is None else t.low + c, t.valid)
            turn = value[w]
            yr, xr = _rotated(t.y, t.x, _tm_trig(turn, True), _tm_trig(turn, False))
            return _Angle(yr, xr, t.offset, None, t.valid)
    return None


def _select_angle(c: int, a: int, b: int, made: dict, consts: dict, tags: dict) -> _Angle | None:
    """The angle tag of ``where(c, a, b)`` for the two forms of :func:`_angle_rule`, or None."""
    cop, csrc = made[c]
    if cop != ca.OP_LT or csrc[0] not in consts:
        return None
    c0, theta = consts[csrc[0]], csrc[1]
    t = tags.get(theta)
    if t is None or not _near(t.low, -_PI):
        return None
    if a == theta and b in consts and _near(c0, -_PI) and _near(consts[b], _PI):
        return t  # where(t > −π, t, π): the same angle
    ta, tb = tags.get(a), tags.get(b)
    if ta is None or tb is None or ta.y is not t.y or tb.y is not t.y or ta.x is not t.x or tb.x is not t.x:
        return None
    alpha = ta.offset - t.offset
    if not _near(tb.offset - ta.offset, _TWO_PI):
        return None
    return _Angle(t.y, t.x, ta.offset, c0 + alpha, t.valid)


def _tm_rule(op: int, src: list[int], made: dict, value: dict) -> _Model:
    """The Taylor-model rule of one instruction with source instructions ``src``."""
    x = value[src[0]]
    y = value[src[1]] if len(src) > 1 else None
    if op == ca.OP_ASSIGN:
        return x
    if op == ca.OP_NEG:
        return _Model.of(-x.c) if x.point else _model(-x.c, -x.s, x.r, _UNARY[op](x.box))
    if op == ca.OP_TWICE:
        return _Model.of(2.0 * x.c) if x.point else _model(2.0 * x.c, 2.0 * x.s, 2.0 * x.r, _UNARY[op](x.box))
    if op == ca.OP_SQ:
        return _tm_mul(x, x, True)
    if op == ca.OP_SQRT:
        return _tm_sqrt(x)
    if op == ca.OP_LOG:
        return _tm_log(x)
    if op == ca.OP_EXP:
        return _tm_exp(x)
    if op in (ca.OP_SIN, ca.OP_COS):
        return _tm_trig(x, op == ca.OP_COS)
    if op == ca.OP_FABS:
        return _tm_fabs(x)
    if op == ca.OP_FLOOR:
        return _hull_model(_UNARY[op](x.box))
    if op == ca.OP_ADD:
        ternary = _ternary(src, made)
        if ternary is not None:
            return _tm_select(*(value[t] for t in ternary))
        return _tm_add(x, y)
    if op == ca.OP_SUB:
        return _tm_sub(x, y)
    if op == ca.OP_MUL:
        return _tm_mul(x, y, src[0] == src[1])
    if op == ca.OP_DIV:
        if y.point:
            return _tm_mul(x, _Model.of(1.0 / y.c), False)
        return _tm_mul(x, _tm_recip(y), False)
    if op in (ca.OP_FMIN, ca.OP_FMAX):
        return _tm_extreme(x, y, op == ca.OP_FMIN)
    if op == ca.OP_ATAN2:
        return _tm_atan2(x, y)
    if op in (ca.OP_LT, ca.OP_LE, ca.OP_EQ, ca.OP_NE):
        out = _compare(op, x.box, y.box)
        return _Model.of(out.lo) if out.point else _hull_model(out)
    if op in (ca.OP_NOT, ca.OP_AND, ca.OP_OR):
        out = _logic(op, x.box, y.box if y is not None else None)
        return _Model.of(out.lo) if out.point else _hull_model(out)
    if op == ca.OP_IF_ELSE_ZERO:
        return _tm_if_else_zero(x, y)
    names = {getattr(ca, n): n for n in dir(ca) if n.startswith("OP_")}
    raise InputError(f"fn: no Taylor-model rule for CasADi operation {names.get(op, op)}")


def taylor_function(fn: ca.Function, models: Sequence[int], name: str | None = None) -> ca.Function:
    r"""The first-order Taylor-model extension of the SX function ``fn`` in its inputs ``models`` (indices).

    Every value over the box is kept as :math:`c + s\,t + [-r, r]` for a common unknown
    :math:`t \in [-1, 1]` (an affine form in one variable with a remainder), together with the
    interval bounds of :func:`interval_function`, each intersected with the other at every step.
    Linear operations are exact in (c, s, r); a product adds the product of the two spreads
    :math:`|s| + r` to the remainder; a smooth function f uses Taylor's theorem about c with a bound
    of :math:`|f''|` over the argument's interval (1/x, √x and log where the interval excludes 0,
    sin, cos, exp, atan2 away from its cut and the origin; elsewhere, and for floor, comparisons and
    undecided selections, the interval bounds with no slope). Because the slopes carry the
    correlation of every value with t, the bounds are tight to second order in the box's size
    (the dependency problem of the plain interval extension is first order).

    Angles: an atan2 is discontinuous on its cut, and a closed form often turns it into a continuous
    angle afterwards (adding π and wrapping, or choosing θ ± π by the sign of θ), which bounds
    evaluated operation by operation cannot see. So a value computed from an atan2 by the forms of
    :func:`_angle_rule` keeps the vector (x, y) it is the angle of, turned by what was added, and
    the window of 2π it lies in; its model is then the atan2 of that turned vector (continuous
    unless the value itself leaves its window), where the tag's conditions surely hold.

    The model inputs are given as their centres (in ``fn``'s input positions), then, for each input
    of ``models`` in that order, its slope, its radius, and interval bounds lo and hi (all with the
    input's shape): the input lies in ``centre + slope·t ± radius`` and in [lo, hi] for the same t as
    every other model input. A parameter range [a, b] is the model ``(a + b)/2 + (b − a)/2·t``
    (radius 0, lo = a, hi = b); the outputs of one Taylor function are valid model inputs of another
    (the composition keeps the common t). Outputs: for each of ``fn``'s outputs its centres, then all
    slopes, radii, lower and upper bounds (5 × n_out outputs).

    Soundness: as :func:`interval_function` (round-to-nearest arithmetic; bounds may miss by a few
    units in the last place).

    Raises:
        InputError: ``fn`` is not an SX function, or uses an operation without a rule here.
    """
    if not fn.is_a("SXFunction"):
        raise InputError(f"fn: taylor_function needs an SX function, got {fn.class_name()}")
    boxed = list(dict.fromkeys(int(i) for i in models))
    centre = [ca.SX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    extra = {
        i: [ca.SX.sym(f"{fn.name_in(i)}_{part}", fn.sparsity_in(i)) for part in ("slope", "radius", "lo", "hi")]
        for i in boxed
    }
    shapes = [fn.sparsity_out(i) for i in range(fn.n_out())]
    out = [[ca.SX.zeros(sp) for sp in shapes] for _ in range(5)]
    slot: dict[int, int] = {}
    made: dict[int, tuple[int, list[int]]] = {}
    value: dict[int, _Model] = {}
    consts: dict[int, float] = {}
    tags: dict[int, _Angle] = {}
    for k in range(fn.n_instructions()):
        op, args, res = fn.instruction_id(k), fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:
            i, nz = args
            if i in extra:
                s, r, lo, hi = (x.nz[nz] for x in extra[i])
                m = _Model(centre[i].nz[nz], s, r, _pair(lo, hi), False)
            else:
                m = _Model.of(centre[i].nz[nz])
            src: list[int] = []
        elif op == ca.OP_CONST:
            consts[k] = fn.instruction_constant(k)
            m, src = _Model.of(ca.SX(consts[k])), []
        else:
            src = [slot[a] for a in args]
            if op == ca.OP_OUTPUT:
                v = value[src[0]]
                for part, x in zip(out, (v.c, v.s, v.r, v.box.lo, v.box.hi)):
                    part[res[0]].nz[res[1]] = x
                continue
            m = _tm_rule(op, src, made, value)
            made[k] = (op, src)
            tag = None if m.point else _angle_rule(op, src, made, consts, value, tags)
            if tag is not None:
                tags[k] = tag
                if tag.low is not None and op != ca.OP_ATAN2:
                    m = _choose(tag.valid, _angle_model(tag), m)
        made[k] = (op, src)
        value[k] = m
        slot[res[0]] = k
    inputs = centre + [x for i in boxed for x in extra[i]]
    return ca.Function(name or f"{fn.name()}_taylor", inputs, [x for part in out for x in part])
