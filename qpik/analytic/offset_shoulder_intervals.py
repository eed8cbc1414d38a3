r"""Exact feasible δ sets of the offset-shoulder arm (seed 000) under joint limits.

For a fixed pose every joint of every branch is a function of δ. A branch's
feasibility (valid, every joint inside ``[q_min, q_max]``) can only change where

- a joint equals a limit L (or ±π where a limit reaches ±π, the wrap),
- the branch stops being valid: :math:`\sin\theta_4 = \pm 1` or the shoulder
  equation's discriminant vanishes (these are also the elbow and shoulder
  singularities, where θ3 and θ2 can jump),
- a wrist angle jumps by π at :math:`\sin\theta_6 = 0` (a root of the θ5 and θ7
  equations below, for every L).

All those δ are found analytically for the branches with θ1[1] (rows 1–8); rows
9–16 are the same functions shifted by π (θ1[2](δ) = θ1[1](δ + π)). With
:math:`c = \cos\delta`, :math:`s = \sin\delta`, :math:`w' = (rc - a_1, h, rs)`
(:math:`h = w_z - d_1`), :math:`E = w_x'^2 + h^2`, :math:`Z = d_3 + d_5\sin\theta_4`,
:math:`\sin\theta_4 = k_1 + k_2 c` and :math:`D = E - Z^2`:

- θ1 = L: :math:`\delta = L - \mathrm{atan2}(w_y, w_x)`;
- θ4 = L: :math:`k_1 + k_2 c = \sin L`; validity: :math:`k_1 + k_2 c = \pm 1`, :math:`D(c) = 0` (and
  where the solver's tolerant validity tests switch, :math:`k_1 + k_2 c = \pm(1 + \epsilon)`,
  :math:`D = -\epsilon` and :math:`D = -\epsilon E`, ε = :data:`qpik.analytic.trig.EPS`: near a
  tangency they are up to ~1e-9 rad from the exact roots);
- θ2 = L: :math:`-\sin L\,(rc - a_1) + \cos L\, h = Z(c)` (linear in c);
- θ3 = L: :math:`\sin L\, w''_x = \cos L\, w''_y` with :math:`w''_x = \pm\sqrt D`,
  :math:`w''_y = -rs`; squared: :math:`\sin^2 L\, D(c) = \cos^2 L\, r^2 (1 - c^2)` (quadratic in c);
- θ5, θ6, θ7 through the frame-1 unit vector of the upper arm
  :math:`u = (Z\hat w + \sigma\sqrt D\,\hat w_\perp)/E` (:math:`\hat w = (w'_x, h, 0)`,
  :math:`\hat w_\perp = (-h, w'_x, 0)`) and :math:`z_4 = (d_3 u - w')/d_5`:
  θ6 = L ⇔ :math:`z_4\cdot b = \cos L`; θ7 = L (mod π) ⇔
  :math:`z_4\cdot(\sin L\, n + \cos L\, t) = 0`; θ5 = L (mod π) ⇔
  :math:`\sin L\,(u + s_4 z_4)\cdot b - \cos L\,(z_4\times u)\cdot b = 0` (the frame-4
  axes times cos θ4: :math:`c_4 x_4 = u + s_4 z_4`, :math:`c_4 y_4 = z_4 \times u`).
  Multiplied by :math:`d_5 E` each is :math:`P(\delta) + \sigma\sqrt{D}\,Q(\delta)` with
  trigonometric polynomials P, Q; :math:`P^2 - D Q^2 = 0` is a trigonometric polynomial
  of degree 8 (θ5) or 6 (θ6, θ7), i.e. a polynomial of degree 16 or 12 in
  :math:`z = e^{i\delta}` whose unit-modulus roots are the candidates: the
  eigenvalues of the companion matrices of all of them (one batched ``eigvals``
  per pose), polished by Newton steps on the trigonometric polynomials.

Squaring and the ±acos of c add spurious candidates; they only split a gap in
two, which :func:`qpik.analytic.intervals.assemble_many` merges back. Each gap is
classified by one batched evaluation of all 16 branches at the gap midpoints.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.intervals import FeasibleIntervals, assemble_many, wrap
from qpik.analytic.trig import EPS

if TYPE_CHECKING:
    from qpik.analytic.offset_shoulder import OffsetShoulderSolver

PI = np.pi
UNIT_TOL = 1e-3
"""Roots of the z-polynomials with ||z| − 1| below this are kept as candidates (spurious ones are harmless)."""


def feasible_delta(solver: OffsetShoulderSolver, T: np.ndarray) -> FeasibleIntervals:
    """Per branch (Table 2 order), the δ intervals (rad) where the branch is valid and within limits.

    ``singular`` lists, per branch, the candidate δ (validity boundaries: elbow and
    shoulder singularities; common roots of the θ5 and θ7 equations: wrist) at
    which the branch is valid and flagged singular.
    """
    robot = solver.robot
    Tc = solver._base_inv_np @ T @ np.linalg.inv(robot.chain.tool)
    brk, sing = breakpoints(solver, Tc[:3, :3], Tc[:3, 3], robot.q_min, robot.q_max)
    brk = np.concatenate([brk, brk + PI])  # rows 9-16: the same functions shifted by π
    sing = wrap(np.concatenate([sing, sing + PI]))
    found: list[np.ndarray] = []

    def feasible_at(mid: np.ndarray) -> np.ndarray:
        pts = np.concatenate([mid, sing])
        _, valid, singular, inside = solver.solve_many(T, pts)
        found.append(valid[mid.size :] & singular[mid.size :])
        return inside[: mid.size]

    intervals = assemble_many(brk, feasible_at)
    hits = found[0]
    singular = [sorted(set(sing[hits[:, j]].tolist())) for j in range(solver.n_branches)]
    return FeasibleIntervals(solver.param_name, np.array(solver.branch_ids), intervals, singular)


def breakpoints(
    solver: OffsetShoulderSolver, R: np.ndarray, p: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """For the chain-frame pose (R, p) and limits (7,): every δ (rad) where a branch with θ1[1]
    can change feasibility, and the subset where it can be singular."""
    g = solver.geometry
    n, t, b = R[:, 0], R[:, 1], R[:, 2]
    w = p + g.d7 * b
    r = float(np.hypot(w[0], w[1]))
    phi = float(np.arctan2(w[1], w[0])) if r > 1e-13 else 0.0
    h = float(w[2] - g.d1)
    k1 = (r * r + g.a1**2 + h * h - g.d3**2 - g.d5**2) / (2 * g.d3 * g.d5)
    k2 = -g.a1 * r / (g.d3 * g.d5)
    z0, z1 = g.d3 + g.d5 * k1, g.d5 * k2
    levels = [_levels(lo[j], hi[j]) for j in range(7)]

    # ---- equations quadratic in c = cos δ: rows (A, B, C) of A c² + B c + C = 0
    dA, dB, dC = r * r - z1 * z1, -2 * g.a1 * r - 2 * z0 * z1, g.a1**2 + h * h - z0 * z0  # D(c)
    rows = [(0.0, k2, k1 - 1.0), (0.0, k2, k1 + 1.0), (dA, dB, dC)]  # validity: sin θ4 = ±1, D = 0
    # where the solver's tolerant tests switch (|sin θ4| <= 1 + EPS, D >= -EPS max(E, 1); trig.EPS):
    # near a tangency these lie up to ~1e-9 rad from the exact roots above
    rows += [(0.0, k2, k1 - 1.0 - EPS), (0.0, k2, k1 + 1.0 + EPS), (dA, dB, dC + EPS)]
    rows.append((dA + EPS * r * r, dB - 2 * EPS * g.a1 * r, dC + EPS * (g.a1**2 + h * h)))
    for L in levels[1]:  # θ2
        sL, cL = np.sin(L), np.cos(L)
        rows.append((0.0, r * (g.a1 / g.d3 - sL), sL * g.a1 + cL * h - z0))
    for L in levels[2]:  # θ3 (squared)
        s2, c2 = np.sin(L) ** 2, np.cos(L) ** 2
        rows.append((s2 * dA + c2 * r * r, s2 * dB, s2 * dC - c2 * r * r))
    for L in levels[3]:  # θ4
        rows.append((0.0, k2, k1 - np.sin(L)))
    c = _quadratic_roots(np.array(rows))
    c_sing = _quadratic_roots(np.array(rows[:3]))
    delta = [np.arccos(c), -np.arccos(c), np.asarray(levels[0]) - phi]

    # ---- θ5, θ6, θ7: trigonometric polynomials in δ (coefficients of e^{ikδ}, k = -n..n)
    C, S = np.array([0.5, 0, 0.5], complex), np.array([0.5j, 0, -0.5j])
    cphi, sphi = np.cos(phi), np.sin(phi)
    c1, s1 = cphi * C - sphi * S, sphi * C + cphi * S
    wx = r * C - _const(g.a1, 1)
    wz = r * S
    E = _add(_mul(wx, wx), _const(h * h, 1))
    s4 = _const(k1, 1) + k2 * C
    Z = _const(z0, 1) + z1 * C
    D = _add(E, -_mul(Z, Z))

    def frame1(v: np.ndarray) -> tuple[np.ndarray, ...]:
        """(v'x, v'z, ŵ·v', ŵ⊥·v', (w − o1)·v) of a world vector v seen in frame 1."""
        vx, vz = c1 * v[0] + s1 * v[1], s1 * v[0] - c1 * v[1]
        gv = _const(float(w @ v - g.d1 * v[2]), 1) - g.a1 * vx
        return vx, vz, _add(_mul(wx, vx), _const(h * v[2], 2)), _add(-h * vx, wx * v[2]), gv

    def z4_dot(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d5 E z4·v = P + σ√D Q."""
        _, _, wv, wpv, gv = frame1(v)
        return _add(g.d3 * _mul(Z, wv), -_mul(E, gv)), g.d3 * wpv

    polys, n7 = [], 0
    Pb, Qb = z4_dot(b)
    for cL in sorted({round(float(np.cos(L)), 15) for L in levels[5]}):  # θ6
        polys.append(_clear(_add(Pb, -g.d5 * cL * E), Qb, D))
    Pn, Qn = z4_dot(n)
    Pt, Qt = z4_dot(t)
    for L in _mod_pi(levels[6]):  # θ7
        sL, cL = np.sin(L), np.cos(L)
        polys.append(_clear(_add(sL * Pn, cL * Pt), _add(sL * Qn, cL * Qt), D))
        n7 += 1
    _, bz, wb, wpb, gb = frame1(b)
    f = _const(g.d5, 1) + g.d3 * s4  # d5 + d3 s4
    XP = _add(_mul(_mul(f, Z), wb), -_mul(_mul(s4, E), gb))
    XQ = _mul(f, wpb)
    YP = -_mul(_mul(Z, wz), wpb)
    YQ = _add(_mul(wz, wb), -_mul(E, bz))
    for L in _mod_pi(levels[4]):  # θ5
        sL, cL = np.sin(L), np.cos(L)
        polys.append(_clear(_add(sL * XP, -cL * YP), _add(sL * XQ, -cL * YQ), D))
    roots, owner = _unit_roots(polys)
    n6 = len(polys) - n7 - len(_mod_pi(levels[4]))
    r7, r5 = roots[(owner >= n6) & (owner < n6 + n7)], roots[owner >= n6 + n7]
    # sin θ6 = 0 zeroes every θ5 and θ7 equation: their common roots
    common = r5[np.abs(wrap(r5[:, None] - r7[None, :])).min(axis=1, initial=np.inf) < 1e-6]
    sing = np.concatenate([np.arccos(c_sing), -np.arccos(c_sing), common])
    return np.concatenate([np.atleast_1d(d) for d in [*delta, roots]]), sing


def _levels(lo: float, hi: float) -> list[float]:
    """The joint values where feasibility can change: the limits inside (−π, π), and π if a limit reaches ±π."""
    out = [float(x) for x in (lo, hi) if -PI < x < PI]
    if lo <= -PI or hi >= PI:
        out.append(PI)
    return out


def _mod_pi(levels: list[float]) -> list[float]:
    """Levels up to π (an equation 'θ = L (mod π)' serves L and L ± π)."""
    return sorted({round(float(np.mod(L, PI)), 15) for L in levels})


def _quadratic_roots(rows: np.ndarray) -> np.ndarray:
    """Real roots c ∈ [−1, 1] of A c² + B c + C = 0, rows (K, 3); degenerate rows give none."""
    A, B, C = rows.T
    scale = np.abs(rows).max(axis=1) + 1e-300
    lin = np.abs(A) <= 1e-14 * scale
    out = [-C[lin & (np.abs(B) > 1e-14 * scale)] / B[lin & (np.abs(B) > 1e-14 * scale)]]
    q = ~lin
    A, B, C, sc = A[q], B[q], C[q], scale[q]
    disc = B * B - 4 * A * C
    keep = disc >= -1e-12 * sc * sc  # tangency within round-off: the double root
    sq = np.sqrt(np.maximum(disc[keep], 0.0))
    Bk = B[keep]
    m = -0.5 * (Bk + np.where(Bk >= 0, sq, -sq))
    out.append(m / A[keep])
    nz = np.abs(m) > 0
    out.append(C[keep][nz] / m[nz])
    c = np.concatenate(out)
    c = c[np.abs(c) <= 1.0 + 1e-9]
    return np.clip(c, -1.0, 1.0)


# ---- trigonometric polynomials: complex coefficient arrays of e^{ikδ}, k = -n..n


def _const(x: float, n: int) -> np.ndarray:
    out = np.zeros(2 * n + 1, complex)
    out[n] = x
    return out


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.convolve(a, b)


def _add(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    if a.size < b.size:
        a, b = b, a
    pad = (a.size - b.size) // 2
    out = a.copy()
    out[pad : pad + b.size] += b
    return out


def _clear(P: np.ndarray, Q: np.ndarray, D: np.ndarray) -> np.ndarray:
    """P² − D Q²: zero wherever P + σ√D Q = 0 for σ = +1 or −1."""
    return _add(_mul(P, P), -_mul(D, _mul(Q, Q)))


def _unit_roots(polys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Real δ with F(δ) = 0 for real trigonometric polynomials F (coefficients k = -n..n), Newton-polished.

    Returns the roots and, for each, the index of its polynomial. The roots of
    :math:`z^n F(z)` are the eigenvalues of its companion matrix; all
    polynomials go through one batched ``eigvals``, each padded to the common
    degree with zero low-order coefficients (roots at z = 0, off the circle).
    """
    trimmed = []
    for F in polys:
        scale = np.abs(F).max()
        n = (F.size - 1) // 2
        # trim negligible outer pairs (roots near 0 and ∞, never on the circle)
        while n > 0 and abs(F[0]) <= 1e-13 * scale and abs(F[-1]) <= 1e-13 * scale:
            F, n = F[1:-1], n - 1
        trimmed.append(F if n > 0 and scale > 0 else None)
    keep = [i for i, F in enumerate(trimmed) if F is not None]
    if not keep:
        return np.zeros(0), np.zeros(0, int)
    d = max(trimmed[i].size for i in keep) - 1  # common degree in z
    K = len(keep)
    C = np.zeros((K, d + 1), complex)  # C[:, m]: coefficient of z^(d-m), highest first
    for row, i in enumerate(keep):
        F = trimmed[i]
        C[row, : F.size] = F[::-1]
    comp = np.zeros((K, d, d), complex)
    comp[:, 0, :] = -C[:, 1:] / C[:, :1]
    comp[:, np.arange(1, d), np.arange(d - 1)] = 1.0
    z = np.linalg.eigvals(comp)  # (K, d)
    on = np.abs(np.abs(z) - 1.0) < UNIT_TOL
    owner_row = np.nonzero(on)[0]
    delta = np.angle(z[on])
    # Newton on F(δ) = Σ F_k e^{ikδ}, all roots at once (coefficients of the padded, centred form)
    k = np.arange(-(d // 2), d // 2 + 1)  # d = 2n is even
    Fc = np.zeros((K, d + 1), complex)
    for row, i in enumerate(keep):
        F = trimmed[i]
        pad = (d + 1 - F.size) // 2
        Fc[row, pad : pad + F.size] = F
    Fr, dFr = Fc[owner_row], Fc[owner_row] * (1j * k)
    for _ in range(3):
        e = np.exp(1j * np.outer(delta, k))
        f, df = np.einsum("ij,ij->i", e, Fr).real, np.einsum("ij,ij->i", e, dFr).real
        step = np.where(np.abs(df) > 1e-300, f / np.where(df == 0, 1.0, df), 0.0)
        delta = delta - np.clip(step, -1e-3, 1e-3)
    return delta, np.asarray(keep)[owner_row]
