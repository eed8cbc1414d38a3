r"""Interval extensions and Taylor models of CasADi SX functions: rigorous ranges over boxes of inputs.

:func:`interval_function` turns an SX :class:`casadi.Function` ``f`` into another SX
function that, given lower and upper bounds of some of its inputs, returns lower and
upper bounds of every output: for every input in the box, every output lies within
them. It replays ``f``'s instruction list once, replacing each operation by its
interval rule (:mod:`qpik.algebra.interval_rules`; the *natural interval extension*, Moore,
Kearfott & Cloud 2009, ch. 5).

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
models, Makino & Berz 2003, in one variable: :mod:`qpik.algebra.taylor_models`, with the angle
tags of :mod:`qpik.algebra.angle_tags`) beside its interval bounds, so that the
correlation of every value with t survives, and the width of the bounds is second order in
the range's size. :func:`isolation_step` is one round of the isolation of a function's roots over a cell by
such a model (its window of roots and what becomes of the cell).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import casadi as ca

from qpik.algebra import angle_tags as angles
from qpik.algebra import interval_rules as iv
from qpik.algebra import taylor_models as tm
from qpik.core.errors import InputError
from qpik.native.stored import derived


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
    return derived(fn, f"interval {boxed} {name}", lambda: _interval(fn, boxed, name), _DERIVING)


def _interval(fn: ca.Function, boxed: list[int], name: str | None) -> ca.Function:
    """:func:`interval_function`'s derivation (``boxed``: the interval inputs, without repeats)."""
    lo_in = [
        ca.SX.sym(f"{fn.name_in(i)}_lo" if i in boxed else fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())
    ]
    hi_in = {i: ca.SX.sym(f"{fn.name_in(i)}_hi", fn.sparsity_in(i)) for i in boxed}
    out_lo = [ca.SX.zeros(fn.sparsity_out(i)) for i in range(fn.n_out())]
    out_hi = [ca.SX.zeros(fn.sparsity_out(i)) for i in range(fn.n_out())]
    slot: dict[int, int] = {}  # work-vector slot -> instruction that last wrote it
    made: dict[int, tuple[int, list[int]]] = {}  # instruction -> (op, source instructions)
    value: dict[int, iv.Range] = {}
    for k in range(fn.n_instructions()):
        op, args, res = fn.instruction_id(k), fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:
            i, nz = args
            r = iv.Range.of(lo_in[i].nz[nz]) if i not in hi_in else iv.pair(lo_in[i].nz[nz], hi_in[i].nz[nz])
            src: list[int] = []
        elif op == ca.OP_CONST:
            r, src = iv.Range.of(ca.SX(fn.instruction_constant(k))), []
        else:
            src = [slot[a] for a in args]
            if op == ca.OP_OUTPUT:
                out_lo[res[0]].nz[res[1]], out_hi[res[0]].nz[res[1]] = value[src[0]].lo, value[src[0]].hi
                continue
            r = iv.rule(op, src, made, value)
        made[k] = (op, src)
        value[k] = r
        slot[res[0]] = k
    inputs = lo_in + [hi_in[i] for i in boxed]
    return ca.Function(name or f"{fn.name()}_interval", inputs, out_lo + out_hi)


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
    :func:`~qpik.algebra.angle_tags.angle_rule` keeps the vector (x, y) it is the angle of, turned by what was
    added, and
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
    return derived(fn, f"taylor {boxed} {name}", lambda: _taylor(fn, boxed, name), _DERIVING)


def _taylor(fn: ca.Function, boxed: list[int], name: str | None) -> ca.Function:
    """:func:`taylor_function`'s derivation (``boxed``: the model inputs, without repeats)."""
    centre = [ca.SX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    extra = {
        i: [ca.SX.sym(f"{fn.name_in(i)}_{part}", fn.sparsity_in(i)) for part in ("slope", "radius", "lo", "hi")]
        for i in boxed
    }
    shapes = [fn.sparsity_out(i) for i in range(fn.n_out())]
    out = [[ca.SX.zeros(sp) for sp in shapes] for _ in range(5)]
    slot: dict[int, int] = {}
    made: dict[int, tuple[int, list[int]]] = {}
    value: dict[int, tm.Model] = {}
    consts: dict[int, float] = {}
    tags: dict[int, angles.Angle] = {}
    for k in range(fn.n_instructions()):
        op, args, res = fn.instruction_id(k), fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:
            i, nz = args
            if i in extra:
                s, r, lo, hi = (x.nz[nz] for x in extra[i])
                m = tm.Model(centre[i].nz[nz], s, r, iv.pair(lo, hi), False)
            else:
                m = tm.Model.of(centre[i].nz[nz])
            src: list[int] = []
        elif op == ca.OP_CONST:
            consts[k] = fn.instruction_constant(k)
            m, src = tm.Model.of(ca.SX(consts[k])), []
        else:
            src = [slot[a] for a in args]
            if op == ca.OP_OUTPUT:
                v = value[src[0]]
                for part, x in zip(out, (v.c, v.s, v.r, v.box.lo, v.box.hi)):
                    part[res[0]].nz[res[1]] = x
                continue
            m = tm.rule(op, src, made, value)
            made[k] = (op, src)
            tag = None if m.point else angles.angle_rule(op, src, made, consts, value, tags)
            if tag is not None:
                tags[k] = tag
                if tag.low is not None and op != ca.OP_ATAN2:
                    m = tm.choose(tag.valid, angles.angle_model(tag), m)
        made[k] = (op, src)
        value[k] = m
        slot[res[0]] = k
    inputs = centre + [x for i in boxed for x in extra[i]]
    return ca.Function(name or f"{fn.name()}_taylor", inputs, [x for part in out for x in part])


GONE, DONE, TOUCHED, NARROW, HALVE = range(5)
"""The fates of a cell in a round of :func:`isolation_step`."""


def isolation_step(
    a: ca.SX,
    b: ca.SX,
    model: tuple[ca.SX, ...],
    away: ca.SX,
    slack: float,
    window: float,
    touch: float,
    also: Sequence[tuple[ca.SX, ...]] = (),
) -> tuple[ca.SX, ca.SX, ca.SX]:
    r"""One round of the isolation of the roots of a function f over the cell [a, b] (Moore 1966; Makino & Berz
    2003), in SX: its window and its fate.

    ``model`` is f's Taylor model over the cell (:func:`taylor_function`, the cell ``(a + b)/2 + (b − a)/2·t``):
    centre :math:`f_0`, slope :math:`f_1`, remainder r, bounds lo, hi; ``away`` is true where the cell surely holds
    no root of interest on other grounds. The window is the part of the cell where :math:`|f_0 + f_1 t| \le r +`
    ``slack``, its ends :math:`x_1 \le x_2` (the whole cell where the model has no slope, no finite remainder or no
    centre), and the fate :data:`GONE` (the window is empty, or the bounds exclude 0 by more than ``slack``, or
    ``away``), :data:`DONE` (the window is at most ``window`` wide: it holds the roots), :data:`TOUCHED` (:math:`|f|
    \le` ``touch`` over the cell: its ends are roots), :data:`NARROW` (the window is at most half the cell: the next
    cell) or :data:`HALVE` (the window's halves are the next cells). ``also``: models, in the same form, of functions
    with the same roots of interest in the cell (f times a factor > 0, say): the window is then the intersection of
    every model's, and the cell is gone where any one's window is empty or bounds exclude 0 (the touch is f's).
    Returns :math:`(x_1, x_2,` fate).
    """
    m, w = 0.5 * (a + b), 0.5 * (b - a)
    t1, t2, outside = -1.0, 1.0, away
    for f0, f1, r, lo, hi in (model, *also):
        rest = r + slack
        u1, u2 = (-f0 - rest) / f1, (-f0 + rest) / f1
        flat = ca.logic_or(ca.logic_not(ca.fabs(f1) > 0), ca.logic_not(ca.fabs(rest) < ca.inf))
        t1 = ca.fmax(t1, ca.if_else(flat, -1.0, ca.fmin(u1, u2)))
        t2 = ca.fmin(t2, ca.if_else(flat, 1.0, ca.fmax(u1, u2)))
        empty = ca.logic_and(flat, ca.fabs(f0) > rest)
        outside = ca.logic_or(outside, ca.logic_or(ca.logic_or(lo > slack, hi < -slack), empty))
    x1, x2 = m + w * t1, m + w * t2
    gone = ca.logic_or(t1 > t2, outside)
    f0, f1, rest = model[0], model[1], model[2] + slack
    small = ca.if_else(ca.fabs(f0) + ca.fabs(f1) + rest <= touch, TOUCHED, ca.if_else(x2 - x1 <= w, NARROW, HALVE))
    return x1, x2, ca.if_else(gone, GONE, ca.if_else(x2 - x1 <= window, DONE, small))


_DERIVING = (angles, iv, tm, sys.modules[__name__])
"""The modules whose source a derived function depends on (:func:`qpik.native.stored.derived`'s key)."""
