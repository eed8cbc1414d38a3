"""Closed-form closest points of a segment to a segment, a box and a half-space.

Written once in the scalar algebra of :mod:`qpik.algebra.symbolic`: a scalar is a
numpy array (a batch of pairs, element-wise) or a CasADi ``SX`` (traced into a
compiled function for the 1 kHz path, or differentiated in an NLP). Vectors
are 3-tuples of scalars; there is no branching on data, only ``ops.where``.
Every kernel is exact: no iteration, no sampling.

A segment is ``x(s) = a + s u``, ``s ∈ [0, 1]``; ``u = 0`` is a point. Each
kernel returns ``(s, sd, p, n)``: the parameter of the axis point ``x(s)``
nearest to (or deepest in) the obstacle, the signed distance ``sd`` of
``x(s)`` to the obstacle surface (negative inside), the nearest surface point
``p`` and the unit normal ``n`` pointing from ``p`` toward ``x(s)``, so that
``x(s) = p + sd n``.
"""

from __future__ import annotations

from itertools import combinations, pairwise

from qpik.algebra.symbolic import Ops, Scalar, Vec, cross, dot, vadd, vscale, vsub

TINY2 = 1e-24
"""Squared length (m²) under which a segment counts as a point, or a distance as zero."""
PARALLEL = 1e-12
"""Two segments count as parallel when ``sin²`` of their angle is below this."""
FLAT = 1e-100
"""A piece of the box kernel's ``f′`` rising by less than this is flat (its root fraction is then 0 or 1)."""
_SORT6 = ((0, 5), (1, 3), (2, 4), (1, 2), (3, 4), (0, 3), (2, 5), (0, 1), (2, 3), (4, 5), (1, 2), (3, 4))
"""An optimal sorting network for 6 values (12 compare-exchanges)."""


def _clip01(x: Scalar, ops: Ops) -> Scalar:
    return ops.fmin(ops.fmax(x, 0.0), 1.0)


def _div(num: Scalar, den: Scalar, ok: Scalar, ops: Ops) -> Scalar:
    """``num/den`` where ``ok``, else ``num`` (never divides by zero; callers clamp or mask the result)."""
    return num / ops.where(ok, den, 1.0)


def _unit_or(w: Vec, fallback: Vec, ops: Ops) -> Vec:
    """``w/|w|``, or ``fallback`` where ``|w|`` is (numerically) zero."""
    n2 = dot(w, w)
    ok = n2 > TINY2
    inv = 1.0 / ops.sqrt(ops.where(ok, n2, 1.0))
    return tuple(ops.where(ok, w[i] * inv, fallback[i]) for i in range(3))  # type: ignore[return-value]


def any_normal(u: Vec, v: Vec, ops: Ops) -> Vec:
    """A unit vector ⟂ to both ``u`` and ``v`` if they span a plane, else ⟂ to the nonzero one, else z."""
    along = tuple(ops.where(dot(u, u) > TINY2, u[i], v[i]) for i in range(3))
    mostly_x = along[0] * along[0] > 0.5 * dot(along, along)
    pick = (ops.where(mostly_x, 0.0, 1.0), ops.where(mostly_x, 1.0, 0.0), 0.0)
    return _unit_or(cross(u, v), _unit_or(cross(along, pick), (0.0, 0.0, 1.0), ops), ops)


def segment_segment(a: Vec, u: Vec, q: Vec, v: Vec, ops: Ops) -> tuple[Scalar, Scalar]:
    """Parameters ``(s, t)`` in [0, 1] of the closest points of ``a + s u`` and ``q + t v``.

    Math (Ericson, *Real-Time Collision Detection*, 5.1.9): with ``w = a − q``,
    ``A = u·u, B = u·v, E = v·v, c = u·w, f = v·w``, the squared distance
    ``|w + s u − t v|²`` is a convex quadratic on the unit square. Take the
    infinite-line solution ``s₀ = (B f − c E)/(A E − B²)`` clamped to [0, 1]
    (any ``s₀`` serves for parallel lines), then the best
    ``t = clamp((B s₀ + f)/E)``, then the best ``s = clamp((B t − c)/A)``; the
    last step is a no-op when ``t`` was not clamped and corrects ``s`` when it
    was, so ``(s, t)`` is a global minimiser (one of many for parallel segments).
    A point (``u = 0``) gets ``s = 0``.
    """
    w = vsub(a, q)
    A, B, E, c, f = dot(u, u), dot(u, v), dot(v, v), dot(u, w), dot(v, w)
    denom = A * E - B * B
    s0 = _clip01(_div(B * f - c * E, denom, denom > PARALLEL * A * E, ops), ops)  # any s0 is fine if parallel
    t = _clip01(_div(B * s0 + f, E, E > TINY2, ops), ops)
    s = ops.where(A > TINY2, _clip01(_div(B * t - c, A, A > TINY2, ops), ops), 0.0)
    return s, t


def segment_capsule(a: Vec, u: Vec, q: Vec, v: Vec, radius: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Vec, Vec]:
    """``(s, sd, p, n)`` of the segment ``a + s u`` to the capsule ``q + t v``, ``radius`` (a sphere if ``v = 0``).

    ``sd = |x(s) − y(t)| − radius`` with the closest axis points; where the axes
    meet (distance 0) the normal is :func:`any_normal` of the two directions.
    """
    s, t = segment_segment(a, u, q, v, ops)
    x, y = vadd(a, vscale(s, u)), vadd(q, vscale(t, v))
    diff = vsub(x, y)
    n = _unit_or(diff, any_normal(u, v, ops), ops)
    dist = ops.sqrt(dot(diff, diff))
    return s, dist - radius, vadd(y, vscale(radius, n)), n


def segment_halfspace(a: Vec, u: Vec, normal: Vec, offset: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Vec, Vec]:
    """``(s, sd, p, n)`` of the segment to the solid ``normal·x ≤ offset`` (``normal`` unit).

    ``normal·x(s) − offset`` is affine in ``s``: least at ``s = 0`` or ``s = 1``
    (``s = 0`` on a tie, i.e. a segment parallel to the plane).
    """
    da = dot(normal, a) - offset
    db = da + dot(normal, u)
    s = ops.where(db < da, 1.0, 0.0)
    sd = ops.fmin(da, db)
    x = vadd(a, vscale(s, u))
    return s, sd, vsub(x, vscale(sd, normal)), normal


def segment_box(a: Vec, u: Vec, h: Vec, ops: Ops) -> tuple[Scalar, Scalar, Vec, Vec]:
    """``(s, sd, p, n)`` of the segment ``y(s) = a + s u`` to the box ``|yᵢ| ≤ hᵢ``, all in the box frame.

    Math. Outside, ``f(s) = dist²(y(s)) = Σᵢ eᵢ(s)²`` with the excess
    ``eᵢ = yᵢ − clamp(yᵢ, −hᵢ, hᵢ)`` is convex and C¹, and
    ``f′(s)/2 = Σᵢ uᵢ eᵢ(s)`` is continuous, non-decreasing and *linear*
    between the breakpoints where ``y(s)`` crosses a slab plane ``yᵢ = ±hᵢ``
    (6 values, clamped to [0, 1] and sorted: knots ``0 = k₀ ≤ … ≤ k₇ = 1``).
    So the minimiser is found exactly from ``f′`` at the knots: on each piece
    the root of ``f′`` lies at the fraction ``ρⱼ = clamp(−f′ⱼ/(f′ⱼ₊₁ − f′ⱼ), 0, 1)``
    (1 if ``f′ < 0`` on the whole piece, 0 if ``f′ ≥ 0``), and
    ``s* = Σⱼ ρⱼ (kⱼ₊₁ − kⱼ)`` (pieces left of the root count fully, those
    right of it not at all).

    If ``f(s*) = 0`` the segment meets the box: the signed distance
    ``g(s) = maxᵢ (|yᵢ(s)| − hᵢ)`` is convex piecewise linear (the maximum of
    six lines ``±yᵢ − hᵢ``), so its minimum is at ``s ∈ {0, 1}`` or where two of
    the lines cross (15 candidates); the largest term there names the
    nearest face (``sd < 0``).
    """
    # ---- outside: root of the monotone piecewise-linear f' ---------------------------------
    knots = []
    for i in range(3):
        ok = ops.fabs(u[i]) > 0.0
        knots += [_clip01(_div(h[i] - a[i], u[i], ok, ops), ops), _clip01(_div(-h[i] - a[i], u[i], ok, ops), ops)]
    for i, j in _SORT6:
        knots[i], knots[j] = ops.fmin(knots[i], knots[j]), ops.fmax(knots[i], knots[j])
    knots = [0.0, *knots, 1.0]

    def slope(s: Scalar) -> Scalar:  # f'(s)/2
        total = 0.0
        for i in range(3):
            y = a[i] + s * u[i]
            total = total + u[i] * (y - ops.fmin(ops.fmax(y, -h[i]), h[i]))
        return total

    slopes = [slope(k) for k in knots]
    s_out = 0.0
    for (k0, k1), (f0, f1) in zip(pairwise(knots), pairwise(slopes)):
        df = f1 - f0
        sloped = df > FLAT
        # a flat piece gives 1 if f' < 0 there, else 0; the guarded division keeps derivatives finite (NLPs)
        rho = ops.where(sloped, _clip01(_div(-f0, df, sloped, ops), ops), ops.where(f0 < 0.0, 1.0, 0.0))
        s_out = s_out + rho * (k1 - k0)
    y = vadd(a, vscale(s_out, u))
    p_out = tuple(ops.fmin(ops.fmax(y[i], -h[i]), h[i]) for i in range(3))
    diff = vsub(y, p_out)
    d2 = dot(diff, diff)
    outside = d2 > TINY2
    n_out = _unit_or(diff, (0.0, 0.0, 1.0), ops)

    # ---- inside: convex piecewise-linear signed distance g(s) = max_i |y_i| - h_i ----------
    lines = [(sign * a[i] - h[i], sign * u[i]) for sign in (1.0, -1.0) for i in range(3)]  # c + s g
    cands = [0.0, 1.0]
    for j, k in combinations(range(6), 2):
        dg = lines[j][1] - lines[k][1]
        cands.append(_clip01(_div(lines[k][0] - lines[j][0], dg, ops.fabs(dg) > 0.0, ops), ops))

    def depth(s: Scalar) -> tuple[Scalar, ...]:  # |y_i(s)| - h_i per axis
        return tuple(ops.fabs(a[i] + s * u[i]) - h[i] for i in range(3))

    s_in, g_in = None, None
    for s in cands:
        e = depth(s)
        g = ops.fmax(ops.fmax(e[0], e[1]), e[2])
        s_in, g_in = (s, g) if s_in is None else (ops.where(g < g_in, s, s_in), ops.fmin(g, g_in))
    y_in = vadd(a, vscale(s_in, u))
    e = depth(s_in)
    face = (ops.where((e[0] >= e[1]) * (e[0] >= e[2]), 1.0, 0.0),)
    face += (ops.where(e[1] >= e[2], 1.0 - face[0], 0.0),)
    face += (1.0 - face[0] - face[1],)
    n_in = tuple(face[i] * ops.where(y_in[i] < 0.0, -1.0, 1.0) for i in range(3))
    p_in = tuple(ops.where(face[i] > 0.0, n_in[i] * h[i], y_in[i]) for i in range(3))

    s = ops.where(outside, s_out, s_in)
    sd = ops.where(outside, ops.sqrt(d2), g_in)
    p = tuple(ops.where(outside, p_out[i], p_in[i]) for i in range(3))
    n = tuple(ops.where(outside, n_out[i], n_in[i]) for i in range(3))
    return s, sd, p, n  # type: ignore[return-value]
