r"""Recognising a 7-R arm that becomes a Pieper-type 6-R chain when its last (or first) joint is locked (Franka Panda,
xArm7; Kinova Gen3 read backwards).

With q7 given, the flange pose fixes the remaining 6-R chain (joints 1-6). That chain has a closed form
(:mod:`qpik.analytic.locked_joint`; He & Liu 2021, Tittel 2021, the subproblems of Elias & Wen 2022) when

- axes 1, 2, 3 meet in one point S (a spherical shoulder; consecutive axes not parallel),
- axes 5 and 6 meet in one point W (not parallel),
- neither S nor W lies on axis 4 (otherwise q4 does not change their distance).

Axes 3-4, 4-5 and 6-7 may be offset (Panda: 82.5, 82.5 and 88 mm). The test is on the joint axis lines at
q = 0 (:meth:`~qpik.robots.chain.SerialChain.axes`, base frame): intersections hold for every q since
consecutive axes keep their relative placement; S and W are each fixed in a link (S in the base, W in link 4).
No Panda number is used: :func:`find_locked_joint` reads everything from the chain.

**Reversed.** An arm whose axes 7, 6, 5 meet (a spherical wrist) and whose axes 3 and 2 meet is the same geometry
read from the flange: :func:`reversed_chain` (joints in the opposite order, FK inverted) is then of the family, and
locking its last joint locks the arm's q1 (:attr:`LockedJointGeometry.reversed`; the Kinova Gen3, all of whose
consecutive axes meet, with its meeting points on axes 2, 4 and 6 apart by 11.75, 12.75 and 0.35 mm in its files).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Frame, Vec
from qpik.robots.chain import SerialChain
from qpik.robots.joint import Joint

MEET_TOL = 1e-10
"""Largest distance (m) between two axes that meet; above it they are offset."""
NEAR_TOL = 5e-4
"""Largest distance (m) by which the axes that should meet may miss for the chain to count as a near member: it gets
the closed form of its :func:`ideal_chain`, polished on its own FK (:mod:`qpik.analytic.polish`). A file's
rounding gives such misses: an rpy written as 1.571 (2e-4 rad off a quarter turn) over a 0.5 m link puts an axis
1e-4 m from where it should pass; so do small offsets a file keeps where the maker's table has none (the Kinova Gen3's
files put its axes 5 and 7 0.35 mm apart, joint origins offset by 0.175 mm, where Kinova's DH table has a spherical
wrist). The closed form's start is then about miss/0.1 rad from the answer (links of ~0.1 m), which Newton's
quadratic steps take to round-off in the polish. Near a singular Jacobian of the six joints left (smallest
singular value σ_min) the file's answer lies about miss/σ_min from the ideal one, beyond the polish's reach where
σ_min is below about miss: the closed form's branches are then first corrected toward the file's
(:func:`qpik.analytic.locked_joint.correction_rounds`), and a branch may still be missed where σ_min is far below the
miss (flagged invalid, or the polish reaching another answer)."""
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
        reversed: the geometry is that of :func:`reversed_chain` of the arm (its axis k is the arm's axis 8 − k):
            the arm's q1 is locked.
    """

    h: np.ndarray
    o: np.ndarray
    shoulder: np.ndarray
    wrist: np.ndarray
    home: np.ndarray
    offsets: dict[tuple[int, int], float]
    reversed: bool = False

    def describe(self, layout: str, near: str = "") -> str:
        """One line for ``robot.notes``: the geometry found, in the arm's own axis numbers, ``layout`` (the axes in
        words, :func:`layout_words` of the arm's chain), and the solver serving it; ``near``, the deviations of a file
        from its :func:`ideal_chain` in words (empty for a chain of the family)."""
        ideal = (
            f" on its nearest ideal geometry ({near}), polished by Newton on the file's chain (a branch may be missed"
            f" near a singular Jacobian of joints {'2-7' if self.reversed else '1-6'}; feasible sets not proved)"
            if near
            else ""
        )
        if self.reversed:
            lock, groups = (
                "q1 locked (the chain read from the flange; parameter q1, 8 branches)",
                "axes 7-6-5 meet (spherical wrist), axes 3-2 meet",
            )
        else:
            lock, groups = "q7 locked (parameter q7, 8 branches)", "axes 1-2-3 meet (spherical shoulder), axes 5-6 meet"
        pairs = {((8 - j, 8 - i) if self.reversed else (i, j)): d for (i, j), d in self.offsets.items()}
        off = ", ".join(f"{i}-{j} {1000 * d:.4g} mm" for (i, j), d in sorted(pairs.items())) or "none"
        return (
            f"closed form with {lock}{ideal}: {groups}; offsets between axes {off} ({layout}); solved by subproblems "
            "3, 2, 2 and 1 "
            "(qpik.analytic.locked_joint" + (", qpik.analytic.polish)" if near else ")")
        )


def _mm(x: float) -> str:
    """A length (m) in words: mm, or µm below 0.01 mm."""
    return f"{1e6 * x:.4g} µm" if x < 1e-5 else f"{1000 * x:.4g} mm"


def layout_words(chain: SerialChain) -> str:
    """The axes of a revolute ``chain`` in words, from its axis lines at q = 0: which consecutive axes meet, the
    distance (mm) between those that do not (their common normal), and along each axis between the feet of its two
    common normals (the DH d; where both neighbours meet it, the distance between the points where they do)."""
    h, o = chain.axes(np.zeros(chain.dof))
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    n = len(h)
    normals = [feet(o[i], h[i], o[i + 1], h[i + 1]) for i in range(n - 1)]
    meet, apart, parallel = [], [], []
    for i, f in enumerate(normals):
        name = f"{i + 1}-{i + 2}"
        if f is None:
            parallel.append(f"{name} parallel ({_mm(off_line(o[i + 1], o[i], h[i]))} apart)")
        elif (gap := float(np.linalg.norm(f[1] - f[0]))) <= MEET_TOL:
            meet.append(name)
        else:
            apart.append(f"{name} {_mm(gap)} apart")
    along = [
        f"axis {k + 1} {_mm(abs(d))}"
        for k in range(1, n - 1)
        if normals[k - 1] is not None
        and normals[k] is not None
        and abs(d := float((normals[k][0] - normals[k - 1][1]) @ h[k])) > MEET_TOL
    ]
    parts = [f"axes {', '.join(meet)} meet"] if meet else []
    parts += [f"axes {x}" for x in apart + parallel]
    if along:
        parts.append("along " + ", ".join(along) + " between the feet of its common normals with its neighbours")
    return ", ".join(parts)


def feet(p: np.ndarray, u: np.ndarray, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Feet (on line 1, on line 2) of the common normal of lines p + t u and q + s v; None if parallel."""
    n = np.cross(u, v)
    if np.linalg.norm(n) < PARALLEL_TOL:
        return None
    w = p - q
    a, b, c, d, e = u @ u, u @ v, v @ v, u @ w, v @ w
    den = a * c - b * b
    t, s = (b * e - c * d) / den, (a * e - b * d) / den
    return p + t * u, q + s * v


def off_line(x: np.ndarray, p: np.ndarray, u: np.ndarray) -> float:
    """Distance (m) of the point x from the line p + t u (u unit)."""
    return float(np.linalg.norm(np.cross(x - p, u)))


def find_locked_joint(
    chain: SerialChain, tol: float = MEET_TOL, reversed: bool = False, shoulder: int = 3
) -> tuple[LockedJointGeometry | None, str]:
    """The locked-q7 geometry of ``chain`` (7 revolute joints), or None and the reason in one line; ``tol`` (m):
    the largest miss of axes that meet (:data:`MEET_TOL`; :data:`NEAR_TOL` for a near member); ``reversed``: ``chain``
    is :func:`reversed_chain` of the arm (its axis k the arm's axis 8 − k, said so in the reason). ``shoulder`` 2:
    only axes 1 and 2 meet in S, axis 3 passes S at a distance (the geometry of the 1-D search,
    :mod:`qpik.analytic.locked_search`; axes 2-3 may be offset; farther than :data:`NEAR_TOL` from S, else the
    closed form serves the chain and the search's subproblem 3 about axis 3 degenerates)."""
    h, o = chain.axes(np.zeros(7))
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    normals = [feet(o[i], h[i], o[i + 1], h[i + 1]) for i in range(6)]
    gap = {i: (np.inf if f is None else float(np.linalg.norm(f[1] - f[0]))) for i, f in enumerate(normals)}
    k = (lambda i: 8 - i) if reversed else (lambda i: i)  # the arm's number of the chain's axis i

    def pair(i: int) -> str:
        return f"axes {k(i + 1)}-{k(i + 2)}"

    for i in (0, 1, 4) if shoulder == 3 else (0, 4):
        if normals[i] is None:
            return None, f"{pair(i)} are parallel"
        if gap[i] > tol:
            return None, f"{pair(i)} do not meet ({1000 * gap[i]:.4g} mm apart)"
    S, W = normals[0][0], normals[4][0]
    if shoulder == 2 and (d := off_line(S, o[2], h[2])) <= NEAR_TOL:  # the closed form's; subproblem 3 degenerates
        return None, f"axis {k(3)} passes {_mm(d)} from the point where axes {k(1)}-{k(2)} meet (the closed form's)"
    if shoulder == 3 and (d := off_line(S, o[2], h[2])) > tol:
        group = f"axes {k(1)}-{k(2)}-{k(3)}"
        return None, f"{group} do not meet in one point (axis {k(3)} passes {1000 * d:.4g} mm from it)"
    if min(off_line(S, o[3], h[3]), off_line(W, o[3], h[3])) < 1e3 * MEET_TOL:
        return None, "the shoulder or wrist point lies on axis 4"
    offsets = {(i + 1, i + 2): gap[i] for i in range(6) if gap[i] > tol and np.isfinite(gap[i])}
    home = chain.fk(np.zeros(7))
    return LockedJointGeometry(h, o, S, W, home, offsets, reversed), ""


FLIP = np.diag([1.0, -1.0, -1.0, 1.0])
"""A half turn about x: :math:`R_z(-x) = F R_z(x) F`."""


def reversed_chain(chain: SerialChain) -> SerialChain:
    r"""The chain read from the end effector to the base: joint k of it is joint n + 1 − k of ``chain`` at the same
    angle, and its FK is the inverse of ``chain``'s, :math:`T'(q_n, \ldots, q_1) = T(q_1, \ldots, q_n)^{-1}`
    (every joint independent).

    :math:`T = B \prod_k P_k R_z(q_k + o_k) S_k\, E`, so :math:`T^{-1} = E^{-1} \prod_{k = n}^{1} S_k^{-1}
    R_z(-q_k - o_k) P_k^{-1}\, B^{-1}` and :math:`R_z(-x) = F R_z(x) F` (:data:`FLIP`): the reversed joint has
    ``pre`` :math:`S_k^{-1} F`, the same offset, ``post`` :math:`F P_k^{-1}` (its axis the original turned
    over); base :math:`E^{-1}`, tool :math:`B^{-1}`."""
    joints = [
        Joint(pre=np.linalg.inv(j.post) @ FLIP, post=FLIP @ np.linalg.inv(j.pre), offset=j.offset, name=j.name)
        for j in reversed(chain.joints)
    ]
    return SerialChain(joints, np.linalg.inv(chain.tool), np.linalg.inv(chain.base))


def ideal_chain(chain: SerialChain, reversed: bool = False, shoulder: int = 3) -> tuple[SerialChain | None, str]:
    r"""The family's chain nearest to ``chain`` (7 revolute joints) whose axes miss by at most :data:`NEAR_TOL`, and
    the misses in words; None and the reason otherwise. ``reversed``: ``chain`` is :func:`reversed_chain` of the arm,
    whose axis numbers the words use; ``shoulder``: as :func:`find_locked_joint` (2: axis 3 is not moved).

    Axes 1 and 2 are moved parallel to themselves through the midpoint S of their common normal, axis 3 through S,
    axes 5 and 6 through the midpoint W of theirs (each by at most its miss; directions, the other axes, the base and
    the end-effector pose at q = 0 are kept): the joint frames at q = 0 are translated by
    :math:`\delta_k`, so :math:`P'_k = T(R_{k-1}^T(\delta_k - \delta_{k-1}))\,P_k` (:math:`R_{k-1}` the rotation
    of link frame k-1 at q = 0, :math:`T` a translation) and the tool takes :math:`-\delta_7`.
    """
    geometry, why = find_locked_joint(chain, NEAR_TOL, reversed, shoulder)
    if geometry is None:
        return None, why
    h, o = geometry.h, geometry.o
    n = (lambda i: 8 - i) if reversed else (lambda i: i)  # the arm's number of the chain's axis i
    shift = np.zeros((8, 3))  # δ_k of joint k = 1..7; row 0 the base's
    misses = []
    for a, b, rows, name in ((0, 1, (1, 2, 3)[:shoulder], "wrist" if reversed else "shoulder"),
                             (4, 5, (5, 6), "shoulder" if reversed else "wrist")):  # fmt: skip
        fa, fb = feet(o[a], h[a], o[b], h[b])  # type: ignore[misc]
        point = 0.5 * (fa + fb)
        if (gap := float(np.linalg.norm(fb - fa))) > MEET_TOL:
            misses.append(f"axes {n(a + 1)}-{n(b + 1)} pass {1e6 * gap:.4g} µm apart")
        for k in rows:
            v = point - o[k - 1]
            shift[k] = v - (v @ h[k - 1]) * h[k - 1]
        if a == 0 and shoulder == 3 and (d := off_line(fa, o[2], h[2])) > MEET_TOL:
            misses.append(f"axis {n(3)} passes {1e6 * d:.4g} µm from the {name} point")
    F = chain.frames(np.zeros(7))
    joints = []
    for k, joint in enumerate(chain.joints, start=1):
        pre = joint.pre.copy()
        pre[:3, 3] += F[k - 1, :3, :3].T @ (shift[k] - shift[k - 1])
        joints.append(replace(joint, pre=pre))
    tool = chain.tool.copy()
    tool[:3, 3] -= F[7, :3, :3].T @ shift[7]
    return SerialChain(joints, chain.base, tool), "; ".join(misses)


@dataclass(frozen=True)
class ChainGap:
    r"""The end's position on a chain less that on a chain which differs from it only in the translations of its
    joints' ``pre`` and ``post`` transforms, base and tool (a near member's :func:`ideal_chain`), at the same q:

    .. math:: \Delta(q) = p(q) - p'(q) = d_0 + \sum_k \big(R_{k-1}(q)\,d^{pre}_k
              + R_k(q)\,S_k^T d^{post}_k\big) + R_n(q)\,d^{tool},

    :math:`R_k` the rotation of link frame k (the same on both chains), :math:`S_k` the rotation of joint k's
    ``post`` and the d's the differences of the translations (base frame for :math:`d_0`, each transform's own
    parent frame otherwise). Attributes: ``base`` (3,) m; ``pre``: (k, d) pairs (1-based joints, d (3,) m) of the
    joints whose ``pre`` translations differ; ``post``: likewise, (k, :math:`S_k^T d^{post}_k`), in link frame k;
    ``tool`` (3,) m."""

    base: np.ndarray
    pre: tuple[tuple[int, np.ndarray], ...]
    post: tuple[tuple[int, np.ndarray], ...]
    tool: np.ndarray

    @classmethod
    def between(cls, chain: SerialChain, ideal: SerialChain) -> ChainGap:
        """The gap of ``chain`` over ``ideal`` (same joints, rotations and types; translations may differ)."""
        pairs = list(enumerate(zip(chain.joints, ideal.joints), 1))
        pre = [(k, x.pre[:3, 3] - y.pre[:3, 3]) for k, (x, y) in pairs]
        post = [(k, x.post[:3, :3].T @ (x.post[:3, 3] - y.post[:3, 3])) for k, (x, y) in pairs]
        return cls(
            chain.base[:3, 3] - ideal.base[:3, 3],
            tuple((k, d) for k, d in pre if d.any()),
            tuple((k, d) for k, d in post if d.any()),
            chain.tool[:3, 3] - ideal.tool[:3, 3],
        )

    @property
    def bound(self) -> float:
        r"""m: a bound of :math:`|\Delta(q)|` over every q, the sum of the differences' lengths (each is turned)."""
        parts = [self.base, self.tool, *(d for _, d in self.pre), *(d for _, d in self.post)]
        return float(sum(np.linalg.norm(d) for d in parts))

    def expr(self, frames: list[Frame]) -> Vec:
        r""":math:`\Delta(q)` (m, base frame) from the chain's frames at q
        (:meth:`~qpik.robots.chain.SerialChain.frames_expr`: base, links 1..n, end; numpy or CasADi)."""
        out: Vec = tuple(float(x) for x in self.base)  # type: ignore[assignment]
        for k, d in self.pre:
            out = sy.vadd(out, sy.matvec(frames[k - 1][0], tuple(float(x) for x in d)))
        for k, d in self.post:
            out = sy.vadd(out, sy.matvec(frames[k][0], tuple(float(x) for x in d)))
        if self.tool.any():
            out = sy.vadd(out, sy.matvec(frames[-2][0], tuple(float(x) for x in self.tool)))
        return out
