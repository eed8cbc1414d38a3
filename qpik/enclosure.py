r"""Interval extensions of CasADi SX functions: rigorous ranges over boxes of inputs.

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
map it, or compile it (:mod:`qpik.compiled`).

Soundness: in exact arithmetic the bounds contain the true range; the endpoints are
computed in round-to-nearest floating point (no outward rounding), so they may miss it by
a few units in the last place of the values involved. Callers that need proofs keep a
tolerance well above that (:mod:`qpik.nlp.certificate` uses 1e-9 and more). The
extension is only as tight as the expression allows: a variable that appears several
times is treated as independent each time (the dependency problem), so the width of the
bounds is a small multiple of the true range for narrow boxes and can be much more for
wide ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.errors import InputError

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
