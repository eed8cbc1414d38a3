r"""Yoshikawa's manipulability :math:`m = \sqrt{\det(J J^T)}` and its gradient, in the scalar algebra.

Written once against :mod:`qpik.algebra.symbolic`, so that the chains (:mod:`qpik.robots.chain`)
evaluate it on numpy batches and trace it into their compiled functions.
"""

from __future__ import annotations

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Scalar

DEGENERATE = 1e-16
r"""A QR pivot :math:`R_{ii}` of :math:`J^T` with :math:`R_{ii}^2` below this times :math:`\mathrm{tr}(J J^T)` counts
as singular."""


def manipulability_gradient_expr(J: list[list[Scalar]], H: list[list[list[Scalar]]]) -> tuple[list[Scalar], Scalar]:
    r"""∇m of :math:`m = \sqrt{\det(J J^T)}`, in the scalar algebra: ``(grad (n scalars), m)``.

    ``J[r][j]`` (r × n scalars: rows of the Jacobian, r = 6, or 3 for the translational
    index) and ``H[k][r][j]`` = :math:`\partial J_{rj}/\partial q_k` (n × r × n).
    By Jacobi's formula, with :math:`A = J J^T` and :math:`\partial A/\partial q_k = H_k J^T + J H_k^T`,
    :math:`\partial m/\partial q_k = m\,\mathrm{tr}(A^{-1} J H_k^T)`.

    Evaluated through the Householder QR :math:`J^T = Q R` (Q: n × r, orthonormal columns),
    not through :math:`J J^T`: with :math:`L = R^T`, :math:`J = L Q^T`, so
    :math:`m = |\prod_i R_{ii}|` and

    .. math:: \partial m/\partial q_k = m \sum_{i} (Q^T)_{i\cdot} \cdot (L^{-1} H_k)_{i\cdot},

    one forward substitution per k. Forming :math:`J J^T` squares the condition number
    of J (near a singularity the result then depends on the order of the operations:
    numpy and compiled code disagreed by ~1e-9 at m ~ 1e-5); the QR keeps the error
    proportional to it. Where a pivot has :math:`R_{ii}^2` at most :data:`DEGENERATE` ·
    tr A (m is not differentiable at m = 0) the result is 0, the limit of the formula
    with m = 0. With fewer joints than rows (n < r), m = 0 everywhere and so is ∇m.
    """
    ops = sy.ops_of(J, H)
    rows, n = len(J), len(J[0])
    if rows > n:  # fewer joints than task rows: det(J Jᵀ) = 0 for every q
        return [0.0] * n, 0.0
    X = [list(J[c]) for c in range(rows)]  # the columns of Jᵀ, n scalars each
    tiny = DEGENERATE * sum(sy.lin(*zip(J[r], J[r])) for r in range(rows))
    reflections = []
    R: list[list[Scalar]] = [[0.0] * rows for _ in range(rows)]
    for c in range(rows):
        x = X[c][c:]
        norm = ops.sqrt(sy.lin(*zip(x, x)))
        sign = ops.where(x[0] >= 0, 1.0, -1.0)
        v = [x[0] + sign * norm, *x[1:]]  # H = I - β v vᵀ maps x to -sign·|x| e_0
        vtv = sy.lin(*zip(v, v))
        beta = ops.where(vtv > 0, 2.0 / ops.where(vtv > 0, vtv, 1.0), 0.0)
        reflections.append((v, beta))
        R[c][c] = -sign * norm
        for d in range(c + 1, rows):
            w = beta * sy.lin(*zip(v, X[d][c:]))
            X[d][c:] = [a - w * b for a, b in zip(X[d][c:], v)]
            R[c][d] = X[d][c]
    # Q = H_0 ⋯ H_{r-1} [I; 0], applied column by column (the last reflection first)
    Q = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(rows)]  # Q[i] = column i of Q, n scalars
    for c in reversed(range(rows)):
        v, beta = reflections[c]
        for i in range(rows):
            w = beta * sy.lin(*zip(v, Q[i][c:]))
            Q[i][c:] = [a - w * b for a, b in zip(Q[i][c:], v)]
    ok: Scalar = 1.0
    det: Scalar = 1.0
    inv: list[Scalar] = []
    for i in range(rows):
        good = R[i][i] * R[i][i] > tiny
        ok = ops.where(good, ok, 0.0)
        inv.append(1.0 / ops.where(good, R[i][i], 1.0))
        det = det * R[i][i]
    m = ops.where(ok > 0.5, ops.fabs(det), 0.0)
    grad = []
    for k in range(n):
        G: list[list[Scalar]] = []  # G = L⁻¹ H_k, with L[i][t] = R[t][i]
        total: Scalar = 0.0
        for i in range(rows):
            G.append(
                [sy.mul(sy.sub(H[k][i][j], sy.lin(*((R[t][i], G[t][j]) for t in range(i)))), inv[i]) for j in range(n)]
            )
            total = sy.add(total, sy.lin(*zip(Q[i], G[i])))
        grad.append(m * total)
    return grad, m


def manipulability_gradient_from(J: np.ndarray, H: np.ndarray, translational: bool = False) -> np.ndarray:
    """∇m (..., n) from a Jacobian (..., 6, n) and Hessian (..., n, 6, n) (numpy).

    See :func:`manipulability_gradient_expr`.
    """
    J, H = np.asarray(J, dtype=float), np.asarray(H, dtype=float)
    rows, n = (3 if translational else 6), J.shape[-1]
    Js = [[J[..., r, j] for j in range(n)] for r in range(rows)]
    Hs = [[[H[..., k, r, j] for j in range(n)] for r in range(rows)] for k in range(n)]
    grad, _ = manipulability_gradient_expr(Js, Hs)
    return np.stack([np.broadcast_to(g, J.shape[:-2]) for g in grad], axis=-1)


def jacobian_rows(jv: list[sy.Vec], jw: list[sy.Vec]) -> list[list[Scalar]]:
    """The geometric Jacobian's columns (linear, angular parts) as rows ``J[r][j]`` (6 × n scalars)."""
    return [[(jv[j] if r < 3 else jw[j])[r % 3] for j in range(len(jv))] for r in range(6)]


def hessian_rows(H: list[list[tuple[sy.Vec, sy.Vec]]]) -> list[list[list[Scalar]]]:
    """A kinematic Hessian ``H[k][j] = (linear, angular)`` as ``H[k][r][j]`` (n × 6 × n scalars)."""
    return [[[(row[j][0] if r < 3 else row[j][1])[r % 3] for j in range(len(row))] for r in range(6)] for row in H]
