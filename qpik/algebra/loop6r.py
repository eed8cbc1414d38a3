r"""Every inverse-kinematics solution of a general 6-R chain, by elimination to one eigenproblem (Raghavan & Roth 1993;
Manocha & Canny 1994).

The chain is given by its joint axes at q = 0 (unit directions :math:`h_j`, a point :math:`o_j` on each; any frame):
:math:`E_j(\theta) = \begin{pmatrix} R(h_j, \theta) & o_j - R(h_j, \theta)\,o_j \\ 0 & 1\end{pmatrix}` (the
product of exponentials), and a pose is :math:`G = E_1(\theta_1) \cdots E_6(\theta_6)` (the tool's home pose taken
out by the caller).

**The equations.** Four consecutive joints a, b, c, d of the chain (a *window*, :data:`WINDOWS`) satisfy
:math:`E_a E_b E_c E_d = X`, with X the pose and the two other joints (:math:`X = (E_1\cdots E_{a-1})^{-1} G
(E_{d+1}\cdots E_6)^{-1}`). Applied to a point :math:`o_d` and the direction :math:`h_d` of axis d, which
:math:`E_d` keeps, this gives a point p and a direction l twice: from the three joints a, b, c on the left and from the
two others on the right, so :math:`\theta_d` is gone (or, read backwards, :math:`E_d^{-1} E_c^{-1} E_b^{-1}` on
:math:`o_a, h_a`). Raghavan & Roth's 14 equations

.. math:: p,\ l,\ p\cdot p,\ p\cdot l,\ p\times l,\ (p\cdot p)\,l - 2\,(p\cdot l)\,p

are, with the origin on the first axis of the left side, linear on the left in :math:`x_1 = (s_b s_c, s_b c_c,
c_b s_c, c_b c_c, s_b, c_b, s_c, c_c, 1)` with coefficients linear in :math:`(1, s_a, c_a)` (a matrix
:math:`P(\theta_a) = P_0 + s_a P_1 + c_a P_2`, 14 × 9, of the chain alone) and on the right linear in the same
products :math:`x_2` of the two other joints (14 × 9, of the pose). Both matrices are found by least squares from
the sides' values at random angles (:data:`LEFT_SAMPLES`, :data:`RIGHT_SAMPLES`): exact to round-off where the form
holds, which :meth:`Loop6R.of` checks (:data:`FIT_TOL`).

**The elimination.** The left null space N (6 × 14) of the right side's 8 columns of products takes the other two
joints out: :math:`N P(\theta_a) x_1 = 0` (the constant column moved to the left). With half-angle tangents
:math:`x = \tan(\theta/2)` and the equations times :math:`(1 + x_a^2)(1 + x_b^2)(1 + x_c^2)`, these are 6 equations,
quadratic in :math:`x_a`, in the 9 monomials :math:`x_b^i x_c^j` (i, j ≤ 2); with the same times :math:`x_b`, 12
equations in 12 monomials, :math:`(A_2 x_a^2 + A_1 x_a + A_0) z = 0`: a quadratic eigenproblem of size 12, solved as
a generalised one of size 24 (LAPACK's QZ, ``dggev``). Its 24 eigenvalues hold the 16 solutions of the chain
(complex ones and 8 at :math:`\pm i` have no real configuration); each real eigenvalue gives :math:`\theta_a`, its
eigenvector :math:`\theta_b, \theta_c` (ratios of its entries), the right side's products the two other joints
(least squares), and the rotation left over :math:`\theta_d` (subproblem 1).

The candidates are not polished and not checked: the caller polishes them on its own chain and keeps those that reach
the pose. For a chain with special geometry (intersecting or parallel axes) the eigenproblem of a window may be
singular for every :math:`x_a`; :meth:`Loop6R.of` then tries the next window, and keeps the first whose candidates hold
random configurations of the chain (:data:`CHECKS`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sl

from qpik.algebra import symbolic as sy

WINDOWS = ((2, False), (0, False), (1, False), (0, True), (1, True), (2, True))
"""The windows tried (:meth:`Loop6R.of`): the first joint s (0-based) of the four s..s+3, and whether they are read
backwards (the left side :math:`E_{s+3}^{-1} E_{s+2}^{-1} E_{s+1}^{-1}` on axis s; else :math:`E_s E_{s+1} E_{s+2}` on
axis s + 3). Raghavan & Roth's joints 3-5 first."""
LEFT_SAMPLES = 96
"""Random angles of the left side's three joints from which its matrices are fitted."""
RIGHT_SAMPLES = 24
"""Random angles of the right side's two joints from which its matrix is fitted, per pose."""
FIT_TOL = 1e-9
"""Largest residual (relative to the values) of a fit where the equations have the form (:meth:`Loop6R.of`)."""
CHECKS = 12
"""Random configurations of the chain whose poses a window's candidates must hold (:meth:`Loop6R.of`)."""
HELD = 1e-6
"""rad: a candidate this close in every joint holds a configuration (:meth:`Loop6R.of`)."""
REAL = 1e-7
"""An eigenvalue whose imaginary part is at most this times (1 + its modulus) is real."""


def _products(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:math:`(s_u s_v, s_u c_v, c_u s_v, c_u c_v, s_u, c_u, s_v, c_v, 1)` of angles u, v (...,): (..., 9)."""
    su, cu, sv, cv = np.sin(u), np.cos(u), np.sin(v), np.cos(v)
    return np.stack([su * sv, su * cv, cu * sv, cu * cv, su, cu, sv, cv, np.ones_like(su)], axis=-1)


def _fourteen(p: np.ndarray, l: np.ndarray) -> np.ndarray:
    """Raghavan & Roth's 14 quantities of points p and directions l (..., 3): (..., 14)."""
    pp, pl = (p * p).sum(-1, keepdims=True), (p * l).sum(-1, keepdims=True)
    return np.concatenate([p, l, pp, pl, np.cross(p, l), pp * l - 2.0 * pl * p], axis=-1)


def _tangent_map() -> np.ndarray:
    """(9, 9): row k the coefficients, over the monomials :math:`x_b^i x_c^j` (index 3i + j), of the k-th product of
    :func:`_products` times :math:`(1 + x_b^2)(1 + x_c^2)`, with :math:`s = 2x/(1 + x^2)`, :math:`c = (1 - x^2)/(1 +
    x^2)`."""
    s, c, one = np.array([0.0, 2.0, 0.0]), np.array([1.0, 0.0, -1.0]), np.array([1.0, 0.0, 1.0])  # × (1 + x²)
    rows = [np.outer(a, b) for a, b in ((s, s), (s, c), (c, s), (c, c), (s, one), (c, one), (one, s), (one, c))]
    return np.stack([*rows, np.outer(one, one)]).reshape(9, 9)


TANGENT = _tangent_map()


def turns(h: np.ndarray, o: np.ndarray, theta: np.ndarray) -> np.ndarray:
    r"""The motions :math:`E(h, o, \theta)` (..., 4, 4) about the axis through o (3,) along the unit h (3,), by the
    angles ``theta`` (...,) rad."""
    theta = np.asarray(theta, float)
    K = np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])
    s, c = np.sin(theta)[..., None, None], np.cos(theta)[..., None, None]
    R = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    out = np.zeros((*theta.shape, 4, 4))
    out[..., :3, :3], out[..., :3, 3], out[..., 3, 3] = R, o - R @ o, 1.0
    return out


@dataclass(frozen=True)
class Window:
    """The joints of a window (:data:`WINDOWS`): the left side's three (``left``, the first the eigenproblem's
    variable), their signs (−1 read backwards), the eliminated joint, and the right side's two (``right``)."""

    left: tuple[int, int, int]
    sign: float
    gone: int
    right: tuple[int, int]

    @classmethod
    def of(cls, start: int, backwards: bool) -> Window:
        """The window of joints ``start``..``start`` + 3 (0-based), read ``backwards`` or not."""
        four = tuple(range(start, start + 4))
        right = tuple(j for j in range(6) if j not in four)
        if backwards:
            return cls((four[3], four[2], four[1]), -1.0, four[0], right)  # type: ignore[arg-type]
        return cls(four[:3], 1.0, four[3], right)  # type: ignore[arg-type]


class Loop6R:
    """The elimination of a 6-R chain for one window (module docstring); :meth:`of` finds the window.

    Args:
        h: (6, 3) unit axis directions at q = 0.
        o: (6, 3) a point on each axis (m).
        window: the window's joints.
    """

    def __init__(self, h: np.ndarray, o: np.ndarray, window: Window):
        self.h, self.o, self.window = np.asarray(h, float), np.asarray(o, float), window
        self._origin = self.o[window.left[0]].copy()
        """The left side's frame: the world's moved to a point of its first axis."""
        k = self.h[window.gone]
        across = np.cross(k, np.eye(3)[int(np.argmin(np.abs(k)))])
        self._across = across / np.linalg.norm(across)
        self._quarter = np.cross(k, self._across)
        """Unit vectors a and k × a across the eliminated joint's axis k (its angle's subproblem 1, :meth:`_gone`)."""
        local = self.o - self._origin
        self._moves = [lambda t, j=j: turns(self.h[j], local[j], t) for j in range(6)]
        rng = np.random.default_rng(7)
        u = rng.uniform(-np.pi, np.pi, (LEFT_SAMPLES, 3))
        p, l = self._left(u)
        values = _fourteen(p, l)
        x1 = _products(u[:, 1], u[:, 2])
        basis = np.concatenate([x1, np.sin(u[:, :1]) * x1, np.cos(u[:, :1]) * x1], axis=1)
        coef = np.linalg.lstsq(basis, values, rcond=None)[0]
        self.fit = float(np.abs(basis @ coef - values).max() / max(1.0, np.abs(values).max()))
        """The left fit's largest residual, relative to the values."""
        self._P = [coef[9 * k : 9 * k + 9].T for k in range(3)]
        self._right_angles = rng.uniform(-np.pi, np.pi, (RIGHT_SAMPLES, 2))
        self._right_basis = _products(self._right_angles[:, 0], self._right_angles[:, 1])

    @classmethod
    def of(cls, h: np.ndarray, o: np.ndarray) -> tuple[Loop6R | None, str]:
        """The first window of :data:`WINDOWS` whose fits hold (:data:`FIT_TOL`) and whose candidates hold
        :data:`CHECKS` random configurations of the chain (to :data:`HELD` rad); None and the reason where none
        does."""
        rng = np.random.default_rng(11)
        q = rng.uniform(-np.pi, np.pi, (CHECKS, 6))
        h, o = np.asarray(h, float), np.asarray(o, float)
        poses = np.eye(4)[None].repeat(CHECKS, 0)
        for j in range(6):
            poses = poses @ turns(h[j], o[j], q[:, j])
        held = []
        for start, backwards in WINDOWS:
            loop = cls(h, o, Window.of(start, backwards))
            if loop.fit > FIT_TOL:
                continue
            ok = 0
            for G, qk in zip(poses, q):
                found = loop.solve(G)
                ok += bool(len(found)) and bool((np.abs(sy.NUMPY.wrap(found - qk)).max(axis=1) <= HELD).any())
            if ok == CHECKS:
                return loop, ""
            held.append(f"joints {start + 1}-{start + 4}{' backwards' if backwards else ''} {ok}/{CHECKS}")
        return None, "the elimination of every window is singular (configurations held: " + ", ".join(held) + ")"

    def _left(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The left side's point and direction (M, 3) each at its joints' angles ``u`` (M, 3) rad (the left frame)."""
        w = self.window
        A = self._moves[w.left[0]](w.sign * u[:, 0]) @ self._moves[w.left[1]](w.sign * u[:, 1])
        A = A @ self._moves[w.left[2]](w.sign * u[:, 2])
        o = self.o[w.gone] - self._origin
        return A[:, :3, :3] @ o + A[:, :3, 3], A[:, :3, :3] @ self.h[w.gone]

    def _right(self, G: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The right side's point and direction (M, 3) each at the pose G (4, 4; world) and the right joints' angles
        ``v`` (M, 2) rad (the left frame)."""
        w = self.window
        shift = np.eye(4)
        shift[:3, 3] = self._origin
        X = np.linalg.inv(shift) @ G @ shift  # the pose in the left frame
        moves = {j: self._moves[j](v[:, k]) for k, j in enumerate(w.right)}
        before = np.eye(4)[None].repeat(len(v), 0)
        after = before.copy()
        for j in w.right:
            if j < min((*w.left, w.gone)):
                before = before @ moves[j]
            else:
                after = after @ moves[j]
        Y = np.linalg.inv(before) @ X @ np.linalg.inv(after)  # E_a..E_d
        if w.sign < 0:
            Y = np.linalg.inv(Y)
        o = self.o[w.gone] - self._origin
        return Y[:, :3, :3] @ o + Y[:, :3, 3], Y[:, :3, :3] @ self.h[w.gone]

    def solve(self, G: np.ndarray) -> np.ndarray:
        """The candidates (K, 6) rad, K ≤ 16, of the pose ``G`` (4, 4): :math:`E_1 \\cdots E_6 = G` (module
        docstring); not polished."""
        w = self.window
        values = _fourteen(*self._right(G, self._right_angles))
        coef = np.linalg.lstsq(self._right_basis, values, rcond=None)[0]
        Q, constant = coef[:8].T, coef[8]
        P0 = self._P[0].copy()
        P0[:, 8] -= constant
        U, sv, Vt = np.linalg.svd(Q, full_matrices=True)
        if sv[-1] <= 1e-12 * max(1.0, sv[0]):
            return np.zeros((0, 6))
        N = U[:, 8:].T
        S0, S1, S2 = N @ P0, N @ self._P[1], N @ self._P[2]
        A = [_grown(C @ TANGENT) for C in (S0 + S2, 2.0 * S1, S0 - S2)]  # × x_a^0, x_a^1, x_a^2
        lam, vec = _pencil(*A)
        real = np.flatnonzero(np.abs(lam.imag) <= REAL * (1.0 + np.abs(lam)))
        z = vec[:12, real].T.reshape(-1, 4, 3)  # z[k, i, j] ∝ x_b^i x_c^j
        rows = np.arange(len(real))
        i, j = np.unravel_index(np.abs(z[:, :3]).reshape(-1, 9).argmax(axis=1), (3, 3))
        m, n = np.unravel_index(np.abs(z[:, :, :2]).reshape(-1, 8).argmax(axis=1), (4, 2))
        u = 2.0 * np.arctan(np.stack([lam[real].real, z[rows, i + 1, j] / z[rows, i, j],
                                      z[rows, m, n + 1] / z[rows, m, n]], axis=1))  # fmt: skip
        P = P0 + np.sin(u[:, :1, None]) * self._P[1] + np.cos(u[:, :1, None]) * self._P[2]
        rhs = (P @ _products(u[:, 1], u[:, 2])[..., None])[..., 0]
        x2 = ((rhs @ U[:, :8]) / sv) @ Vt  # least squares by Q's SVD
        q = np.zeros((len(real), 6))
        q[:, list(w.left)] = u  # the left side turns by −u where read backwards: E(−θ) = E(θ)⁻¹
        q[:, w.right[0]], q[:, w.right[1]] = np.arctan2(x2[:, 4], x2[:, 5]), np.arctan2(x2[:, 6], x2[:, 7])
        q[:, w.gone] = self._gone(G, q)
        return q

    def _gone(self, G: np.ndarray, q: np.ndarray) -> np.ndarray:
        """The eliminated joint's angles (K,) rad from the others' (``q`` (K, 6), its own column unused): the rotation
        left about its axis (subproblem 1)."""
        d = self.window.gone
        before = after = np.eye(4)[None]
        for j in range(d):
            before = before @ turns(self.h[j], self.o[j], q[:, j])
        for j in range(d + 1, 6):
            after = after @ turns(self.h[j], self.o[j], q[:, j])
        R = (np.linalg.inv(before) @ G @ np.linalg.inv(after))[:, :3, :3]
        b = R @ self._across  # a turned by the joint: its angle is atan2((a × b)·k, a·b) = atan2(b·(k × a), b·a)
        return np.arctan2(b @ self._quarter, b @ self._across)


def _pencil(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""The finite eigenvalues λ (complex, (M,)) of :math:`(A_2 \lambda^2 + A_1 \lambda + A_0) z = 0` (each (12, 12))
    and the real parts of their eigenvectors (24, M) of the linearisation :math:`[0, I; -A_0, -A_1] v = \lambda
    [I, 0; 0, A_2] v`, :math:`v = (z, \lambda z)`, by LAPACK's QZ (``dggev``; :func:`scipy.linalg.eig` where it fails).
    A complex pair's two vectors have one real part."""
    alphar, alphai, beta, _, vr, _, info = sl.lapack.dggev(*_linearised(A0, A1, A2), compute_vl=0, overwrite_a=1,
                                                           overwrite_b=1)  # fmt: skip
    if info != 0:
        lam, vec = sl.eig(*_linearised(A0, A1, A2))
        finite = np.isfinite(lam)
        return lam[finite], vec[:, finite].real
    finite = beta != 0.0
    first = np.arange(len(beta)) - (alphai < 0.0)  # the column of a pair's real part
    lam = (alphar + 1j * alphai)[finite] / beta[finite]
    return lam, vr[:, first[finite]]


def _linearised(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:math:`[0, I; -A_0, -A_1]` and :math:`[I, 0; 0, A_2]` (each (24, 24), column-major, for LAPACK)."""
    n = len(A0)
    a, b = np.zeros((2 * n, 2 * n), order="F"), np.zeros((2 * n, 2 * n), order="F")
    a[:n, n:], a[n:, :n], a[n:, n:] = np.eye(n), -A0, -A1
    b[:n, :n], b[n:, n:] = np.eye(n), A2
    return a, b


def _grown(C: np.ndarray) -> np.ndarray:
    """(12, 12): the 6 equations ``C`` (6, 9) over :math:`x_b^i x_c^j` (i ≤ 2), and the same times :math:`x_b` (i ≤ 3),
    over :math:`x_b^i x_c^j` (index 3i + j)."""
    A = np.zeros((12, 12))
    A[:6, :9], A[6:, 3:] = C, C
    return A
