r"""The subproblems of Paden and Kahan as Elias & Wen 2022 (IK-Geo) write them, against :mod:`qpik.algebra.symbolic`
(numpy batches and CasADi symbols alike): the rotation about a unit axis (Rodrigues), subproblem 1 (one angle turning
a vector onto another about an axis) and subproblem 2 (two angles about two axes), with the precision notes of each.
The closed forms and the 1-D search that use them: :mod:`qpik.analytic.locked_joint`,
:mod:`qpik.analytic.locked_search`.
"""

from __future__ import annotations

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.analytic.trig import angle

BRANCH_TOL = 1e-13
"""Relative squared distance between two roots (of one subproblem) below which they are one: ``singular``."""
Signs = tuple[Scalar, ...]
"""Signs (±1) of the roots of a subproblem to take, in order; a symbol stands for a sign given at run time."""
BOTH: Signs = (1.0, -1.0)
"""Both roots of a subproblem: a branch bit 0, then 1."""


def constant(x: np.ndarray) -> Vec:
    """A vector of numbers (3,) as a :mod:`qpik.algebra.symbolic` vector, its entries snapped
    (:func:`~qpik.algebra.symbolic.snap`)."""
    return tuple(sy.snap(float(c)) for c in x)  # type: ignore[return-value]


def rotate(k: Vec, c: Scalar, s: Scalar, v: Vec) -> Vec:
    r""":math:`R(k, \theta)\,v = v\cos\theta + (k\times v)\sin\theta + k\,(k\cdot v)(1-\cos\theta)` (k unit)."""
    kv = sy.mul(sy.dot(k, v), sy.sub(1.0, c))
    kxv = sy.cross(k, v)
    return tuple(sy.lin((v[i], c), (kxv[i], s), (k[i], kv)) for i in range(3))  # type: ignore[return-value]


def rotation(k: Vec, c: Scalar, s: Scalar) -> Mat:
    """The matrix :math:`R(k, \\theta)` (columns: the unit vectors turned)."""
    cols = [rotate(k, c, s, e) for e in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))]
    return sy.transpose(tuple(cols))  # type: ignore[arg-type]


def subproblem1(k: Vec, p: Vec, q: Vec, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    r"""θ in (−π, π] with :math:`R(k, \theta) p = q` (best fit), and cos θ, sin θ: θ = atan2(y, x),
    :math:`y = k\cdot(p_\perp\times q_\perp)`, :math:`x = p_\perp\cdot q_\perp` (Elias & Wen 2022, subproblem 1),
    :math:`p_\perp = p - (k\cdot p)k`: the projections are formed first, so that a p or q close to k (a near-singular
    joint) keeps its relative precision. cos θ, sin θ = :math:`(x, y)/|(x, y)|` (a square root instead of two
    trigonometric calls); θ = 0, cos θ = 1 when p or q lies on k."""
    return unit(*plane_vector(k, p, q), ops)


def plane_vector(k: Vec, p: Vec, q: Vec) -> tuple[Scalar, Scalar]:
    r""":func:`subproblem1`'s :math:`(x, y) = \rho\,(\cos\theta, \sin\theta)`, :math:`\rho = |p_\perp|\,|q_\perp|`
    (the units of p times those of q; 0 where p or q lies on k)."""
    return _plane(k, _across(k, p), _across(k, q))


def turn_between(k: Vec, p: Vec, q: Vec, ops: Ops) -> tuple[Scalar, Scalar]:
    r"""cos θ, sin θ of the turn θ about the unit vector ``k`` that takes ``p`` to ``q``, where their parts
    :math:`p_\perp, q_\perp` across k are equally long (subproblem 1 where it has an exact solution):
    :math:`(p_\perp\cdot q_\perp,\ k\cdot(p_\perp\times q_\perp))/|p_\perp|^2`, no square root (whose Taylor
    model's remainder grows fast where its argument's bounds near 0); (1, 0) where p lies on k."""
    pp, qq = _across(k, p), _across(k, q)
    x, y = _plane(k, pp, qq)
    n2 = sy.dot(pp, pp)
    inv = 1.0 / ops.fmax(n2, 1e-300)
    return ops.where(n2 > 1e-300, x * inv, 1.0), y * inv


def _across(k: Vec, v: Vec) -> Vec:
    r"""The part of v across the unit vector k: :math:`v - (k\cdot v)\,k`."""
    return sy.vsub(v, sy.vscale(sy.dot(k, v), k))


def _plane(k: Vec, pp: Vec, qq: Vec) -> tuple[Scalar, Scalar]:
    r""":math:`(p_\perp\cdot q_\perp,\ k\cdot(p_\perp\times q_\perp))` of the parts across k."""
    return sy.dot(pp, qq), sy.dot(k, sy.cross(pp, qq))


def unit(x: Scalar, y: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    """θ = atan2(y, x) in (−π, π] and cos θ, sin θ = :math:`(x, y)/|(x, y)|` (:func:`subproblem1`); θ = 0, cos θ = 1 at
    (0, 0)."""
    rho = ops.sqrt(x * x + y * y)
    some = rho > 1e-300
    inv = 1.0 / ops.fmax(rho, 1e-300)
    return angle(y, x, ops), ops.where(some, x * inv, 1.0), y * inv


def line_root(a: Scalar, b: Scalar, c: Scalar, sign: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    r"""The root of sign σ = ``sign`` of :math:`a\cos\theta + b\sin\theta = c` as cos θ, sin θ, and the relative
    discriminant :math:`(r^2 - c^2)/r^2`, :math:`r^2 = a^2 + b^2` (negative: no root): :math:`\cos\theta = (ac -
    \sigma b\sqrt{r^2 - c^2})/r^2`, :math:`\sin\theta = (bc + \sigma a\sqrt{r^2 - c^2})/r^2`, no angle formed (the
    square root clamped at 0; subproblem 3 of Elias & Wen 2022 ends here)."""
    r2 = a * a + b * b
    disc = r2 - c * c
    root = ops.safe_sqrt(disc)
    inv = 1.0 / ops.fmax(r2, 1e-300)
    return (a * c - sign * b * root) * inv, (b * c + sign * a * root) * inv, disc * inv


def subproblem3(k: Vec, p: Vec, q: Vec, d2: Scalar, sign: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    r"""The root of sign σ = ``sign`` of :math:`|R(k, \theta)\,p - q|^2 = d^2` (Elias & Wen 2022, subproblem 3; p and q
    from one point of the axis, k a unit vector, ``d2`` = :math:`d^2`) as cos θ, sin θ and the relative discriminant
    (:func:`line_root`): :math:`q\cdot R(k, \theta)\,p = (|p|^2 + |q|^2 - d^2)/2`, linear in cos θ and sin θ."""
    kp, kq = sy.dot(k, p), sy.dot(k, q)
    a = sy.dot(p, q) - kp * kq
    b = sy.dot(q, sy.cross(k, p))
    c = 0.5 * (sy.dot(p, p) + sy.dot(q, q) - d2) - kp * kq
    return line_root(a, b, c, sign, ops)


def subproblem2(ka: Vec, pa: Vec, kb: Vec, pb: Vec, ops: Ops, signs: Signs = BOTH) -> tuple[list[Vec], Scalar, Scalar]:
    r"""The two vectors :math:`v_\pm = R(k_a, \theta_a) p_a = R(k_b, \theta_b) p_b` (Elias & Wen 2022, subproblem 2;
    :math:`k_a, k_b` constant unit vectors, not parallel; :math:`|p_a| = |p_b|`).

    :math:`v = \alpha k_a + \beta k_b \pm \gamma\,n`, :math:`n = k_a \times k_b`, from
    :math:`k_a\cdot v = k_a\cdot p_a`, :math:`k_b\cdot v = k_b\cdot p_b` and :math:`|v| = |p_a|`, in the form
    :math:`\gamma^2 (1 - c^2) = |p_b \times k_b|^2 - \alpha^2 (1 - c^2)`, :math:`c = k_a\cdot k_b` (the part of v off
    :math:`k_b` is that of :math:`p_b`): where :math:`p_b` nears :math:`k_b` (the shoulder singularity, axes 1 and 3
    aligned) and :math:`\alpha` is fixed (the Panda's :math:`\alpha = h_2\cdot h_3 = 0`) no difference of near
    equal numbers is formed, so q2 there keeps its absolute precision instead of the square root of it.
    Returns ``(v, measure, close)``: ``v`` the vectors :math:`\alpha k_a + \beta k_b + \sigma\gamma\,n` for the
    signs σ of ``signs`` (:data:`BOTH`: :math:`v_+, v_-`); ``measure`` :math:`= \gamma^2 (1 - c^2)/|p_a|^2`,
    continuous in the inputs, solvable where it is :math:`\ge -` EPS; ``close`` where :math:`\gamma^2 <` BRANCH_TOL
    :math:`|p_a|^2`.
    """
    c = float(np.dot(ka, kb))
    s2 = 1.0 - c * c
    n = sy.cross(ka, kb)
    A, B = sy.dot(ka, pa), sy.dot(kb, pb)
    al, be = (A - c * B) / s2, (B - c * A) / s2
    norm2 = sy.dot(pa, pa)
    pxk = sy.cross(pb, kb)
    g2s = sy.dot(pxk, pxk) - s2 * al * al  # γ² s2 = |v × k_b|² − α² s2, and |v × k_b| = |p_b × k_b|
    g = ops.safe_sqrt(g2s / s2)
    base = sy.vadd(sy.vscale(al, ka), sy.vscale(be, kb))
    measure = g2s / ops.fmax(norm2, 1e-300)
    close = measure < BRANCH_TOL * s2
    return [sy.vadd(base, sy.vscale(sign * g, n)) for sign in signs], measure, close
