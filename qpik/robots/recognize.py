r"""Recognising an S-R-S or offset-shoulder arm in any serial chain, and its map to the catalog's DH table.

The closed-form solvers (:mod:`qpik.analytic.srs`, :mod:`qpik.analytic.offset_shoulder`) are
written for one DH table each (standard DH), a :data:`PATTERNS` entry: the twists α, the
joint offsets, which a and d are zero and the signs some d must have. A 7-joint revolute
chain fits a pattern when a DH table of that form, with some base and tool transforms,
has the same FK under a joint map

.. math:: q^{DH}_i = s_i\,q_i + c_i,\qquad s_i = \pm 1,

(the sign of each joint axis, and the zero offsets that real models carry).

:func:`recognize` derives the table from the joint axis lines at q = 0 (the DH parameters of
consecutive axes do not depend on q): with the axis directions :math:`u_i = s_i z_i`, x_i is
the common normal of axes i and i+1 (for intersecting axes :math:`\pm u_i \times u_{i+1}`,
the sign that gives the pattern's α_i), :math:`a_i` its length, :math:`d_i` the distance
along axis i between the normals i-1 and i, :math:`\theta_i` the angle between them (so
:math:`c_i = \theta_i - o_i` at q = 0). Frame 0 sits on axis 1 at the foot of the chain's
base origin with x along the base's x (projected), frame 7 on axis 7 at the foot of the
end effector's origin (or at the wrist centre where the pattern needs d_7 ≤ 0 and the
foot is beyond), and the tool takes the rest. The sign choices are tried in the order of
fewest flips; the first that fits the pattern is verified by FK at random q (to
:data:`VERIFY_TOL`) before it is accepted. Otherwise the reason is said in one line
("axes 5-6-7 do not intersect (offsets 0.088 m)").
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from qpik.algebra.loop6r import Loop6R
from qpik.core.errors import InputError
from qpik.robots.chain import SerialChain
from qpik.robots.dh import DHChain
from qpik.robots.elbow_search import find_elbow_search
from qpik.robots.locked_joint import NEAR_TOL, find_locked_joint, ideal_chain, layout_words, reversed_chain

TOL = 1e-9
"""m and rad: an a or d below this is zero, an α within this of ±π/2 is ±π/2."""
ROUGHLY = 1e-3
"""rad: consecutive axes off perpendicular by more than this are reported before any offset."""
VERIFY_TOL = 1e-10
"""Largest difference (m, and rotation-matrix entries) of the FK of the chain and of the mapped DH table."""
PI = np.pi
HALF = np.pi / 2


@dataclass(frozen=True)
class Pattern:
    """A DH table form (standard DH, 7 joints).

    Attributes:
        alpha: the twists α_i (rad).
        offset: the joint offsets o_i (rad): the table turns joint i by q_i + o_i.
        a_free: the a_i that may be non-zero (0-based), all others must be 0.
        d_zero: the d_i that must be 0 (0-based).
        d_sign: ``{i: +1 or -1}``: d_i must be > 0 (< 0).
        d7_nonpositive: d_7 must be ≤ 0.
    """

    alpha: tuple[float, ...]
    offset: tuple[float, ...]
    a_free: frozenset[int]
    d_zero: frozenset[int]
    d_sign: dict[int, int]
    d7_nonpositive: bool = False


PATTERNS: dict[str, Pattern] = {
    # Shimizu et al. 2008 as written for iiwa14 (qpik.analytic.srs): a = 0, d = (d_bs, 0, d_se, 0, d_ew, 0, d_wt)
    "srs": Pattern(
        alpha=(-HALF, HALF, HALF, -HALF, -HALF, HALF, 0.0),
        offset=(0.0,) * 7,
        a_free=frozenset(),
        d_zero=frozenset({1, 3, 5}),
        d_sign={2: 1, 4: 1},
    ),
    # Nammoto & Kosuge 2012, Table 1: a = (a1, 0, ...), d = (d1, 0, d3, 0, -d5, 0, -d7)
    "offset_shoulder": Pattern(
        alpha=(HALF, -HALF, HALF, -HALF, HALF, HALF, 0.0),
        offset=(0.0, 0.0, 0.0, HALF, 0.0, PI, 0.0),
        a_free=frozenset({0}),
        d_zero=frozenset({1, 3, 5}),
        d_sign={2: 1, 4: -1},
        d7_nonpositive=True,
    ),
}


@dataclass(frozen=True)
class JointMap:
    r"""The canonical table's joint angles from the robot's: :math:`q^{DH} = s \odot q + c` (rad).

    Attributes:
        sign: (n,) ±1.
        shift: (n,) c, rad, in (−π, π].
    """

    sign: np.ndarray
    shift: np.ndarray

    @property
    def identity(self) -> bool:
        return bool(np.all(self.sign == 1.0) and np.all(self.shift == 0.0))

    def to_table(self, q: np.ndarray) -> np.ndarray:
        """q (..., n) of the robot -> the table's angles (not wrapped)."""
        return self.sign * q + self.shift


@dataclass(frozen=True)
class Canonical:
    """A closed form found in a chain: the catalog-form DH table with its base/tool, and the joint map (for the
    locked-q7 family, which reads the axes of any chain, the chain itself and the identity); ``notes``, the
    geometry in words where the family says it. ``exact`` False: ``table`` is the family's chain nearest to one that
    misses it by a file's rounding (:func:`qpik.robots.locked_joint.ideal_chain`), whose branches the solver polishes
    on the robot's own chain (:mod:`qpik.analytic.polish`). ``reversed``: ``table`` is of the family read from the
    flange (:func:`qpik.robots.locked_joint.reversed_chain`; its joint k is the robot's joint 8 − k, q1 locked)."""

    kind: str
    table: SerialChain
    joints: JointMap
    notes: str = ""
    exact: bool = True
    reversed: bool = False


REDUNDANCY = {"psi": "srs", "delta": "offset_shoulder", "q7": "locked_joint", "q1": "locked_joint"}
"""The redundancy parameters a user can ask for (``load_robot(..., redundancy=)``) and their family (q7, q1: the
locked-joint closed form, else the 1-D search of the same locked joint, ``"locked_search"``, else the general 6-R
left, ``"locked_general"``)."""


def recognize(chain: SerialChain, redundancy: str | None = None) -> tuple[Canonical | None, str]:
    """The first closed form ``chain`` fits, or None and the reason (one line): the patterns of :data:`PATTERNS`,
    then q7 locked, then q1 locked (the chain read from the flange; :mod:`qpik.robots.locked_joint`), exactly or as a
    near member (its axes miss by at most
    :data:`~qpik.robots.locked_joint.NEAR_TOL`: the closed form of its ideal chain, polished on its own), then the
    1-D search's geometry (``"locked_search"``, q1 locked, then q7; :func:`_searched`), then a general 6-R chain left
    with q7 or q1 locked (``"locked_general"``, :func:`_general`), whose notes say what serves it and why there is no
    closed form. ``redundancy`` (a key of :data:`REDUNDANCY`) tries only the
    family of that parameter (and for q1 or q7, the search with that joint locked)."""
    if redundancy is not None and redundancy not in REDUNDANCY:
        raise InputError(f"redundancy: expected one of {', '.join(REDUNDANCY)} or None, got {redundancy!r}"[:200])
    if len(chain.joints) != chain.dof:
        return None, "the closed forms do not cover mimic (coupled) joints"
    if chain.dof != 7 or chain.prismatic.any():
        return None, f"the closed forms need 7 revolute joints, the chain has {chain.dof} joints" + (
            f", {int(chain.prismatic.sum())} prismatic" if chain.prismatic.any() else ""
        )
    reasons = []
    wanted = None if redundancy is None else REDUNDANCY[redundancy]
    for kind, pattern in PATTERNS.items():
        if wanted not in (None, kind):
            continue
        found, why = _fit(chain, kind, pattern)
        if found is not None:
            return replace(found, notes=_pattern_notes(kind, found.table, chain)), ""
        reasons.append(f"not {kind.replace('_', '-')}: {why}")
    directions = {"q7": (False,), "q1": (True,)}.get(redundancy or "", (True, False))
    if wanted in (None, "locked_joint"):
        found, why = _locked(chain, directions[::-1])
        if found is not None:
            return found, ""
        reasons.append(why)
    why = f"{layout_words(chain)}; " + "; ".join(reasons)
    if wanted not in (None, "locked_joint"):
        return None, why
    found = _searched(chain, directions)
    if found is None:
        found, general = _general(chain, directions[::-1])
        if found is None:
            return None, f"{why}; {general}"
    return replace(found, notes=f"{found.notes}, no closed form: {why}"), ""


def _pattern_notes(kind: str, table: SerialChain, chain: SerialChain) -> str:
    """The geometry of a :data:`PATTERNS` family found in ``chain`` (its table ``table``, a :class:`DHChain`) in
    words, with its lengths in mm, and the solver that serves it."""
    d, a = np.abs(np.asarray(table.d)), np.abs(np.asarray(table.a))  # type: ignore[attr-defined]
    arm = [("base to shoulder", d[0]), ("shoulder to elbow", d[2]), ("elbow to wrist", d[4]), ("wrist to flange", d[6])]
    if kind == "srs":
        head = "the arm angle ψ (parameter psi, 8 branches; Shimizu et al. 2008, qpik.analytic.srs)"
        shape = "axes 1-2-3 meet (spherical shoulder), axes 5-6-7 meet (spherical wrist), axis 4 meets axes 3 and 5"
    else:
        head = "δ (parameter delta, 16 branches; Nammoto & Kosuge 2012, qpik.analytic.offset_shoulder)"
        shape = "axes 2-3 meet, axes 5-6-7 meet (spherical wrist), axis 4 meets axes 3 and 5, axis 1 offset from axis 2"
        arm.insert(0, ("shoulder offset", a[0]))
    said = ", ".join(f"{name} {1e3 * x:.4g} mm" for name, x in arm)
    return f"closed form along {head}: {shape}; {said} ({layout_words(chain)})"


def _searched(chain: SerialChain, directions: tuple[bool, ...]) -> Canonical | None:
    """The family of the 1-D search (:mod:`qpik.analytic.locked_search`, ``"locked_search"``) in ``chain``, its
    geometries in the order of :func:`qpik.analytic.search_geometry.search_for`: the locked-q7 geometry but for axis 3
    (:func:`~qpik.robots.locked_joint.find_locked_joint` with ``shoulder=2``) exactly, then the geometry of
    :func:`~qpik.robots.elbow_search.find_elbow_search`, then the first within
    :data:`~qpik.robots.locked_joint.NEAR_TOL`, each with q1 locked (``True`` in ``directions``, the chain read from
    the flange) or q7 locked (``False``), in that order; None where none holds. ``table`` is the chain itself (the
    search finds its ideal chain), ``exact`` whether the geometry holds without the tolerance, ``notes`` the search in
    words."""
    identity = JointMap(np.ones(7), np.zeros(7))

    def found(rev: bool, exact: bool, x: str, module: str) -> Canonical:
        notes = f"served by a certified 1-D search over {x} with q{1 if rev else 7} locked (qpik.analytic.{module})"
        return Canonical("locked_search", chain, identity, notes, exact=exact, reversed=rev)

    turned = {rev: reversed_chain(chain) if rev else chain for rev in directions}
    for rev, c in turned.items():
        if find_locked_joint(c, reversed=rev, shoulder=2)[0] is not None:
            return found(rev, True, "q4", "search_geometry.ShoulderSearch")
    for rev, c in turned.items():
        if find_elbow_search(c, rev)[0] is not None:
            return found(rev, True, "q7" if rev else "q1", "search_geometry.ElbowSearch")
    for rev, c in turned.items():
        if find_locked_joint(c, NEAR_TOL, rev, shoulder=2)[0] is not None:
            return found(rev, False, "q4", "search_geometry.ShoulderSearch, on its nearest ideal chain")
    return None


def _general(chain: SerialChain, directions: tuple[bool, ...]) -> tuple[Canonical | None, str]:
    """The general family (``"locked_general"``, :mod:`qpik.analytic.general_solver`) in ``chain``: q7 locked
    (``False`` in ``directions``) or q1 (``True``, the chain read from the flange), in that order, where a window of
    the elimination of joints 1-6 holds (:meth:`qpik.algebra.loop6r.Loop6R.of`); None and the reasons otherwise."""
    reasons = []
    for rev in directions:
        turned = reversed_chain(chain) if rev else chain
        h, o = turned.axes(np.zeros(7))
        loop, why = Loop6R.of(h[:6], o[:6])
        locked = 1 if rev else 7
        if loop is not None:
            w = loop.window
            joints = "-".join(str(7 - j if rev else j + 1) for j in (*w.left, w.gone))  # the arm's numbers
            notes = (f"served with q{locked} locked by elimination of the 6-R chain left to one eigenproblem of size "
                     f"24 (Raghavan & Roth 1993; Manocha & Canny 1994; joints {joints}; qpik.algebra.loop6r), each "
                     "solution polished on the file's chain, not proved (qpik.analytic.general_solver)")  # fmt: skip
            identity = JointMap(np.ones(7), np.zeros(7))
            return Canonical("locked_general", chain, identity, notes, reversed=rev), ""
        reasons.append(f"q{locked} locked: {why}")
    return None, "no elimination: " + "; ".join(reasons)


def _search(chain: SerialChain) -> str:
    """For a near member of the locked-joint family, served by its ideal chain's closed form: the 1-D search
    (:mod:`qpik.analytic.locked_search`) that would find the file's own roots, where its geometry holds."""
    found = _searched(chain, (True, False))
    if found is None:
        return ""
    return f"; IK by {found.notes.removeprefix('served by ')}; qpik.ik uses the closed form"


def _locked(chain: SerialChain, directions: tuple[bool, ...]) -> tuple[Canonical | None, str]:
    """The locked-joint family (:mod:`qpik.robots.locked_joint`) in ``chain``: q7 locked (``False`` in ``directions``)
    or q1 locked, the chain read from the flange (``True``), exactly, then as a near member; or the reasons."""
    identity = JointMap(np.ones(7), np.zeros(7))
    layout = layout_words(chain)
    turned = {rev: reversed_chain(chain) if rev else chain for rev in directions}
    for rev, c in turned.items():
        geometry, _ = find_locked_joint(c, reversed=rev)
        if geometry is not None:
            return Canonical("locked_joint", c, identity, geometry.describe(layout), reversed=rev), ""
    reasons = {}
    for rev, c in turned.items():
        ideal, near = ideal_chain(c, rev)
        geometry, reasons[rev] = (None, near) if ideal is None else find_locked_joint(ideal, reversed=rev)
        if geometry is not None:
            notes = geometry.describe(layout, near) + _search(chain)  # a near member: the search may be exact
            return Canonical("locked_joint", ideal, identity, notes, False, rev), ""
    return None, "; ".join(f"not the locked-q{1 if rev else 7} closed form: {why}" for rev, why in reasons.items())


def _fit(chain: SerialChain, kind: str, pattern: Pattern) -> tuple[Canonical | None, str]:
    z, o = chain.axes(np.zeros(7))
    why = _structure(z, o, pattern)
    if why:
        return None, why
    why = "no choice of axis signs gives the table's twists and signs of d"
    for flips in sorted(itertools.product((1.0, -1.0), repeat=7), key=lambda s: (s.count(-1.0), [-x for x in s])):
        sign = np.array(flips)
        table = _table(chain, sign[:, None] * z, o, pattern)
        if table is None:
            continue
        canonical = Canonical(kind, table[0], JointMap(sign, table[1]))
        err = _verify(chain, canonical)
        if err <= VERIFY_TOL:
            return canonical, ""
        why = f"FK of the fitted table differs by {err:.1e}"
    return None, why


def _normal(u: np.ndarray, p: np.ndarray, v: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Feet (on line 1, on line 2) of the common normal of the lines p + t u and q + t v (not parallel)."""
    w = p - q
    a, b, c, d, e = u @ u, u @ v, v @ v, u @ w, v @ w
    den = a * c - b * b
    t, s = (b * e - c * d) / den, (a * e - b * d) / den
    return p + t * u, q + s * v


def _structure(z: np.ndarray, o: np.ndarray, pattern: Pattern) -> str:
    """The sign-free conditions: perpendicular consecutive axes, the zero a's and d's; '' when they hold. An axis pair
    off perpendicular by less than :data:`ROUGHLY` is said only when the intersections hold (the file's rounding is
    then what is left, not the reason)."""
    angles = [np.arccos(np.clip(abs(z[i] @ z[i + 1]), 0.0, 1.0)) for i in range(6)]

    def perpendicular(tol: float) -> str:
        for i, angle in enumerate(angles):
            if (off := abs(angle - HALF)) > tol:
                return f"axes {i + 1}-{i + 2} are not perpendicular ({np.degrees(angle):.6g}°, {off:.1e} rad off)"
        return ""

    if why := perpendicular(ROUGHLY):
        return why
    feet = [_normal(z[i], o[i], z[i + 1], o[i + 1]) for i in range(6)]
    offsets = {i: float(np.linalg.norm(b - a)) for i, (a, b) in enumerate(feet)}
    gaps = {i: float(abs((feet[i][0] - feet[i - 1][1]) @ z[i])) for i in range(1, 6)}
    groups = ((0, 1, 2), (2, 3, 4), (4, 5, 6))  # shoulder, elbow, wrist: axes that should meet in one point
    for g in groups:
        bad = [offsets[i] for i in g[:2] if i not in pattern.a_free and offsets[i] > TOL]
        bad += [gaps[g[1]]] if g[1] in pattern.d_zero and gaps[g[1]] > TOL else []
        if bad:
            names = "-".join(str(i + 1) for i in g)
            return f"axes {names} do not intersect (offsets {', '.join(f'{x:.3g}' for x in bad)} m)"
    return perpendicular(TOL)


def _table(chain: SerialChain, u: np.ndarray, o: np.ndarray, pattern: Pattern) -> tuple[DHChain, np.ndarray] | None:
    """The pattern's DH table on the signed axes u (7, 3) through o (7, 3), and the shifts; None if it does not fit."""
    x = []
    origins = []  # frame i's origin (on axis i+1), i = 1..6
    feet = []  # the foot of normal i on axis i
    a = np.zeros(7)
    for i in range(6):
        foot_i, foot_next = _normal(u[i], o[i], u[i + 1], o[i + 1])
        a[i] = np.linalg.norm(foot_next - foot_i)
        if a[i] > TOL:
            xi = (foot_next - foot_i) / a[i]
            alpha = np.arctan2(np.cross(u[i], u[i + 1]) @ xi, u[i] @ u[i + 1])
            if abs(alpha - pattern.alpha[i]) > TOL:
                return None
        else:
            a[i] = 0.0
            xi = np.cross(u[i], u[i + 1]) * np.sign(np.sin(pattern.alpha[i]))  # gives α_i = pattern
            xi /= np.linalg.norm(xi)
        x.append(xi)
        origins.append(foot_next)
        feet.append(foot_i)
    base = chain.base
    o0 = o[0] + ((base[:3, 3] - o[0]) @ u[0]) * u[0]  # frame 0: on axis 1 at the foot of the base origin
    x0 = base[:3, 0] - (base[:3, 0] @ u[0]) * u[0]
    if np.linalg.norm(x0) < 1e-6:
        x0 = base[:3, 1] - (base[:3, 1] @ u[0]) * u[0]
    x0 /= np.linalg.norm(x0)
    ee = chain.fk(np.zeros(7))
    p7 = o[6] + ((ee[:3, 3] - o[6]) @ u[6]) * u[6]  # frame 7: on axis 7 at the foot of the ee origin
    d = np.zeros(7)
    d[0] = (feet[0] - o0) @ u[0]
    for i in range(1, 6):
        d[i] = (feet[i] - origins[i - 1]) @ u[i]
    d[6] = (p7 - origins[5]) @ u[6]
    if pattern.d7_nonpositive and d[6] > 0:
        p7, d[6] = origins[5], 0.0  # frame 7 at the wrist centre
    for i in pattern.d_zero:
        d[i] = 0.0  # below TOL: checked by _structure
    if any(np.sign(d[i]) != s for i, s in pattern.d_sign.items()):
        return None
    theta = np.array([_angle(xa, xb, ui) for xa, xb, ui in zip([x0, *x[:5]], x, u)])
    shift = np.zeros(7)
    shift[:6] = _wrap(theta - np.array(pattern.offset[:6]))
    F7 = np.eye(4)  # frame 7 at q = 0 with q7^DH = 0: x_7 = R(u_7, o_7) x_6
    x7 = _rotate(x[5], u[6], pattern.offset[6])
    F7[:3, 0], F7[:3, 1], F7[:3, 2], F7[:3, 3] = x7, np.cross(u[6], x7), u[6], p7
    B = np.eye(4)
    B[:3, 0], B[:3, 1], B[:3, 2], B[:3, 3] = x0, np.cross(u[0], x0), u[0], o0
    table = DHChain(
        a=tuple(a),
        d=tuple(d),
        alpha=pattern.alpha,
        offset=pattern.offset,
        base=_clean(B),
        tool=_clean(np.linalg.inv(F7) @ ee),
    )
    return table, _snap_angles(shift)


def _verify(chain: SerialChain, canonical: Canonical) -> float:
    """Largest FK difference between the chain and the mapped table over 64 random configurations."""
    q = np.random.default_rng(0).uniform(-PI, PI, (64, 7))
    return float(np.abs(chain.fk(q) - canonical.table.fk(canonical.joints.to_table(q))).max())


def _angle(xa: np.ndarray, xb: np.ndarray, u: np.ndarray) -> float:
    """Signed angle (rad) from xa to xb about the unit vector u."""
    return float(np.arctan2(np.cross(xa, xb) @ u, xa @ xb))


def _rotate(v: np.ndarray, u: np.ndarray, angle: float) -> np.ndarray:
    """v turned by ``angle`` about the unit vector u (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    return v * c + np.cross(u, v) * s + u * (u @ v) * (1 - c)


def _wrap(x: np.ndarray) -> np.ndarray:
    return x + 2 * PI * np.floor((PI - x) / (2 * PI))


def _snap_angles(x: np.ndarray) -> np.ndarray:
    """Angles within TOL of a multiple of π/2 set to it (models write their quarter turns to ~1e-12)."""
    k = np.round(x / HALF)
    return _wrap(np.where(np.abs(x - k * HALF) < TOL, k * HALF, x))


def _clean(T: np.ndarray) -> np.ndarray:
    """Entries within 1e-15 of 0 or ±1 set to it (so that they fold away in the compiled expressions)."""
    out = T.copy()
    for v in (0.0, 1.0, -1.0):
        out[np.abs(out - v) < 1e-15] = v
    return out
