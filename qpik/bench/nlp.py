"""Bench: :func:`qpik.solve_best` beside ssik's full sweep, and the full-joint NLP beside mink's iterated IK.

Poses are ``fk(q)`` of configurations drawn uniformly inside the joint limits (seed 0).

Part 1, per ``solve_best`` call (both closed-form arms), median and p95 over the poses:

- ``ssik iiwa14_ik.solve``: ssik's full solve on the same iiwa poses — a sweep of 16 arm
  angles × 8 branches (every solution it enumerates), by its compiled path (the default), the reference of
  the ratios; and the same by its Python path (``native=False``, fewer poses);
- ``solve_best margin``: the joint-limit margin by the default method, the exact super-level sets
  (:mod:`qpik.nlp.levelset`: the search and its proof in one; "certified" counts the poses proved);
- ``solve_best margin, method=search``: the same problem by sampling and polish, with its Taylor-model
  certificate and without;
- ``solve_best margin, method=ipopt``: the same problem with IPOPT from every feasible interval
  (the alternative the search was measured against; fewer poses);
- ``solve_best manipulability + 2 obstacles``: −log m with two spheres as clearance constraints
  (no certificate exists for −log m: the flag stays off at no cost);
- ``solve_best margin, batched``: :data:`BATCH` poses in one call by the default method, time per pose
  (and poses per second), the median of :data:`BATCH_CALLS` calls after a first one.

The certificate's success rate and its median cell count are in the notes.

Part 2, the full-joint NLP on ``zheng7`` and ``panda`` (no closed form): the same poses and the
same starts (``q0``, then the seeded random starts of :func:`qpik.nlp.solve_full`) for both
peers, each stopping at its first start that reaches the pose to 1e-9:

- ``solve_full`` (IPOPT, exact derivatives, pose as an equality, joint limits as bounds; self-collision off, as mink
  has none here);
- ``mink.solve_ik`` iterated on the MJCF twin (FrameTask gain 1, dt = 1, daqp, ConfigurationLimit)
  until the pose error is below 1e-9 or :data:`MINK_ITERS` iterations, per start (a start whose QP
  has no solution counts as failed).

Rows: seconds per pose (median; p95 in the note) and the success rate over the poses.

Part 3, an arm of the 1-D search (example-robot-data's Baxter, right arm, q1 locked), the margin on the same poses:

- ``solve_best`` (:mod:`qpik.nlp.best_sampled`: every slot sampled along q1, the best minima narrowed and polished by
  IPOPT; not certified);
- ``solve_full`` (IPOPT from the search's branches at eight values of q1, then seeded random starts: the best of
  :class:`~qpik.nlp.options.FullOptions`' default 8 starts that reach the pose).

The note counts the poses where each answer's margin is the larger by more than 1e-9.
"""

from __future__ import annotations

import argparse

import numpy as np

from qpik.algebra.lie import pose_error
from qpik.bench import Row
from qpik.geometry.shapes import Sphere
from qpik.nlp import solve_best, solve_full
from qpik.nlp.full import REACHED
from qpik.nlp.options import BestOptions, FullOptions
from qpik.robots.loader import load_robot
from qpik.scene import Scene

TITLE = "NLP: best branch and δ/ψ (solve_best) and the full-joint NLP"
SSIK = "ssik iiwa14_ik.solve (16 ψ × 8 branches)"
SSIK_PYTHON = "ssik iiwa14_ik.solve(native=False), its Python path"
BATCH = 200
"""Most poses of the batched row (fewer with a small ``--repeat``)."""
BATCH_CALLS = 3
"""Timed calls of the batched row (its median)."""
MINK_ITERS = 200
MAX_STARTS = 30


def run(args: argparse.Namespace) -> list[Row]:
    import time

    repeat = max(5, int(getattr(args, "repeat", 2000)) // 20)
    batch = min(BATCH, 10 * repeat)
    rows: list[Row] = []
    ssik = _ssik_rows(repeat)
    rows += ssik
    ref = ssik[0] if ssik else None
    obstacles = [Sphere((0.45, 0.3, 0.6), 0.08), Sphere((0.3, -0.4, 0.4), 0.08)]
    for name in ("iiwa14", "nammoto7"):
        robot = load_robot(name)
        T = robot.fk(np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (max(repeat, batch), robot.dof)))
        r = SSIK if name == "iiwa14" and ref is not None else None
        manipulability = {"objective": "manipulability", "obstacles": obstacles}
        cases = [
            ("margin (level sets), certified", {}, BestOptions(), repeat),
            ("margin, method=search, certified", {}, BestOptions(method="search"), repeat),
            ("margin, method=search, no certificate", {}, BestOptions(method="search", certify=False), repeat),
            ("margin, method=ipopt", {}, BestOptions(certify=False, method="ipopt"), max(3, repeat // 10)),
            ("manipulability + 2 obstacles", manipulability, BestOptions(), repeat),
        ]  # fmt: skip
        for label, kw, options, n in cases:
            kw = {"objective": "margin", **kw, "options": options}
            solve_best(robot, T[0], **kw)  # builds and compiles
            times, cert = [], []
            for k in range(n):
                t0 = time.perf_counter()
                res = solve_best(robot, T[k], **kw)
                times.append(time.perf_counter() - t0)
                cert.append(res.certified)
            t = np.array(times)
            note = f"p95 {_ms(np.percentile(t, 95))}"
            if options.certify and label.startswith("margin"):
                note += f"; certified {np.mean(cert):.0%} of {n}"
            rows.append(Row(f"solve_best {label} ({name})", float(np.median(t)), r, note=note))
        solve_best(robot, T[:batch])  # the first large call allocates and compiles
        calls = []
        for _ in range(BATCH_CALLS):
            t0 = time.perf_counter()
            res = solve_best(robot, T[:batch])
            calls.append((time.perf_counter() - t0) / batch)
        per = float(np.median(calls))
        note = f"{batch} poses in one call (median of {BATCH_CALLS} calls): {1.0 / per:.0f} poses/s"
        note += f", certified {np.mean(res.certified):.0%}"
        rows.append(Row(f"solve_best margin, batched, per pose ({name})", per, r, note=note))
    for name in ("zheng7", "panda"):
        rows += _full_rows(name, max(10, repeat))
    return rows + _searched_rows(max(5, repeat // 5))


def _ms(s: float) -> str:
    return f"{s * 1e3:.3g} ms"


def _ssik_rows(repeat: int) -> list[Row]:
    """ssik's sweep on the same iiwa poses: its default (compiled) path, the reference, and its Python path
    (``native=False``, on fewer poses)."""
    import time

    try:
        from ssik.prebuilt.kuka import iiwa14_ik
    except ImportError:
        return []
    robot = load_robot("iiwa14")
    T = robot.fk(np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (repeat, robot.dof)))
    rows = []
    for label, native, n in ((SSIK, True, repeat), (SSIK_PYTHON, False, max(3, repeat // 10))):
        iiwa14_ik.solve(T[0], native=native)
        times = []
        for k in range(n):
            t0 = time.perf_counter()
            iiwa14_ik.solve(T[k], native=native)
            times.append(time.perf_counter() - t0)
        t = np.array(times)
        rows.append(Row(label, float(np.median(t)), None if native else SSIK, note=f"p95 {_ms(np.percentile(t, 95))}"))
    return rows


def _full_rows(name: str, n: int) -> list[Row]:
    """solve_full and mink's iterated solve_ik on the same poses and starts."""
    import time

    robot = load_robot(name)
    rng = np.random.default_rng(0)
    Q = rng.uniform(robot.q_min, robot.q_max, (n, robot.dof))
    starts = rng.uniform(robot.q_min, robot.q_max, (n, robot.dof))
    T = robot.fk(Q)
    mink_solve = _mink(robot)
    scene = Scene.of(robot, self_collision=False)
    solve_full(scene, T[0], options=FullOptions(q0=starts[0]))
    out = {"qpik": ([], []), "mink": ([], [])}
    for k in range(n):
        t0 = time.perf_counter()
        res = solve_full(scene, T[k], options=FullOptions(q0=starts[k], seed=k, max_starts=MAX_STARTS))
        out["qpik"][0].append(time.perf_counter() - t0)
        out["qpik"][1].append(res.status == "optimal" and robot.within_limits(res.q))
        t0 = time.perf_counter()
        ok = mink_solve(T[k], starts[k], k)
        out["mink"][0].append(time.perf_counter() - t0)
        out["mink"][1].append(ok)
    rows = []
    labels = {"qpik": f"solve_full, IPOPT ({name})", "mink": f"mink.solve_ik iterated, daqp ({name})"}
    for peer in ("mink", "qpik"):
        t, ok = np.array(out[peer][0]), np.array(out[peer][1])
        note = f"p95 {_ms(np.percentile(t, 95))}; reached 1e-9 on {ok.mean():.1%} of {n} poses"
        rows.append(Row(labels[peer], float(np.median(t)), labels["mink"] if peer == "qpik" else None, note=note))
    return rows


def _searched_rows(n: int) -> list[Row]:
    """solve_best (sampled) and solve_full on ``n`` poses of the 1-D search's arm, the margin (module docstring)."""
    import time

    from qpik.bench.analytic_locked import SEARCHED
    from qpik.robots.packaged import packaged_model

    robot = load_robot(str(packaged_model(SEARCHED.key)), **SEARCHED.options)
    T = robot.fk(np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (n, robot.dof)))
    solve_best(robot, T[0]), solve_full(robot, T[0], "margin")  # builds and compiles
    times, margins = {"best": [], "full": []}, {"best": [], "full": []}
    for pose in T:
        for peer, solve in (("best", solve_best), ("full", solve_full)):
            t0 = time.perf_counter()
            res = solve(robot, pose, "margin")
            times[peer].append(time.perf_counter() - t0)
            margins[peer].append(-res.objective if res.status == "optimal" else -np.inf)
    labels = {"full": "solve_full margin, IPOPT multi-start (baxter, 1-D search)",
              "best": "solve_best margin, sampled + polished, not certified (baxter, 1-D search)"}  # fmt: skip
    rows = []
    for peer, other in (("full", "best"), ("best", "full")):
        t, m, o = np.array(times[peer]), np.array(margins[peer]), np.array(margins[other])
        note = f"p95 {_ms(np.percentile(t, 95))}; margin larger than {other}'s on {int((m > o + 1e-9).sum())} of {n}"
        rows.append(Row(labels[peer], float(np.median(t)), labels["full"] if peer == "best" else None, note=note))
    return rows


def _mink(robot):
    """``solve(T, q0, seed) -> bool``: mink.solve_ik iterated from q0, then from the same seeded random starts."""
    import mink

    model = robot.mj_model()
    conf = mink.Configuration(model)
    task = mink.FrameTask("ee", "site", position_cost=1.0, orientation_cost=1.0, gain=1.0)
    limits = [mink.ConfigurationLimit(model)]

    def attempt(T: np.ndarray, q0: np.ndarray) -> bool:
        conf.update(q0)
        for _ in range(MINK_ITERS):
            if np.linalg.norm(pose_error(T, robot.fk(conf.q))) < REACHED:
                return True
            try:
                v = mink.solve_ik(conf, [task], 1.0, solver="daqp", limits=limits)
            except mink.NoSolutionFound:  # the attempt fails; the next start follows
                return False
            conf.integrate_inplace(v, 1.0)
        return bool(np.linalg.norm(pose_error(T, robot.fk(conf.q))) < REACHED)

    def solve(T: np.ndarray, q0: np.ndarray, seed: int) -> bool:
        task.set_target(mink.SE3.from_matrix(T))
        if attempt(T, q0):
            return True
        rng = np.random.default_rng(seed)
        return any(attempt(T, rng.uniform(robot.q_min, robot.q_max)) for _ in range(MAX_STARTS - 1))

    return solve
