r"""Denavit–Hartenberg chains: FK, geometric Jacobian, kinematic Hessian, manipulability.

One :class:`DHChain` holds a DH table in either convention:

- ``standard``: :math:`A_i = R_z(\theta_i + o_i)\,T_z(d_i)\,T_x(a_i)\,R_x(\alpha_i)`
  (Nammoto & Kosuge 2012, eq. 1); joint *i* turns about the z axis of frame *i-1*.
- ``modified`` (Craig): :math:`A_i = R_x(\alpha_{i-1})\,T_x(a_{i-1})\,R_z(\theta_i + o_i)\,T_z(d_i)`;
  joint *i* turns about the z axis of frame *i*.

Frame 0 is ``base`` (a constant transform from the world), the end-effector is
``frame_n @ tool``. The expressions are written once in :mod:`qpik.symbolic`
and evaluated three ways: numpy over a batch, CasADi symbols, and a compiled
CasADi function for one configuration (the fast path, :mod:`qpik.compiled`).

Conventions: metres and radians; the geometric Jacobian rows are
``[v; ω]`` of the end-effector origin, both in the base (world) frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import casadi as ca
import numpy as np

from qpik import symbolic as sy
from qpik.compiled import Compiled
from qpik.errors import InputError
from qpik.symbolic import Frame, Ops, Scalar
from qpik.validate import bounded, finite_array, flag, joint_vector

Convention = Literal["standard", "modified"]


@dataclass(frozen=True)
class DHChain:
    """A revolute serial chain described by a DH table.

    Attributes:
        a, d, alpha, offset: DH parameters per joint (m, m, rad, rad), shape (n,).
            In the ``modified`` convention ``a[i]`` and ``alpha[i]`` are Craig's
            :math:`a_{i-1}`, :math:`\alpha_{i-1}` (they precede joint *i*).
        convention: ``"standard"`` or ``"modified"``.
        base: (4, 4) world-from-frame-0 transform.
        tool: (4, 4) frame-n-from-end-effector transform.
    """

    a: tuple[float, ...]
    d: tuple[float, ...]
    alpha: tuple[float, ...]
    offset: tuple[float, ...] = ()
    convention: Convention = "standard"
    base: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        for name in ("a", "d", "alpha", "offset"):  # finite numbers, lengths within 1e6 m
            bounded(finite_array(getattr(self, name), f"DHChain.{name}", (None,)), f"DHChain.{name}")
        n = len(self.a)
        if not (len(self.d) == len(self.alpha) == n) or (len(self.offset) and len(self.offset) != n):
            raise InputError("DHChain: a, d, alpha (and offset) must have the same length")
        if self.convention not in ("standard", "modified"):
            raise InputError(f"DHChain.convention: unknown convention {self.convention!r}")
        object.__setattr__(self, "offset", tuple(self.offset) or (0.0,) * n)
        for name in ("base", "tool"):
            finite_array(getattr(self, name), f"DHChain.{name}", (4, 4))

    @property
    def dof(self) -> int:
        return len(self.a)

    # ---- the one definition -------------------------------------------------

    def frames_expr(self, q: list[Scalar], ops: Ops) -> list[Frame]:
        """Frames 0..n and the end-effector, as :mod:`qpik.symbolic` frames.

        Returns ``n + 2`` frames: ``[base, frame_1, ..., frame_n, ee]``.
        """
        frames = [sy.frame_of(self.base)]
        for i in range(self.dof):
            th = q[i] + self.offset[i] if self.offset[i] else q[i]
            c, s = ops.cos(th), ops.sin(th)
            ca_, sa = sy.snap(np.cos(self.alpha[i])), sy.snap(np.sin(self.alpha[i]))
            if self.convention == "standard":
                R = sy.matmul(sy.rot_z(c, s), sy.rot_x(ca_, sa))
                p = (sy.mul(self.a[i], c), sy.mul(self.a[i], s), self.d[i])
            else:
                Rx = sy.rot_x(ca_, sa)
                R = sy.matmul(Rx, sy.rot_z(c, s))
                p = sy.vadd((self.a[i], 0.0, 0.0), sy.matvec(Rx, (0.0, 0.0, self.d[i])))
            frames.append(sy.compose(frames[-1], (R, p)))
        frames.append(sy.compose(frames[-1], sy.frame_of(self.tool)))
        return frames

    def axes_expr(self, frames: list[Frame]) -> list[tuple[sy.Vec, sy.Vec]]:
        """Joint axes as (unit axis z_i, point p_i on the axis), world frame."""
        idx = range(self.dof) if self.convention == "standard" else range(1, self.dof + 1)
        return [(sy.col(frames[k][0], 2), frames[k][1]) for k in idx]

    def point_jacobian_expr(self, frames: list[Frame], point: sy.Vec, link: int) -> list[sy.Vec]:
        r"""Columns of the translational Jacobian of a world point rigidly attached to link ``link`` (1..n).

        Joint ``j`` turns about the unit axis :math:`z_j` through :math:`o_j` (world frame),
        so :math:`\dot p = \sum_{j \le link} z_j \times (p - o_j)\,\dot q_j`; returns the
        ``link`` columns :math:`z_j \times (p - o_j)` (the joints beyond ``link`` do not move it).
        """
        return [sy.cross(z, sy.vsub(point, o)) for z, o in self.axes_expr(frames)[:link]]

    def jacobian_expr(self, frames: list[Frame]) -> tuple[list[sy.Vec], list[sy.Vec]]:
        """Columns of the geometric Jacobian: (linear parts, angular parts)."""
        jv = self.point_jacobian_expr(frames, frames[-1][1], self.dof)
        jw = [z for z, _ in self.axes_expr(frames)]
        return jv, jw

    def hessian_expr(
        self, frames: list[Frame], jacobian: tuple[list[sy.Vec], list[sy.Vec]] | None = None
    ) -> list[list[tuple[sy.Vec, sy.Vec]]]:
        r"""Kinematic Hessian: ``H[k][j] = ∂J[:, j]/∂q_k`` as (linear, angular) parts.

        For revolute joints with axes :math:`z_i` and linear columns :math:`J_{v,i}`:
        :math:`∂J_{v,j}/∂q_k = z_{\min(j,k)} \times J_{v,\max(j,k)}`, and
        :math:`∂z_j/∂q_k = z_k \times z_j` for :math:`k < j`, else 0. ``jacobian``: the
        columns of :meth:`jacobian_expr` if the caller has them already.
        """
        jv, jw = self.jacobian_expr(frames) if jacobian is None else jacobian
        zero = (0.0, 0.0, 0.0)
        H = []
        for k in range(self.dof):
            row = []
            for j in range(self.dof):
                lo, hi = min(j, k), max(j, k)
                hv = sy.cross(jw[lo], jv[hi])
                hw = sy.cross(jw[k], jw[j]) if k < j else zero
                row.append((hv, hw))
            H.append(row)
        return H

    # ---- CasADi -------------------------------------------------------------

    @cached_property
    def casadi_functions(self) -> dict[str, ca.Function]:
        """CasADi functions of ``q`` (n,): ``fk`` -> (4,4), ``jacobian`` -> (6,n),
        ``fk_jacobian`` -> both, ``frames`` -> (4, 4*(n+2)) side by side,
        ``hessian`` -> (6*n, n) with rows ``[k*6:(k+1)*6]`` = ∂J/∂q_k,
        ``manipulability_gradient`` -> ∇m (n,) and the translational ∇m (n,)."""
        q = ca.SX.sym("q", self.dof)
        frames = self.frames_expr([q[i] for i in range(self.dof)], sy.CASADI)
        T = _frame_to_sx(frames[-1])
        jv, jw = self.jacobian_expr(frames)
        J = ca.horzcat(*[ca.vertcat(*v, *w) for v, w in zip(jv, jw)])
        H = self.hessian_expr(frames, (jv, jw))
        Hs = ca.vertcat(*[ca.horzcat(*[ca.vertcat(*hv, *hw) for hv, hw in row]) for row in H])
        F = ca.horzcat(*[_frame_to_sx(f) for f in frames])
        Jr, Hr = _jacobian_rows(jv, jw), _hessian_rows(H)
        grad = [manipulability_gradient_expr(Jr[:rows], [Hk[:rows] for Hk in Hr])[0] for rows in (6, 3)]
        return {
            "fk": ca.Function("fk", [q], [T]),
            "jacobian": ca.Function("jacobian", [q], [J]),
            "fk_jacobian": ca.Function("fk_jacobian", [q], [T, J]),
            "frames": ca.Function("frames", [q], [F]),
            "hessian": ca.Function("hessian", [q], [Hs]),
            "manipulability_gradient": ca.Function(
                "manipulability_gradient", [q], [ca.vertcat(*grad[0]), ca.vertcat(*grad[1])]
            ),
        }

    @cached_property
    def _compiled(self) -> dict[str, Compiled]:
        """The fast single-q evaluators of :attr:`casadi_functions`, each built on first use."""
        return _LazyCompiled(self.casadi_functions)

    # ---- numeric API --------------------------------------------------------

    def _batch(self, q: np.ndarray) -> list[Frame]:
        return self.frames_expr([q[:, i] for i in range(self.dof)], sy.NUMPY)

    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector pose in the world frame: q (n,) -> (4, 4); q (N, n) -> (N, 4, 4)."""
        q, batched = joint_vector(q, self.dof)
        if not batched:
            return self._compiled["fk"](q)[0].copy()
        return _frame_to_np(self._batch(q)[-1], len(q))

    def frames(self, q: np.ndarray) -> np.ndarray:
        """World poses of ``[base, frame_1..frame_n, ee]``: (n+2, 4, 4) or (N, n+2, 4, 4)."""
        q, batched = joint_vector(q, self.dof)
        if not batched:
            F = self._compiled["frames"](q)[0]
            return F.reshape(4, self.dof + 2, 4).transpose(1, 0, 2).copy()
        fr = self._batch(q)
        return np.stack([_frame_to_np(f, len(q)) for f in fr], axis=1)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian ``[v; ω]`` (world frame): (6, n) or (N, 6, n)."""
        q, batched = joint_vector(q, self.dof)
        if not batched:
            return self._compiled["jacobian"](q)[0].copy()
        return self._jac_np(self._batch(q), len(q))

    def fk_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose and Jacobian together (one kinematics pass)."""
        q, batched = joint_vector(q, self.dof)
        if not batched:
            T, J = self._compiled["fk_jacobian"](q)
            return T.copy(), J.copy()
        fr = self._batch(q)
        return _frame_to_np(fr[-1], len(q)), self._jac_np(fr, len(q))

    def _jac_np(self, fr: list[Frame], n: int) -> np.ndarray:
        jv, jw = self.jacobian_expr(fr)
        cols = [sy.stack([*v, *w], sy.NUMPY, (n,)) for v, w in zip(jv, jw)]
        return np.stack(cols, axis=-1)

    def hessian(self, q: np.ndarray) -> np.ndarray:
        """Kinematic Hessian ``H[..., k, :, j] = ∂J[:, j]/∂q_k``: (n, 6, n) or (N, n, 6, n)."""
        q, batched = joint_vector(q, self.dof)
        n = self.dof
        if not batched:
            return self._compiled["hessian"](q)[0].reshape(n, 6, n).copy()
        H = self.hessian_expr(self._batch(q))
        return np.stack(
            [np.stack([sy.stack([*hv, *hw], sy.NUMPY, (len(q),)) for hv, hw in row], axis=-1) for row in H],
            axis=1,
        )

    def manipulability(self, q: np.ndarray, translational: bool = False) -> np.ndarray | float:
        """Yoshikawa's index sqrt(det(J Jᵀ)) (Zheng et al. 2019, eq. 6); ``translational`` uses J[:3].

        Returns a float for q (n,) and an array (N,) for q (N, n).
        """
        J = self.jacobian(q)
        if flag(translational, "translational"):
            J = J[..., :3, :]
        # Jᵀ = QR gives det(J Jᵀ) = det(RᵀR) = Π R_ii²; unlike det(J Jᵀ), which squares the
        # condition number, this keeps m accurate to ~ε·σ_max near singular configurations
        R = np.linalg.qr(np.swapaxes(J, -1, -2), mode="r")
        m = np.abs(np.prod(np.diagonal(R, axis1=-2, axis2=-1), axis=-1))
        return float(m) if m.ndim == 0 else m

    def manipulability_gradient(self, q: np.ndarray, translational: bool = False) -> np.ndarray:
        r"""∂m/∂q (per rad) from the kinematic Hessian: (n,) or (N, n); see :func:`manipulability_gradient_expr`.

        One configuration goes through the compiled function, a batch through numpy.
        """
        q, batched = joint_vector(q, self.dof)
        if not batched:
            return self._compiled["manipulability_gradient"](q)[int(flag(translational, "translational"))].copy()
        return manipulability_gradient_from(self.jacobian(q), self.hessian(q), translational)


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
    with m = 0.
    """
    ops = sy.ops_of(J, H)
    rows, n = len(J), len(J[0])
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
                [
                    sy.mul(sy.sub(H[k][i][j], sy.lin(*((R[t][i], G[t][j]) for t in range(i)))), inv[i])
                    for j in range(n)
                ]
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
    return np.stack(np.broadcast_arrays(*grad), axis=-1)


def _jacobian_rows(jv: list[sy.Vec], jw: list[sy.Vec]) -> list[list[Scalar]]:
    """The geometric Jacobian's columns as rows ``J[r][j]`` (6 × n scalars)."""
    return [[(jv[j] if r < 3 else jw[j])[r % 3] for j in range(len(jv))] for r in range(6)]


def _hessian_rows(H: list[list[tuple[sy.Vec, sy.Vec]]]) -> list[list[list[Scalar]]]:
    """:meth:`DHChain.hessian_expr` as ``H[k][r][j]`` (n × 6 × n scalars)."""
    return [[[(row[j][0] if r < 3 else row[j][1])[r % 3] for j in range(len(row))] for r in range(6)] for row in H]


class _LazyCompiled(dict):
    """``name -> Compiled(functions[name])``, compiled when first asked for."""

    def __init__(self, functions: dict[str, ca.Function]):
        super().__init__()
        self.functions = functions

    def __missing__(self, name: str) -> Compiled:
        self[name] = Compiled(self.functions[name])
        return self[name]


def _frame_to_sx(f: Frame) -> ca.SX:
    R, p = f
    rows = [ca.horzcat(*R[i], p[i]) for i in range(3)]
    return ca.vertcat(*rows, ca.DM([[0, 0, 0, 1]]))


def _frame_to_np(f: Frame, n: int) -> np.ndarray:
    R, p = f
    T = np.zeros((n, 4, 4))
    for i in range(3):
        for j in range(3):
            T[:, i, j] = R[i][j]
        T[:, i, 3] = p[i]
    T[:, 3, 3] = 1.0
    return T
