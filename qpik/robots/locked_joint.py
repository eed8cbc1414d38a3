r"""Recognising a 7-R arm that becomes a Pieper-type 6-R chain when its last joint is locked (Franka Panda, xArm7).

With q7 given, the flange pose fixes the remaining 6-R chain (joints 1-6). That chain has a closed form
(:mod:`qpik.analytic.locked_joint`; He & Liu 2021, Tittel 2021, the subproblems of Elias & Wen 2022) when

- axes 1, 2, 3 meet in one point S (a spherical shoulder; consecutive axes not parallel),
- axes 5 and 6 meet in one point W (not parallel),
- neither S nor W lies on axis 4 (otherwise q4 does not change their distance).

Axes 3-4, 4-5 and 6-7 may be offset (Panda: 82.5, 82.5 and 88 mm). The test is on the joint axis lines at
q = 0 (:meth:`~qpik.robots.chain.SerialChain.axes`, base frame): intersections hold for every q since
consecutive axes keep their relative placement; S and W are each fixed in a link (S in the base, W in link 4).
No Panda number is used: :func:`find_locked_joint` reads everything from the chain.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from qpik.robots.chain import SerialChain

MEET_TOL = 1e-10
"""Largest distance (m) between two axes that meet; above it they are offset."""
NEAR_TOL = 1e-4
"""Largest distance (m) by which the axes that should meet may miss for the chain to count as a near member: it gets
the closed form of its :func:`ideal_chain`, polished on its own FK (:mod:`qpik.analytic.polish`). A file's
rounding gives such misses: an rpy written as 1.571 (2e-4 rad off a quarter turn) over a 0.5 m link puts an axis
1e-4 m from where it should pass; the closed form's start is then about 1e-4/0.1 rad from the answer (links of
~0.1 m), which Newton's quadratic steps take to round-off in the polish's four. Not near a singular Jacobian of
joints 1-6 (smallest singular value σ_min): the file's answer lies about miss/σ_min from the ideal one, beyond the
polish's reach where σ_min is below about 1e-4, and a branch may be missed there (flagged invalid, or the polish
reaching another answer)."""
PARALLEL_TOL = 1e-9
"""Smallest sine of the angle between two axes that are not parallel."""


@dataclass(frozen=True)
class LockedJointGeometry:
    """The constants of the locked-q7 closed form, base frame at q = 0 (m, unit vectors).

    Attributes:
        h: (7, 3) unit joint axes.
        o: (7, 3) a point on each axis.
        shoulder: (3,) S, where axes 1-3 meet.
        wrist: (3,) W, where axes 5-6 meet.
        home: (4, 4) the end-effector pose at q = 0.
        offsets: ``{(i, j): m}``, the distances between consecutive axes i, j (1-based) that do not meet.
    """

    h: np.ndarray
    o: np.ndarray
    shoulder: np.ndarray
    wrist: np.ndarray
    home: np.ndarray
    offsets: dict[tuple[int, int], float]

    def describe(self, near: str = "") -> str:
        """One line for ``robot.notes``: the geometry found (offsets in mm) and the solver serving it; ``near``, the
        deviations of a file from its :func:`ideal_chain` in words (empty for a chain of the family)."""
        off = ", ".join(f"{i}-{j} {1000 * d:.4g} mm" for (i, j), d in self.offsets.items()) or "none"
        ideal = (
            f" on its nearest ideal geometry ({near}), polished by Newton on the file's chain (a branch may be missed"
            " near a singular Jacobian of joints 1-6; feasible sets not proved)"
            if near
            else ""
        )
        return (
            f"closed form with q7 locked (parameter q7, 8 branches){ideal}: axes 1-2-3 meet (spherical shoulder), "
            f"axes 5-6 meet; offsets between axes {off}; solved by subproblems 3, 2, 2 and 1 "
            "(qpik.analytic.locked_joint" + (", qpik.analytic.polish)" if near else ")")
        )


def _feet(p: np.ndarray, u: np.ndarray, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Feet (on line 1, on line 2) of the common normal of lines p + t u and q + s v; None if parallel."""
    n = np.cross(u, v)
    if np.linalg.norm(n) < PARALLEL_TOL:
        return None
    w = p - q
    a, b, c, d, e = u @ u, u @ v, v @ v, u @ w, v @ w
    den = a * c - b * b
    t, s = (b * e - c * d) / den, (a * e - b * d) / den
    return p + t * u, q + s * v


def _off_line(x: np.ndarray, p: np.ndarray, u: np.ndarray) -> float:
    """Distance (m) of the point x from the line p + t u (u unit)."""
    return float(np.linalg.norm(np.cross(x - p, u)))


def find_locked_joint(chain: SerialChain, tol: float = MEET_TOL) -> tuple[LockedJointGeometry | None, str]:
    """The locked-q7 geometry of ``chain`` (7 revolute joints), or None and the reason in one line; ``tol`` (m):
    the largest miss of axes that meet (:data:`MEET_TOL`; :data:`NEAR_TOL` for a near member)."""
    h, o = chain.axes(np.zeros(7))
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    feet = [_feet(o[i], h[i], o[i + 1], h[i + 1]) for i in range(6)]
    gap = {i: (np.inf if f is None else float(np.linalg.norm(f[1] - f[0]))) for i, f in enumerate(feet)}
    for i in (0, 1, 4):
        if feet[i] is None:
            return None, f"axes {i + 1}-{i + 2} are parallel"
        if gap[i] > tol:
            return None, f"axes {i + 1}-{i + 2} do not meet ({1000 * gap[i]:.4g} mm apart)"
    S, W = feet[0][0], feet[4][0]
    if (d := _off_line(S, o[2], h[2])) > tol:
        return None, f"axes 1-2-3 do not meet in one point (axis 3 passes {1000 * d:.4g} mm from it)"
    if min(_off_line(S, o[3], h[3]), _off_line(W, o[3], h[3])) < 1e3 * MEET_TOL:
        return None, "the shoulder or wrist point lies on axis 4"
    offsets = {(i + 1, i + 2): gap[i] for i in range(6) if gap[i] > tol and np.isfinite(gap[i])}
    home = chain.fk(np.zeros(7))
    return LockedJointGeometry(h, o, S, W, home, offsets), ""


def ideal_chain(chain: SerialChain) -> tuple[SerialChain | None, str]:
    r"""The family's chain nearest to ``chain`` (7 revolute joints) whose axes miss by at most :data:`NEAR_TOL`, and
    the misses in words; None and the reason otherwise.

    Axes 1 and 2 are moved parallel to themselves through the midpoint S of their common normal, axis 3 through S,
    axes 5 and 6 through the midpoint W of theirs (each by at most its miss; directions, the other axes, the base and
    the end-effector pose at q = 0 are kept): the joint frames at q = 0 are translated by
    :math:`\delta_k`, so :math:`P'_k = T(R_{k-1}^T(\delta_k - \delta_{k-1}))\,P_k` (:math:`R_{k-1}` the rotation
    of link frame k-1 at q = 0, :math:`T` a translation) and the tool takes :math:`-\delta_7`.
    """
    geometry, why = find_locked_joint(chain, NEAR_TOL)
    if geometry is None:
        return None, why
    h, o = geometry.h, geometry.o
    shift = np.zeros((8, 3))  # δ_k of joint k = 1..7; row 0 the base's
    misses = []
    for a, b, rows, name in ((0, 1, (1, 2, 3), "shoulder"), (4, 5, (5, 6), "wrist")):
        fa, fb = _feet(o[a], h[a], o[b], h[b])  # type: ignore[misc]
        point = 0.5 * (fa + fb)
        if (gap := float(np.linalg.norm(fb - fa))) > MEET_TOL:
            misses.append(f"axes {a + 1}-{b + 1} pass {1e6 * gap:.4g} µm apart")
        for k in rows:
            v = point - o[k - 1]
            shift[k] = v - (v @ h[k - 1]) * h[k - 1]
        if name == "shoulder" and (d := _off_line(fa, o[2], h[2])) > MEET_TOL:
            misses.append(f"axis 3 passes {1e6 * d:.4g} µm from the shoulder point")
    F = chain.frames(np.zeros(7))
    joints = []
    for k, joint in enumerate(chain.joints, start=1):
        pre = joint.pre.copy()
        pre[:3, 3] += F[k - 1, :3, :3].T @ (shift[k] - shift[k - 1])
        joints.append(replace(joint, pre=pre))
    tool = chain.tool.copy()
    tool[:3, 3] -= F[7, :3, :3].T @ shift[7]
    return SerialChain(joints, chain.base, tool), "; ".join(misses)
