"""Bench rows of the locked-q7 closed form, the 1-D search and the general 6-R beside others' solvers of the same arms
(``qpik bench analytic``).

**The Panda** (:func:`panda_rows`). Poses are ``fk(q)`` of the catalog Panda's flange for configurations drawn
uniformly inside Franka's limits (seed 2), each solved at its own q7. Timed interleaved, blocks of
:data:`~qpik.bench.analytic.BLOCK` calls ("hot"):

- ``qpik.ik`` (all 8 branches, flags and limit test);
- frankik's ``ik_full(T, None, q7)`` (Tittel 2021: the flange pose; up to 4 solutions inside the limits, NaN rows
  for the others);
- GeoFIK's ``franka_ik_q7(r, R, q7)`` (geofikpy: the pose of frame E, the flange turned by −π/4 about z and moved
  0.1034 m along it; up to 8 solutions, NaN entries outside the limits);
- ssik's ``panda_ik.solve(T)`` (it samples q7: a larger question, the issue's reference for speed).

**The 1-D search** (:func:`search_rows`): example-robot-data's Baxter, its right arm (:data:`SEARCHED`; left out with
a note when the package is not installed), served by the certified 1-D search over q4 with q1 locked
(:mod:`qpik.analytic.locked_search`). Poses are ``fk(q)`` for configurations drawn inside its limits (seed 4), timed
interleaved, blocks of :data:`~qpik.bench.analytic.BLOCK` calls, fewer samples than the closed forms' rows (a call
takes milliseconds):

- ``qpik.ik`` (all 16 slots at the configuration's q1; its note gives the configurations found of the poses);
- ``qpik.feasible_intervals`` (sampled, not proved: :mod:`qpik.analytic.sampled_sets`) on :data:`SET_POSES` of the
  poses, one call each (no peer computes feasible sets);
- ik-geo's ``Robot.two_intersecting`` (the 6R family of IK-Geo whose axes 5 and 6 meet, solved by a 1-D search over
  its q4) of joints 2-7 at q1 = 0, built once; each pose turned about axis 1 by −q1 before the timing (the locked
  joint folded into the pose), then ``get_ik``. The installed ik-geo (PyPI ``ik-geo`` 1.0.3, the Rust crate 0.1.2)
  searches by minimising each branch's squared error with NLopt's MLSL (low-discrepancy starts, Nelder-Mead local
  runs) over budgets of 50, 200, 1,000 and 2,000 evaluations, stopping at the first budget that finds a root, and
  keeps at most one root per branch whose squared error is below 1e-8: neither a fixed grid nor a certificate.
  qpik's search is certified (every root of every branch, or says it is not proved).

**The general 6-R** (:func:`general_rows`): example-robot-data's TIAGo Pro, its left arm (:data:`GENERAL`), q7
locked, served by elimination to one eigenproblem (:mod:`qpik.analytic.general_solver`). Poses as above (seed 5):

- ``qpik.ik`` (all 16 slots at the configuration's q7);
- ik-geo's ``Robot.gen_six_dof`` (IK-Geo's general 6R, solved by a 2-D search) of joints 1-6 at q7 = 0, built once;
  each pose's flange moved by :math:`M^{-1} E_7(q_7)^{-1} M` before the timing (the locked joint folded into the
  pose), then ``get_ik``.

Every peer's answers are first checked by qpik's FK: each row's note says how many of its finite solutions reach the
pose to 1e-9, and how many of the generating configurations are among them (ik-geo's also gives the FK errors of its
solutions, how often q is among them to 1e-3 rad, how many it flags as least-squares, and how far its own FK at q is
from the pose it is given: the conversion's check). A peer that does not import is left out with a note.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from qpik.analytic.api import feasible_intervals, ik
from qpik.analytic.intervals import wrap
from qpik.analytic.subproblems import rotation
from qpik.bench import Row, cycle, import_peer, time_calls, time_interleaved
from qpik.core.errors import QpikError
from qpik.robots.loader import load_robot

POSES = 64
REACH = 1e-9
"""m and rotation entries: a solution reaches the pose when qpik's FK is this close."""


def _hand() -> np.ndarray:
    """Frame E of GeoFIK (and of frankik's ``fk``) in the flange frame: Rz(−π/4), 0.1034 m along z."""
    c = np.sqrt(0.5)
    E = np.eye(4)
    E[:2, :2] = [[c, c], [-c, c]]
    E[2, 3] = 0.1034
    return E


def panda_rows(repeat: int, block: int, row) -> list[Row]:
    """The rows (module docstring); ``row(label, seconds, ref, note)`` makes one."""
    robot = load_robot("panda")
    q = np.random.default_rng(2).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    T = robot.fk(q)
    E = T @ _hand()
    peers: dict[str, tuple] = {"qpik": (lambda i: ik(robot, T[i], float(q[i, 6])), qpik_solutions)}
    missing = []
    try:
        frankik = import_peer("frankik")
        peers["frankik"] = (lambda i: frankik.ik_full(T[i], None, float(q[i, 6])), lambda out: list(out))
    except ImportError as exc:
        missing.append(f"frankik ({exc})")
    try:
        geofik = import_peer("geofikpy")
        poses = [(E[i, :3, 3].copy(), E[i, :3, :3].reshape(-1).copy()) for i in range(POSES)]
        peers["geofik"] = (lambda i: geofik.franka_ik_q7(*poses[i], float(q[i, 6])), lambda out: list(out[0][: out[1]]))
    except ImportError as exc:
        missing.append(f"geofikpy ({exc})")
    try:
        ssik = import_peer("ssik.prebuilt.franka.panda_ik")
        peers["ssik"] = (lambda i: ssik.solve(T[i]), lambda out: [s.q for s in out])
    except ImportError as exc:
        missing.append(f"ssik ({exc})")
    if missing:
        print("qpik bench analytic: Panda peers left out: " + "; ".join(missing))
    notes = {key: check_note(robot, T, q, fn, solutions) for key, (fn, solutions) in peers.items()}
    calls = {key: cycle(fn, list(range(POSES))) for key, (fn, _) in peers.items()}
    t = time_interleaved(calls, max(20, repeat // block), block=block)
    labels = {
        "qpik": "panda q7 locked: qpik.ik, 8 branches",
        "frankik": "panda q7 locked: frankik ik_full (4 solutions)",
        "geofik": "panda q7 locked: GeoFIK franka_ik_q7 (8 solutions)",
        "ssik": "panda: ssik panda_ik.solve (q7 sampled)",
    }
    fastest = min((k for k in ("frankik", "geofik") if k in t), key=lambda k: np.median(t[k]), default=None)
    ref = None if fastest is None else labels[fastest]
    return [row(labels[k], t[k], None if k == fastest or k == "ssik" else ref, notes[k]) for k in peers]


SET_POSES = 4
"""Poses of the 1-D search's feasible-sets row, one call each (a call takes seconds)."""


@dataclass(frozen=True)
class PeerArm:
    """An arm of the rows beside ik-geo (:func:`_beside_geo`): its packaged model (``key``, load ``options``), the
    locked joint (0: q1, 6: q7), the seed of its configurations, the rows' labels (qpik's, ik-geo's) and their name in
    a note."""

    key: str
    options: dict
    locked: int
    seed: int
    labels: tuple[str, str]
    words: str


SEARCHED = PeerArm("erd/baxter", {"base": "right_arm_mount", "tip": "right_wrist"}, 0, 4,
                   ("baxter q1 locked: qpik.ik, 16 slots (certified 1-D search)",
                    "baxter q1 locked: ik-geo two_intersecting get_ik (6R, 1-D search by NLopt MLSL)"),
                   "the 1-D search's rows")  # fmt: skip
"""The arm of the 1-D search's rows: example-robot-data's Baxter, its right arm, q1 locked."""
GENERAL = PeerArm("erd/tiago_pro", {"base": "torso_lift_link", "tip": "arm_left_tool_link"}, 6, 5,
                  ("tiago pro q7 locked: qpik.ik, 16 slots (general 6-R: one eigenproblem)",
                   "tiago pro q7 locked: ik-geo gen_six_dof get_ik (6R, 2-D search)"),
                  "the general 6-R's rows")  # fmt: skip
"""The arm of the general 6-R's rows: example-robot-data's TIAGo Pro, its left arm, q7 locked."""


def search_rows(repeat: int, block: int, row) -> list[Row]:
    """The rows of the 1-D search (module docstring); ``row(label, seconds, ref, note)`` makes one."""
    robot, T, rows = _beside_geo(SEARCHED, repeat, block, row)
    if robot is None:
        return rows
    sets = time_calls(cycle(lambda i: feasible_intervals(robot, T[i]), range(SET_POSES)), SET_POSES, warmup=1)
    label = "baxter q1 locked: qpik.feasible_intervals, 16 slots (sampled, not proved)"
    return [*rows, row(label, sets, None, f"({SET_POSES} poses, one call each; no peer computes feasible sets)")]


def general_rows(repeat: int, block: int, row) -> list[Row]:
    """The rows of the general 6-R (module docstring); ``row(label, seconds, ref, note)`` makes one."""
    return _beside_geo(GENERAL, repeat, block, row)[2]


def _beside_geo(arm: PeerArm, repeat: int, block: int, row) -> tuple:
    """The arm of ``arm`` (None with a note where its package is not installed), its poses (POSES, 4, 4) of
    configurations drawn inside its limits, and the rows of ``qpik.ik`` at their own locked joint beside ik-geo's
    solver of the other six joints (:func:`_geo_locked`; left out with a note where ik-geo is not installed), both
    checked by qpik's FK, then timed interleaved (fewer samples than the closed forms: a call takes milliseconds)."""
    from qpik.robots.packaged import packaged_model

    try:
        robot = load_robot(str(packaged_model(arm.key)), **arm.options)
    except QpikError as exc:
        print(f"qpik bench analytic: {arm.words} left out: {exc}")
        return None, None, []
    locked = arm.locked
    q = np.random.default_rng(arm.seed).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    T = robot.fk(q)
    calls = {"qpik": lambda i: ik(robot, T[i], float(q[i, locked]))}
    notes = {"qpik": check_note(robot, T, q, calls["qpik"], qpik_solutions)}
    try:
        geo, poses = _geo_locked(robot, T, q[:, locked], locked, import_peer("ik_geo"))
        calls["geo"] = lambda i: geo.get_ik(*poses[i])

        solved = [calls["geo"](i) for i in range(POSES)]  # its answers, once per pose: every note reads the same

        def answers(i: int) -> list[np.ndarray]:
            return [np.insert(np.asarray(x, float), locked, q[i, locked]) for x, _ in solved[i]]

        flagged = sum(ls for sols in solved for _, ls in sols)
        free = [j for j in range(robot.dof) if j != locked]
        fk = max(  # ik-geo's own FK at q against the pose it is given: the conversion, checked
            max(np.abs(np.asarray(geo.forward_kinematics(q[i, free])[k]) - poses[i][k]).max() for k in (0, 1))
            for i in range(POSES)
        )
        notes["geo"] = check_note(robot, T, q, answers, list) + _worst(robot, T, q, answers)
        notes["geo"] += f" (flagged least-squares by ik-geo: {flagged}; its FK at q: the pose given to {fk:.0e})"
    except ImportError as exc:
        print(f"qpik bench analytic: ik-geo left out of {arm.words} ({exc})")
    samples = max(10, repeat // (10 * block))
    t = time_interleaved({k: cycle(fn, list(range(POSES))) for k, fn in calls.items()}, samples, block=block)
    ours, theirs = arm.labels
    rows = [row(ours, t["qpik"], theirs if "geo" in t else None, notes["qpik"])]
    return robot, T, rows + ([row(theirs, t["geo"], None, notes["geo"])] if "geo" in t else [])


def _worst(robot, T: np.ndarray, q: np.ndarray, answers) -> str:
    """The FK errors of a peer's answers (qpik's FK: median and largest entry of the pose's difference) and how often
    q is among them to 1e-3 rad."""
    errors, near = [], 0
    for i in range(len(T)):
        sols = answers(i)
        errors += [float(np.abs(robot.fk(x) - T[i]).max()) for x in sols]
        near += any(np.abs(wrap(x - q[i])).max() < 1e-3 for x in sols)
    if not errors:
        return " (no solutions)"
    return f" (FK error median {np.median(errors):.0e}, max {max(errors):.0e}; q within 1e-3 rad {near}/{len(T)})"


def _geo_locked(robot, T: np.ndarray, angles: np.ndarray, locked: int, ik_geo) -> tuple:
    """ik-geo's robot of the arm's other six joints with the locked one (0: q1, ``two_intersecting``, whose axes 5 and
    6 meet; 6: q7, ``gen_six_dof``) at 0 (product of exponentials: axes and the offsets between points on them, base
    frame; the points of the last two axes where they meet for ``two_intersecting``), and the poses with the locked
    joint at ``angles`` folded in (outside the timing) as ``get_ik`` takes them: rotation relative to the flange's at
    q = 0, transposed (its convention), and position. q1 turns the pose about axis 1 by −q1; q7 moves the flange
    by :math:`M^{-1} E_7(q_7)^{-1} M` (M the flange's pose at q = 0)."""
    zero = np.zeros(robot.dof)
    h, o = robot.chain.axes(zero)
    home = robot.fk(zero)
    free = [j for j in range(robot.dof) if j != locked]
    points = [o[j] for j in free]
    if locked == 0:
        s, t = np.linalg.lstsq(np.stack([h[5], -h[6]], axis=1), o[6] - o[5], rcond=None)[0]
        points[-2:] = [0.5 * (o[5] + s * h[5] + o[6] + t * h[6])] * 2
    offsets = [points[0]] + [b - a for a, b in itertools.pairwise(points)] + [home[:3, 3] - points[-1]]
    make = ik_geo.Robot.two_intersecting if locked == 0 else ik_geo.Robot.gen_six_dof
    geo = make(np.array(h[free]), np.array(offsets))
    poses = []
    for Ti, a in zip(T, angles):
        M = np.eye(4)
        M[:3, :3] = np.array(rotation(tuple(h[locked]), np.cos(a), -np.sin(a)), float)
        M[:3, 3] = o[locked] - M[:3, :3] @ o[locked]  # E(−a) about the locked axis
        Tz = M @ Ti if locked == 0 else Ti @ np.linalg.inv(home) @ M @ home
        poses.append(((Tz[:3, :3] @ home[:3, :3].T).T.copy(), Tz[:3, 3].copy()))
    return geo, poses


def qpik_solutions(sols) -> list[np.ndarray]:
    """The valid branches' configurations of a :class:`qpik.IKSolutions`."""
    return list(sols.q[sols.valid])


def check_note(robot, T: np.ndarray, q: np.ndarray, fn, solutions) -> str:
    """How many of a peer's finite solutions reach their pose by qpik's FK, and how often q is among them."""
    good = total = found = 0
    for i in range(len(T)):
        sols = [np.asarray(x, float).ravel() for x in solutions(fn(i))]
        sols = [x for x in sols if np.isfinite(x).all()]
        total += len(sols)
        reach = [x for x in sols if np.abs(robot.fk(x) - T[i]).max() <= REACH]
        good += len(reach)
        found += any(np.abs(wrap(x - q[i])).max() < 1e-7 for x in reach)
    n = len(T)
    return f"({good}/{total} solutions of {n} poses reach the pose to 1e-9 by qpik's FK; q among them {found}/{n})"
