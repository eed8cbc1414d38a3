r"""Real roots of :math:`F(\delta) = A(\cos\delta) + \sin\delta\, B(\cos\delta)`: the wrist breakpoint equations.

The offset-shoulder arm's wrist equations (:mod:`qpik.analytic.offset_shoulder_intervals`)
have this form, A and B polynomials in :math:`c = \cos\delta` with
:math:`n = \max(\deg A, \deg B + 1) \le 8`. With :math:`t = \tan(\delta/2)`
(:math:`\cos\delta = (1-t^2)/(1+t^2)`, :math:`\sin\delta = 2t/(1+t^2)`),

.. math:: H(t) = (1+t^2)^n F = \sum_i a_i (1-t^2)^i (1+t^2)^{n-i}
          + 2t \sum_i b_i (1-t^2)^i (1+t^2)^{n-1-i}

is a polynomial of degree 2n whose real roots are exactly :math:`\tan(\delta/2)` of the
roots of F (no squaring, so no spurious roots). Its roots with :math:`|t| \le 1`
(:math:`|\delta| \le \pi/2`) and those of the reversed polynomial :math:`t^{2n} H(1/t)` in
:math:`|1/t| \le 1` (:math:`|\delta| \ge \pi/2`) cover the circle, each where
:math:`d\delta/dt \in [1, 2]`: well conditioned everywhere (a first version went through
:math:`c = \cos\delta`, where :math:`d\delta = -dc/\sin\delta` lost the roots near 0 and π).

``polyroots.c`` finds the real roots of H in [−1, 1] between its critical points: the
roots of H′ are isolated by Descartes' rule of signs in the Bernstein basis (on an
interval, the sign changes V of the Bernstein coefficients bound the roots there: V = 0
excludes the interval, V = 1 brackets one root, V ≥ 2 halves it by de Casteljau); between
consecutive critical points H is monotone, so each sign change there is one root (Newton's
method safeguarded by bisection), and a critical point where
:math:`|H| \le 10^{-12} \sum |h_i|` is reported as well (a double root, or two roots
closer than rounding separates: next to those, rounding can hide the sign changes of
the Bernstein coefficients of H itself). A critical point is itself found (Newton on H′)
only where its bracket does not settle that: where :math:`|H|` exceeds the bound at both ends of
the bracket and H either changes sign in it (one root) or moves away from zero into it
(no root, and :math:`|H|` above the bound at the extremum too), the bracket's ends serve instead.
Eigenvalues of companion matrices (``numpy.linalg.eigvals``) would cost several times
more per ``qpik.feasible_intervals`` call (see ``qpik bench analytic``). The C source is
compiled once by the system compiler (:func:`qpik.native.sources.load_source`); without
one (or with ``QPIK_NATIVE=0``) the roots of H come from ``numpy``'s companion
eigenvalues instead, every eigenvalue within ``EIG_IMAG`` of the real axis counting
as real; that path resolves a double root only to about √ε (1e-8 rad), the C path to 1e-9 rad
or better.

The roots are *candidates* for the feasible-interval breakpoints: an extra one
only splits a gap, so both paths err on the side of reporting.
"""

from __future__ import annotations

import ctypes
from functools import cache

import numpy as np

from qpik.core.errors import InputError
from qpik.native.sources import load_source

EIG_IMAG = 1e-7
r"""Eigenvalue path: :math:`|\operatorname{Im} t|` below which an eigenvalue counts as real."""
MAX_DEGREE = 16
"""Largest n = max(deg A, deg B + 1) (H has degree 2n ≤ 32)."""


FLAGS = ("-funroll-loops",)
"""Compiler flags of a library holding ``polyroots.c`` (besides :data:`qpik.native.build.CFLAGS`): its short loops over
the coefficients unrolled, about 10 % faster."""


@cache
def _library() -> ctypes.CDLL | None:
    """``polyroots.c`` compiled (:func:`qpik.native.sources.load_source`), or None without a compiler."""
    args = [ctypes.c_int, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int] + [ctypes.c_void_p] * 2
    return load_source("qpik_polyroots", "cdll", ["polyroots.c"], flags=FLAGS,
                       signatures={"qpik_trig_roots": (ctypes.c_int, args)})  # fmt: skip


ROOM = 2 * 128
"""Room for roots per row: polyroots.c reports at most 128 candidates in each half of the circle."""


def trig_roots(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Roots δ ∈ [−π, π] (rad) of :math:`A_k(\cos\delta) + \sin\delta\, B_k(\cos\delta)` for every row k.

    Args:
        A, B: coefficients (K, d + 1), lowest degree first, max(deg A, deg B + 1) ≤ ``MAX_DEGREE`` per row.

    Returns:
        ``(delta, owner)``: the roots (M,) and the row (M,) of each.
    """
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    if A.ndim != 2 or A.shape != B.shape or A.shape[1] < 1:
        raise InputError(f"trig_roots: A, B must be (K, d + 1), the same shape; got {A.shape}, {B.shape}")
    lib = _library()
    if lib is None:
        cols = np.arange(A.shape[1])
        degree = max(cols[A.any(axis=0)].max(initial=0), cols[B.any(axis=0)].max(initial=-1) + 1)
        if degree > MAX_DEGREE:  # polyroots.c checks it per row
            raise InputError(f"trig_roots: max(deg A, deg B + 1) above {MAX_DEGREE}")
        return _eig_roots(A, B)
    a, b, delta, owner, where = _buffers(*A.shape)
    a[...], b[...] = A, B  # copies into fixed buffers, whose addresses are known
    m = lib.qpik_trig_roots(A.shape[0], A.shape[1] - 1, where[0], where[1], delta.size, where[2], where[3])
    if m < 0:
        raise InputError(f"trig_roots: max(deg A, deg B + 1) above {MAX_DEGREE}")
    return delta[:m].copy(), owner[:m].copy()


@cache
def _buffers(K: int, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[int, ...]]:
    """Input (K, size) and output buffers of the C call for K rows, and their addresses (reused; trig_roots
    returns copies)."""
    out = np.empty((K, size)), np.empty((K, size)), np.empty(ROOM * K), np.empty(ROOM * K, dtype=np.intc)
    return (*out, tuple(x.ctypes.data for x in out))


def _eig_roots(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The path without a C compiler: H's real roots from its companion matrix."""
    P = np.polynomial.polynomial
    out, owner = [], []
    for k, (a, b) in enumerate(zip(A, B)):
        a, b = np.trim_zeros(a, "b"), np.trim_zeros(b, "b")
        n = max(a.size - 1, b.size)
        if n <= 0:
            continue
        H = np.zeros(2 * n + 1)
        for i, ai in enumerate(a):
            H += ai * _basis(i, n - i, H.size)
        for i, bi in enumerate(b):
            H[1:] += 2.0 * bi * _basis(i, n - 1 - i, H.size - 1)
        t = P.polyroots(np.trim_zeros(H, "b"))
        d = 2.0 * np.arctan(t.real[np.abs(t.imag) <= EIG_IMAG * np.maximum(1.0, np.abs(t))])
        if abs(H[-1]) <= 1e-12 * np.abs(H).max():  # degree drop: a root at t = ∞, δ = π
            d = np.append(d, np.pi)
        out.append(d)
        owner.append(np.full(d.size, k))
    if not out:
        return np.zeros(0), np.zeros(0, int)
    return np.concatenate(out), np.concatenate(owner)


def _basis(i: int, m: int, size: int) -> np.ndarray:
    """Coefficients of (1 − t²)^i (1 + t²)^m, lowest first, padded to ``size``."""
    P = np.polynomial.polynomial
    out = np.zeros(size)
    c = P.polymul(P.polypow([1.0, 0.0, -1.0], i), P.polypow([1.0, 0.0, 1.0], m))
    out[: c.size] = c
    return out
