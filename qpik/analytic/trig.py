r"""Trigonometric kernel (Sabharwal 2021): atan2 everywhere, no division that can blow up.

Every function works on Python floats, numpy arrays (element-wise) and CasADi
symbols through an :class:`qpik.algebra.symbolic.Ops` backend, and returns both roots
plus a flag saying whether the equation is solvable. When it is not, the
roots are still finite (the argument of the square root is clamped), so no
NaN ever reaches a caller.
"""

from __future__ import annotations

import numpy as np

from qpik.algebra.symbolic import Ops, Scalar

EPS = 1e-12


def solve_cos_sin(a: Scalar, b: Scalar, c: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    r"""Roots of :math:`a\cos\theta + b\sin\theta = c`.

    :math:`\theta = \mathrm{atan2}(b, a) \pm \mathrm{atan2}(\sqrt{a^2+b^2-c^2},\, c)` (Sabharwal 2021, eq. 20).

    Returns ``(theta_plus, theta_minus, ok)``; ``ok`` is true where
    :math:`a^2 + b^2 \ge c^2` and :math:`(a, b) \ne 0`. Where the discriminant is
    slightly negative (round-off) the roots coincide at the closest point.
    """
    r2 = a * a + b * b
    disc = r2 - c * c
    phi = ops.atan2(b, a)
    beta = ops.atan2(ops.safe_sqrt(disc), c)
    ok = (disc >= -EPS * ops.fmax(r2, 1.0)) * (r2 > EPS)
    return phi + beta, phi - beta, ok


def asin2(s: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    r"""Both angles with :math:`\sin\theta = s`: ``atan2(s, ±sqrt(1-s²))``, and ``ok = |s| <= 1``."""
    c = ops.safe_sqrt(1.0 - s * s)
    ok = ops.fabs(s) <= 1.0 + EPS
    s_cl = ops.fmin(ops.fmax(s, -1.0), 1.0)
    return ops.atan2(s_cl, c), ops.atan2(s_cl, -c), ok


def acos2(c: Scalar, ops: Ops) -> tuple[Scalar, Scalar, Scalar]:
    r"""Both angles with :math:`\cos\theta = c`: ``±atan2(sqrt(1-c²), c)``, and ``ok = |c| <= 1``."""
    s = ops.safe_sqrt(1.0 - c * c)
    ok = ops.fabs(c) <= 1.0 + EPS
    c_cl = ops.fmin(ops.fmax(c, -1.0), 1.0)
    t = ops.atan2(s, c_cl)
    return t, -t, ok


CosSin = tuple[Scalar, Scalar]


def solve_cos_sin_cs(a: Scalar, b: Scalar, c: Scalar, ops: Ops) -> tuple[CosSin, CosSin, Scalar]:
    r"""Cosine and sine of both roots of :math:`a\cos\theta + b\sin\theta = c`, without any trig call.

    With :math:`\rho^2 = a^2 + b^2` and :math:`\sigma = \sqrt{\rho^2 - c^2}` (clamped at 0), the
    roots of :func:`solve_cos_sin` are

    .. math:: \theta_\pm:\quad \cos\theta_\pm = (a c \mp b\sigma)/\rho^2,\qquad
              \sin\theta_\pm = (b c \pm a\sigma)/\rho^2 .

    Returns ``((cos θ+, sin θ+), (cos θ-, sin θ-), ok)``; ``atan2(sin, cos)`` gives the
    angle. The division is by :math:`\max(\rho^2, 10^{-12})`, so nothing blows up
    where ``ok`` is false (the pairs are then finite but not unit).
    """
    r2 = a * a + b * b
    disc = r2 - c * c
    sq = ops.safe_sqrt(disc)
    k = 1.0 / ops.fmax(r2, EPS)
    ac, bc, asq, bsq = a * c, b * c, a * sq, b * sq
    ok = (disc >= -EPS * ops.fmax(r2, 1.0)) * (r2 > EPS)
    return ((ac - bsq) * k, (bc + asq) * k), ((ac + bsq) * k, (bc - asq) * k), ok


def angle(y: Scalar, x: Scalar, ops: Ops) -> Scalar:
    r"""``atan2(y, x)`` in :math:`(-\pi, \pi]`.

    ``atan2`` returns :math:`-\pi` for ``y = -0.0`` (or ``y`` negative below round-off) and
    ``x < 0``; that value becomes :math:`\pi`.
    """
    t = ops.atan2(y, x)
    return ops.where(t > -np.pi, t, np.pi)


def flip(theta: Scalar, ops: Ops) -> Scalar:
    r""":math:`\theta \pm \pi` wrapped to :math:`(-\pi, \pi]`, for :math:`\theta \in (-\pi, \pi]`."""
    return ops.where(theta > 0, theta - np.pi, theta + np.pi)
