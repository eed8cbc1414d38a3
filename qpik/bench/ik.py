r"""Bench: inverse kinematics from random starts — ``qpik.solve_ik`` beside TRAC-IK and mink, same poses, same run.

For each arm, the poses are ``fk(q)`` of configurations drawn uniformly inside the joint
limits (seed 0) and the starts are drawn the same way (seed 1): :data:`POSES` of each, or
half of ``--repeat`` when that is fewer. Every peer solves every pose from the same start;
qpik and TRAC-IK take turns pose by pose (the machine's busy spells fall on both), then mink
solves them in a pass of its own (taking turns with mink, TRAC-IK's wall-clock median grew
several-fold, 0.34 to 1.6 ms on iiwa14, while its CPU time did not); Python's garbage collector
is paused; times are wall clock per solve, failures included. The note also gives
the median CPU time of the process over the solve (every thread: TRAC-IK's two threads both count;
unlike wall clock, it leaves out time spent waiting for a CPU on a busy machine).

- **qpik**: :func:`qpik.solve_ik` with ``tol`` = :data:`TOL` on :math:`\|[p^* - p;\ \log(R^* R^T)]\|_2`
  (one thread; the closed form for ``iiwa14`` and ``nammoto7``, compiled Levenberg–Marquardt with
  restarts for ``zheng7`` and ``panda``; seed = the pose's index).
- **TRAC-IK** (``pytracik``, Beeson & Ames 2015) on the URDF of :meth:`Robot.to_urdf` (its FK is
  first checked against qpik's), Speed mode, timeout :data:`TIMEOUT`, ``eps`` = :data:`TOL`, the
  joint limits set from the robot in double precision (its URDF parser rounds them to float).
  TRAC-IK runs two threads, KDL's Newton with random restarts and an SQP (NLopt), and stops at
  the first answer whose twist error has *every component* below eps (:math:`\|\cdot\|_\infty`).
- **mink** (``mink.solve_ik`` on the MJCF twin, site ``ee``): iterated as an IK solver, a
  FrameTask (costs 1, gain 1) and the ConfigurationLimit at dt = 1 with daqp and damping
  :data:`MINK_DAMPING`; restarts from random configurations when the error falls by less than
  half over :data:`MINK_STALL` steps; the same time budget as TRAC-IK's timeout.

One test of success for all: the configuration is inside the limits and its FK (qpik's) has
:math:`\|e\|_2 \le \sqrt 6` eps — what TRAC-IK's per-component test guarantees in any frame;
qpik and mink stop only at :math:`\|e\|_2 \le` eps. Rows: median, p99 and worst time per
pose; the note gives p95 and the success rate. Targets (issue): success ≥ 99.9 %, median ≤
TRAC-IK's and p95 ≤ 5 ms.
"""

from __future__ import annotations

import argparse
import gc
import math
import sys
import time
from collections.abc import Callable

import numpy as np

from qpik.algebra.lie import pose_error
from qpik.bench import Row, fmt_time
from qpik.core.errors import UnreachableError
from qpik.nlp.ik import CLOSED_FORM_DEFAULT, solve_ik
from qpik.nlp.options import IKOptions
from qpik.robots.loader import load_robot
from qpik.robots.robot import Robot

ARMS = ("iiwa14", "panda", "zheng7", "nammoto7")
POSES = 1000
TOL = 1e-6
"""m and rad: qpik's tol on ‖e‖₂, TRAC-IK's eps on each component of its twist error."""
TITLE = (
    "IK from random starts, per pose: qpik.solve_ik vs TRAC-IK vs mink (same poses and starts, same run; "
    f"success = inside the limits with ‖e‖₂ ≤ √6·{TOL:g} by qpik's FK)"
)
TIMEOUT = 0.005
"""s: TRAC-IK's timeout and mink's budget per pose."""
MINK_DAMPING = 1e-6
MINK_STALL = 8

Solve = Callable[[np.ndarray, np.ndarray, int], np.ndarray | None]


def run(args: argparse.Namespace) -> list[Row]:
    poses = max(10, min(POSES, int(getattr(args, "repeat", 2000)) // 2))
    rows: list[Row] = []
    for name in ARMS:
        rows += _arm_rows(load_robot(name), poses)
    return rows


def _arm_rows(robot: Robot, count: int) -> list[Row]:
    q_goal = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (count, robot.dof))
    starts = np.random.default_rng(1).uniform(robot.q_min, robot.q_max, (count, robot.dof))
    targets = robot.fk(q_goal)
    name = robot.name
    closed = robot.closed_form in CLOSED_FORM_DEFAULT
    qpik_label = f"{name}: qpik.solve_ik ({'closed form' if closed else 'Levenberg–Marquardt'})"
    peers: dict[str, Solve] = {qpik_label: _qpik(robot)}
    notes: dict[str, str] = {qpik_label: f"1 thread, tol {TOL:g} on ‖e‖₂"}
    tracik, tracik_note = _tracik(robot)
    tracik_label = f"{name}: TRAC-IK Speed"
    if tracik is not None:
        peers[tracik_label] = tracik
    notes[tracik_label] = tracik_note
    mink_label = f"{name}: mink.solve_ik iterated (daqp)"
    peers[mink_label] = _mink(robot)
    notes[mink_label] = (
        f"1 thread, dt = 1, damping {MINK_DAMPING:g}, random restarts on stall, {TIMEOUT * 1e3:g} ms budget"
    )
    for solve in peers.values():  # warm up (compilation, first calls)
        solve(targets[0], starts[0], 0)
    times = {label: np.empty(count) for label in peers}
    cpu = {label: np.empty(count) for label in peers}
    ok = {label: np.zeros(count, bool) for label in peers}
    enabled = gc.isenabled()
    gc.disable()
    try:
        for group in ([label for label in peers if label != mink_label], [mink_label]):
            for i in _progress(range(count), f"{name}, {len(group)} peer(s)"):
                for label in group:
                    t0, c0 = time.perf_counter(), time.process_time()
                    q = peers[label](targets[i], starts[i], i)
                    times[label][i], cpu[label][i] = time.perf_counter() - t0, time.process_time() - c0
                    ok[label][i] = q is not None and _reached(robot, q, targets[i])
    finally:
        if enabled:
            gc.enable()
    rows = []
    ref = tracik_label if tracik is not None else None
    for label in peers:
        t, good = times[label], ok[label]
        note = (
            f"(p95 {fmt_time(float(np.percentile(t, 95))).strip()}; success {100 * good.mean():.1f} % "
            f"({good.sum()}/{count}); CPU median {fmt_time(float(np.median(cpu[label]))).strip()}; {notes[label]})"
        )
        rows.append(
            Row(
                label,
                float(np.median(t)),
                ref if label == qpik_label else None,
                float(np.percentile(t, 99)),
                float(t.max()),
                note,
            )
        )
    if tracik is None:
        rows.append(Row(tracik_label, math.nan, note=f"({tracik_note})"))
    return rows


def _reached(robot: Robot, q: np.ndarray, target: np.ndarray) -> bool:
    """Inside the limits and ‖e‖₂ ≤ √6·TOL, by qpik's FK."""
    return bool(robot.within_limits(q)) and float(np.linalg.norm(pose_error(target, robot.fk(q)))) <= math.sqrt(6) * TOL


def _qpik(robot: Robot) -> Solve:
    def solve(target: np.ndarray, q0: np.ndarray, i: int) -> np.ndarray | None:
        try:
            return solve_ik(robot, target, q0, tol=TOL, options=IKOptions(seed=i))
        except UnreachableError:
            return None

    return solve


def _tracik(robot: Robot) -> tuple[Solve | None, str]:
    """TRAC-IK on the URDF of the arm, or None and why not."""
    try:
        import pytracik
    except ImportError:
        return None, "pytracik not installed (pip install -e '.[test]'): row left out"
    from scipy.spatial.transform import Rotation

    solver = pytracik.TRAC_IK("base", "ee", robot.to_urdf(), TIMEOUT, TOL, pytracik.SolveType.Speed)
    pytracik.set_joint_limits(solver, robot.q_min, robot.q_max)
    Q = np.random.default_rng(2).uniform(robot.q_min, robot.q_max, (100, robot.dof))
    fk_gap = max(float(np.abs(np.asarray(pytracik.fk(solver, q)) - robot.fk(q)).max()) for q in Q)
    if fk_gap > 1e-9:
        return None, f"TRAC-IK's FK of the URDF differs from qpik's by {fk_gap:.1e}: row left out"

    def solve(target: np.ndarray, q0: np.ndarray, i: int) -> np.ndarray | None:
        x, y, z, w = Rotation.from_matrix(target[:3, :3]).as_quat()
        r = pytracik.ik(solver, q0, *target[:3, 3], x, y, z, w)
        return np.asarray(r[1:]) if r[0] >= 0 else None

    note = (
        f"2 threads, eps {TOL:g} on each twist component, timeout {TIMEOUT * 1e3:g} ms; "
        f"URDF FK = qpik's to {fk_gap:.0e}"
    )
    return solve, note


def _mink(robot: Robot) -> Solve:
    """mink.solve_ik iterated on the MJCF twin (module docstring)."""
    import mink
    from mink.exceptions import NoSolutionFound

    model = robot.mj_model()
    conf = mink.Configuration(model)
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0, gain=1.0)
    limits = [mink.ConfigurationLimit(model)]

    def solve(target: np.ndarray, q0: np.ndarray, i: int) -> np.ndarray | None:
        rng = np.random.default_rng(i)
        task.set_target(mink.SE3.from_matrix(target))
        deadline = time.perf_counter() + TIMEOUT
        q, previous, k = q0.copy(), math.inf, 0
        while time.perf_counter() < deadline:
            err = float(np.linalg.norm(pose_error(target, robot.fk(q))))
            if err <= TOL:
                return q
            if k % MINK_STALL == 0:
                if err > 0.5 * previous:  # stalled: restart
                    q, previous, k = rng.uniform(robot.q_min, robot.q_max), math.inf, 0
                    continue
                previous = err
            conf.update(q)
            try:
                v = mink.solve_ik(conf, [task], 1.0, solver="daqp", damping=MINK_DAMPING, limits=limits)
            except NoSolutionFound:
                q, previous, k = rng.uniform(robot.q_min, robot.q_max), math.inf, 0
                continue
            conf.integrate_inplace(v, 1.0)
            q, k = conf.q.copy(), k + 1
        return None

    return solve


def _progress(items: range, name: str):
    if not sys.stderr.isatty():
        return items
    from tqdm import tqdm

    return tqdm(items, desc=f"qpik bench ik: {name}", unit="pose", leave=False)
