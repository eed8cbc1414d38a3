"""Scalar algebra that runs on numpy arrays and on CasADi symbols alike.

Every closed-form expression in qpik (DH kinematics, the analytic IK solvers)
is written once against this module. A *scalar* is a Python number, a numpy
array (a batch, evaluated element-wise) or a CasADi ``SX``/``MX`` scalar.
Vectors are 3-tuples of scalars and rotations are 3-tuples of row 3-tuples,
so that one source serves

- numpy, batched: every scalar is an array of shape ``(N,)`` (or anything
  that broadcasts);
- CasADi: every scalar is an ``SX`` expression, to differentiate exactly or
  to compile into a fast function (:mod:`qpik.native.compiled`).

Python numbers 0 and ±1 are folded at build time, so constant structure
(for example ``alpha = pi/2``) costs nothing at run time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

Scalar = Any
Vec = tuple[Scalar, Scalar, Scalar]
Mat = tuple[Vec, Vec, Vec]


@dataclass(frozen=True)
class Ops:
    """The elementary functions of one backend."""

    name: str
    sin: Callable[[Scalar], Scalar]
    cos: Callable[[Scalar], Scalar]
    atan2: Callable[[Scalar, Scalar], Scalar]
    sqrt: Callable[[Scalar], Scalar]
    fabs: Callable[[Scalar], Scalar]
    fmax: Callable[[Scalar, Scalar], Scalar]
    fmin: Callable[[Scalar, Scalar], Scalar]
    where: Callable[[Scalar, Scalar, Scalar], Scalar]
    floor: Callable[[Scalar], Scalar]

    def wrap(self, x: Scalar) -> Scalar:
        """Wrap an angle to (-pi, pi]: ``x + 2π floor((π - x) / 2π)`` (so -π maps to π)."""
        return x + 2.0 * np.pi * self.floor((np.pi - x) / (2.0 * np.pi)) if not _const(x) else _wrap_const(x)

    def safe_sqrt(self, x: Scalar) -> Scalar:
        """sqrt(max(x, 0)): never NaN for a slightly negative argument."""
        return self.sqrt(self.fmax(x, 0.0))


def _wrap_const(x: float) -> float:
    return float(x + 2.0 * np.pi * np.floor((np.pi - x) / (2.0 * np.pi)))


def _np_where(c: Scalar, a: Scalar, b: Scalar) -> Scalar:
    return np.where(c, a, b)


def _ca_where(c: Scalar, a: Scalar, b: Scalar) -> Scalar:
    return ca.if_else(c, a, b)


NUMPY = Ops("numpy", np.sin, np.cos, np.arctan2, np.sqrt, np.abs, np.maximum, np.minimum, _np_where, np.floor)
CASADI = Ops("casadi", ca.sin, ca.cos, ca.atan2, ca.sqrt, ca.fabs, ca.fmax, ca.fmin, _ca_where, ca.floor)


def ops_of(*xs: Any) -> Ops:
    """The backend of the given scalars: CasADi if any of them is symbolic."""
    stack = list(xs)
    while stack:
        x = stack.pop()
        if isinstance(x, (ca.SX, ca.MX, ca.DM)):
            return CASADI
        if isinstance(x, (tuple, list)):
            stack.extend(x)
    return NUMPY


# ---- constant folding -------------------------------------------------------


def _const(x: Scalar) -> bool:
    return isinstance(x, (int, float))


def snap(x: float, tol: float = 1e-15) -> float:
    """Round a constant to 0 or ±1 when it is within ``tol`` (cos(pi/2) -> 0)."""
    for v in (0.0, 1.0, -1.0):
        if abs(x - v) < tol:
            return v
    return float(x)


def mul(a: Scalar, b: Scalar) -> Scalar:
    """a*b with 0 and ±1 folded."""
    if _const(a):
        if a == 0:
            return 0.0
        if a == 1:
            return b
        if a == -1:
            return neg(b)
    if _const(b):
        if b == 0:
            return 0.0
        if b == 1:
            return a
        if b == -1:
            return neg(a)
    return a * b


def add(a: Scalar, b: Scalar) -> Scalar:
    """a+b with 0 folded."""
    if _const(a) and a == 0:
        return b
    if _const(b) and b == 0:
        return a
    return a + b


def neg(a: Scalar) -> Scalar:
    return -a if not (_const(a) and a == 0) else 0.0


def sub(a: Scalar, b: Scalar) -> Scalar:
    return add(a, neg(b))


def lin(*pairs: tuple[Scalar, Scalar]) -> Scalar:
    """Sum of products ``sum(a*b for a, b in pairs)`` with folding."""
    out: Scalar = 0.0
    for a, b in pairs:
        out = add(out, mul(a, b))
    return out


# ---- vectors and rotations --------------------------------------------------


def dot(u: Vec, v: Vec) -> Scalar:
    return lin((u[0], v[0]), (u[1], v[1]), (u[2], v[2]))


def cross(u: Vec, v: Vec) -> Vec:
    return (
        sub(mul(u[1], v[2]), mul(u[2], v[1])),
        sub(mul(u[2], v[0]), mul(u[0], v[2])),
        sub(mul(u[0], v[1]), mul(u[1], v[0])),
    )


def vadd(u: Vec, v: Vec) -> Vec:
    return (add(u[0], v[0]), add(u[1], v[1]), add(u[2], v[2]))


def vsub(u: Vec, v: Vec) -> Vec:
    return (sub(u[0], v[0]), sub(u[1], v[1]), sub(u[2], v[2]))


def vscale(s: Scalar, v: Vec) -> Vec:
    return (mul(s, v[0]), mul(s, v[1]), mul(s, v[2]))


def col(R: Mat, j: int) -> Vec:
    return (R[0][j], R[1][j], R[2][j])


def transpose(R: Mat) -> Mat:
    return (col(R, 0), col(R, 1), col(R, 2))


def matvec(R: Mat, v: Vec) -> Vec:
    return (dot(R[0], v), dot(R[1], v), dot(R[2], v))


def matmul(A: Mat, B: Mat) -> Mat:
    Bt = transpose(B)
    return tuple(tuple(dot(A[i], Bt[j]) for j in range(3)) for i in range(3))  # type: ignore[return-value]


def solve_spd(A: list[list[Scalar]], b: list[Scalar]) -> list[Scalar]:
    r"""x with :math:`A x = b` for a symmetric positive definite A (m × m, its lower triangle read; rows of scalars)
    and b (m scalars), by :math:`A = L D L^T` (no square root, no pivoting)."""
    n = len(b)
    L: list[list[Scalar]] = [[0.0] * n for _ in range(n)]
    d: list[Scalar] = [0.0] * n
    for j in range(n):
        d[j] = A[j][j] - sum((L[j][k] * L[j][k] * d[k] for k in range(j)), 0.0)
        for i in range(j + 1, n):
            L[i][j] = (A[i][j] - sum((L[i][k] * L[j][k] * d[k] for k in range(j)), 0.0)) / d[j]
    y: list[Scalar] = [0.0] * n
    for i in range(n):
        y[i] = b[i] - sum((L[i][k] * y[k] for k in range(i)), 0.0)
    x: list[Scalar] = [0.0] * n
    for i in reversed(range(n)):
        x[i] = y[i] / d[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), 0.0)
    return x


Frame = tuple[Mat, Vec]


def compose(A: Frame, B: Frame) -> Frame:
    """Homogeneous product A*B of frames given as (rotation, translation)."""
    return matmul(A[0], B[0]), vadd(matvec(A[0], B[1]), A[1])


def frame_of(T: np.ndarray) -> Frame:
    """A constant numpy (4, 4) transform as a folded frame."""
    R = tuple(tuple(snap(float(T[i, j])) for j in range(3)) for i in range(3))
    p = tuple(snap(float(T[i, 3])) for i in range(3))
    return R, p  # type: ignore[return-value]


def frame_of_batch(T: Any) -> Frame:
    """A numeric batch (..., 4, 4) or a CasADi (4, 4) matrix as a frame of scalars."""
    if isinstance(T, (ca.SX, ca.MX, ca.DM)):
        R = tuple(tuple(T[i, j] for j in range(3)) for i in range(3))
        return R, (T[0, 3], T[1, 3], T[2, 3])  # type: ignore[return-value]
    T = np.asarray(T)
    R = tuple(tuple(T[..., i, j] for j in range(3)) for i in range(3))
    return R, (T[..., 0, 3], T[..., 1, 3], T[..., 2, 3])  # type: ignore[return-value]


def rot_z(c: Scalar, s: Scalar) -> Mat:
    return ((c, neg(s), 0.0), (s, c, 0.0), (0.0, 0.0, 1.0))


def rot_x(c: Scalar, s: Scalar) -> Mat:
    return ((1.0, 0.0, 0.0), (0.0, c, neg(s)), (0.0, s, c))


# ---- assembling outputs -----------------------------------------------------


def stack(items: list[Scalar], ops: Ops, batch_shape: tuple[int, ...] = ()) -> Any:
    """Stack scalars into a numpy array ``(*batch, len)`` or a CasADi column."""
    if ops is CASADI:
        return ca.vertcat(*items)
    return np.stack([np.broadcast_to(np.asarray(x, dtype=float), batch_shape) for x in items], axis=-1)
