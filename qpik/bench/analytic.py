"""Bench: the closed form — one pose, a batch of poses, the feasible intervals — beside ssik.

For each arm with a closed form (``nammoto7``: δ, ``iiwa14``: ψ, ``panda``: q7 locked), poses are
``fk(q)`` of configurations drawn uniformly inside the joint limits (seed 0)
and the parameter of each is the one of its configuration. Rows, in seconds
per pose (median; the single-pose rows and ssik's over blocks of :data:`BLOCK` calls, "hot"):

- ``qpik.ik`` on one pose (all 16 / 8 branches; input checks included), the parameter a Python float;
- the same with the parameter a ``numpy.float64`` (an element of a numpy array), interleaved with the float
  calls; its note gives the ratio of the two medians;
- ``qpik.ik`` on a batch of ``BATCH`` poses with (N,) parameters, divided by N;
- ``qpik.feasible_intervals`` on one pose (every branch's exact δ/ψ set);
- ``ssik.prebuilt.kuka.iiwa14_ik.solve(T)`` on the same iiwa poses (the
  reference: it enumerates the arm-angle self-motion, so it answers a larger
  question; it is the fastest published analytic iiwa solver we can call).

Then, for iiwa14 on poses whose joint 3 is fixed (:data:`LOCKED`, so that 6-DOF solvers can lock
it), timed interleaved: ``qpik.ik`` (all 8 branches at the ψ of the configuration), EAIK
(``DhRobot`` of iiwa14's DH table with joint 3 locked, ``bot.IK(T)``: its 8 solutions of the 6R
arm) and ik-geo (``Robot.spherical_two_intersecting`` of EAIK's remodelled axes, ``get_ik``, its
rotation convention converted before timing), and the batched calls (EAIK's ``IK_batched`` with
:data:`EAIK_THREADS` threads). Every peer's answers are first checked by qpik's FK: the rows say
how many of a peer's solutions reach the pose to 1e-9. A peer that is not installed (the test
extra) is left out with a note. Then the Panda beside frankik, GeoFIK and ssik, and every 7-R arm that ssik ships
with a closed form or the 1-D search, on ssik's own kinematics, beside ssik (:mod:`qpik.bench.ssik_arms`); last, an
arm that needs the 1-D search (example-robot-data's Baxter, right arm, q1 locked: all 16 slots) beside ik-geo's
1-D search of the same 6R problem (:mod:`qpik.bench.analytic_locked`).

Targets (issue): single ≤ 3 µs and faster than EAIK, with a numpy scalar parameter within 10 % of a float;
batched ≤ 3 µs/pose; intervals ≤ 50 µs/pose for both arms; the 1-D search ≤ 100 µs a pose, all 16 slots. Nammoto &
Kosuge report 31.3 µs per solution set (compiled code, Core i7 965, 2012): a note, not a measurement.
"""

from __future__ import annotations

import argparse

import numpy as np

from qpik.analytic.api import closed_form_for, feasible_intervals, ik, redundancy_parameter, symbol
from qpik.bench import Row, cycle, time_calls, time_interleaved
from qpik.bench.analytic_locked import general_rows, panda_rows, search_rows
from qpik.bench.ssik_arms import ssik_rows
from qpik.robots.loader import load_robot

BLOCK = 20
"""The single-pose rows (one pose, feasible intervals, the locked-joint rows): each sample is a block of this many
calls (poses cycling), divided ("hot")."""
TITLE = f"Closed-form IK (per pose; single-pose rows hot: blocks of {BLOCK} calls, peers' blocks interleaved)"
ARMS = ("nammoto7", "iiwa14", "panda")
POSES = 64  # distinct poses cycled through by the single-pose rows
BATCH = 10_000
BATCH_CALLS = 20
"""Batched calls timed per batched row (at least; more with a larger --repeat): each is 10,000 poses."""
LOCKED = 0.3
"""rad: joint 3 of iiwa14 in the poses of the locked-joint rows (labelled "q3 locked"); the batched rows
take :data:`BATCH` poses per call."""
EAIK_THREADS = 2
SSIK = "ssik iiwa14_ik.solve (iiwa14)"
PAPER_NOTE = "(paper: 31.3 µs, compiled, 2012 Core i7 965; quoted, not measured)"


def run(args: argparse.Namespace) -> list[Row]:
    repeat = max(20, int(getattr(args, "repeat", 2000)))
    rows: list[Row] = []
    ssik_row = _ssik_row(repeat)
    if ssik_row is not None:
        rows.append(ssik_row)
    for name in ARMS:
        rows += _arm_rows(name, repeat, SSIK if name == "iiwa14" and ssik_row is not None else None)
    rows += _locked_rows(repeat) + panda_rows(repeat, BLOCK, _row) + ssik_rows(repeat, BLOCK, _row)
    return rows + search_rows(repeat, BLOCK, _row) + general_rows(repeat, BLOCK, _row)


def _arm_rows(name: str, repeat: int, ref: str | None) -> list[Row]:
    """Single, batched and intervals rows of one arm."""
    robot = load_robot(name)
    q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (BATCH, robot.dof))
    T = robot.fk(q)
    par = np.asarray(redundancy_parameter(robot, q)[0])
    cases = list(zip(T[:POSES], par[:POSES].tolist()))
    scalars = list(zip(T[:POSES], par[:POSES]))  # the same parameters as numpy.float64
    single = time_interleaved(
        {
            "float": cycle(lambda c: ik(robot, c[0], c[1]), cases),
            "numpy": cycle(lambda c: ik(robot, c[0], c[1]), scalars),
        },
        max(20, repeat // BLOCK),
        block=BLOCK,
    )
    t1 = single["float"]
    tb = time_calls(lambda: ik(robot, T, par), max(BATCH_CALLS, repeat // 100), warmup=1) / BATCH
    ti = time_calls(
        cycle(lambda c: feasible_intervals(robot, c[0]), cases), max(10, repeat // (2 * BLOCK)), warmup=3, block=BLOCK
    )
    sym = symbol(closed_form_for(robot).param_name)
    ratio = float(np.median(single["numpy"]) / np.median(t1))
    return [
        _row(f"qpik.ik, 1 pose ({name})", t1, ref, PAPER_NOTE if name == "nammoto7" else ""),
        _row(
            f"qpik.ik, 1 pose, numpy.float64 {sym} ({name})",
            single["numpy"],
            None,
            f"(numpy scalar / float: {ratio:.2f}, same run)",
        ),
        _row(f"qpik.ik, batch of {BATCH} ({name}), per pose", tb, ref),
        _row(f"qpik.feasible_intervals ({name})", ti, ref),
    ]


def _row(label: str, t: np.ndarray, ref: str | None, note: str = "") -> Row:
    return Row(label, float(np.median(t)), ref, float(np.percentile(t, 99)), float(t.max()), note)


def _ssik_row(repeat: int) -> Row | None:
    """ssik on fk(q) of the same iiwa configurations (ssik's iiwa14 matches qpik's FK)."""
    try:
        from ssik.prebuilt.kuka import iiwa14_ik
    except ImportError:
        return None
    robot = load_robot("iiwa14")
    q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    T = list(robot.fk(q))
    t = time_calls(cycle(iiwa14_ik.solve, T), max(10, repeat // (10 * BLOCK)), warmup=5, block=BLOCK)
    return _row(SSIK, t, None)


def _locked_rows(repeat: int) -> list[Row]:
    """qpik.ik beside EAIK and ik-geo on iiwa14 poses with joint 3 at :data:`LOCKED` (see the module docstring)."""
    try:
        import ik_geo
        from eaik.IK_DH import DhRobot
    except ImportError as exc:
        print(f"qpik bench analytic: EAIK or ik-geo not installed ({exc}; pip install -e '.[test]'), rows left out")
        return []
    robot = load_robot("iiwa14")
    chain = robot.chain
    q = np.random.default_rng(1).uniform(robot.q_min, robot.q_max, (BATCH, robot.dof))
    q[:, 2] = LOCKED
    T = robot.fk(q)
    par = np.asarray(redundancy_parameter(robot, q)[0])
    bot = DhRobot(np.array(chain.alpha), np.array(chain.a), np.array(chain.d), fixed_axes=[(2, LOCKED)])
    geo = ik_geo.Robot.spherical_two_intersecting(bot.getRemodeled_H().T, bot.getRemodeled_P().T)
    # ik-geo's end effector has the identity rotation at q = 0 and takes the rotation transposed
    zero = np.zeros(robot.dof)
    zero[2] = LOCKED
    R0 = robot.fk(zero)[:3, :3]
    geo_poses = [((t[:3, :3] @ R0.T).T.copy(), t[:3, 3].copy()) for t in T[:POSES]]

    def reached(solutions: list[np.ndarray], pose: np.ndarray) -> tuple[int, int]:
        good = sum(np.abs(robot.fk(x) - pose).max() <= 1e-9 for x in solutions)
        return good, len(solutions)

    counts = {"eaik": [0, 0], "geo": [0, 0], "qpik": [0, 0]}
    for i in range(POSES):
        for key, sols in (
            ("eaik", list(np.asarray(bot.IK(T[i]).Q))),
            ("geo", [np.insert(np.asarray(x), 2, LOCKED) for x, _ in geo.get_ik(*geo_poses[i])]),
            ("qpik", list((s := ik(robot, T[i], float(par[i]))).q[s.valid])),
        ):
            good, total = reached(sols, T[i])
            counts[key][0] += good
            counts[key][1] += total

    def note(key: str) -> str:
        good, total = counts[key]
        return f"({good}/{total} solutions of {POSES} poses reach the pose to 1e-9 by qpik's FK)"

    cases = list(zip(T[:POSES], par[:POSES].tolist()))
    t = time_interleaved(
        {
            "qpik": cycle(lambda c: ik(robot, c[0], c[1]), cases),
            "eaik": cycle(bot.IK, list(T[:POSES])),
            "geo": cycle(lambda c: geo.get_ik(*c), geo_poses),
        },
        max(20, repeat // BLOCK),
        block=BLOCK,
    )
    calls = max(BATCH_CALLS, repeat // 100)
    tb = time_interleaved(
        {
            "qpik": lambda: ik(robot, T, par),
            "eaik": lambda: bot.IK_batched(T, num_worker_threads=EAIK_THREADS),
        },
        calls,
        warmup=1,
    )
    label = "iiwa14 q3 locked: "
    eaik_label, eaik_batch = label + "EAIK IK (6R)", label + f"EAIK batched, {EAIK_THREADS} thr., per pose"
    return [
        _row(label + "qpik.ik, 8 branches", t["qpik"], eaik_label, note("qpik")),
        _row(eaik_label, t["eaik"], None, note("eaik")),
        _row(label + "ik-geo get_ik (6R)", t["geo"], eaik_label, note("geo")),
        _row(label + "qpik.ik batched, per pose", tb["qpik"] / BATCH, eaik_batch),
        _row(eaik_batch, tb["eaik"] / BATCH, None),
    ]
