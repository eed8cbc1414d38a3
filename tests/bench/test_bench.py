"""``qpik bench`` runs every bench and prints every row the README quotes (structure only: no timing is asserted)."""

from __future__ import annotations

import argparse
import importlib
import math
import re

import numpy as np
import pytest
from conftest import LARGE

from qpik.bench import BENCHES, Row, render

EXPECTED = {
    "kinematics": [
        "iiwa14: qpik fk_jacobian (1 q)",
        "iiwa14: pinocchio J + pose",
        "iiwa14: pinocchio J only",
        "iiwa14: mink",
        "panda: qpik batched N=10000, per q",
    ],
    "analytic": [
        "ssik iiwa14_ik.solve (iiwa14)",
        "qpik.ik, 1 pose (nammoto7)",
        "qpik.ik, 1 pose, numpy.float64 δ (nammoto7)",
        "qpik.ik, 1 pose, numpy.float64 ψ (iiwa14)",
        "qpik.feasible_intervals (nammoto7)",
        "qpik.feasible_intervals (iiwa14)",
        "iiwa14 q3 locked: qpik.ik, 8 branches",
        "iiwa14 q3 locked: EAIK IK (6R)",
        "iiwa14 q3 locked: ik-geo get_ik (6R)",
        "KUKA iiwa LBR 7: qpik.ik, 8 branches (srs, ψ)",
        "KUKA iiwa LBR 7: ssik solve (self-motion sampled)",
        "UFactory xArm7: qpik.ik, 8 branches (locked joint, q7)",
        "UFactory xArm7: ssik solve (self-motion sampled)",
        "baxter q1 locked: qpik.ik, 16 slots (certified 1-D search)",
        "baxter q1 locked: ik-geo two_intersecting get_ik (6R, 1-D search by NLopt MLSL)",
        "baxter q1 locked: qpik.feasible_intervals, 16 slots (sampled, not proved)",
        "tiago pro q7 locked: qpik.ik, 16 slots (general 6-R: one eigenproblem)",
        "tiago pro q7 locked: ik-geo gen_six_dof get_ik (6R, 2-D search)",
    ],
    "controller": [
        "no obstacles, hot: mink + osqp (rebuilt each call)",
        "no obstacles, hot: qpik + osqp (persistent, active set reused)",
        "no obstacles, hot: qpik + daqp",
        "no obstacles, hot: placo (pinocchio + qpmad, QP formed each call)",
        "mink + osqp (rebuilt each call)",
        "mink + daqp",
        "qpik + osqp (persistent, active set reused)",
        "qpik + daqp",
        "qpik + proxqp",
        "qpik + quadprog",
        "fold + moving sphere: qpik + osqp",
        "fold + moving sphere: mink + daqp",
    ],
    "ik": [
        "iiwa14: qpik.solve_ik (closed form)",
        "iiwa14: TRAC-IK Speed",
        "iiwa14: mink.solve_ik iterated (daqp)",
        "panda: qpik.solve_ik (Levenberg–Marquardt)",
        "panda: TRAC-IK Speed",
        "zheng7: qpik.solve_ik (Levenberg–Marquardt)",
        "nammoto7: qpik.solve_ik (closed form)",
    ],
    "nlp": [
        "ssik iiwa14_ik.solve (16 ψ × 8 branches)",
        "solve_best margin (level sets), certified (iiwa14)",
        "solve_best margin, method=search, certified (nammoto7)",
        "solve_best manipulability + 2 obstacles (nammoto7)",
        "solve_best margin, batched, per pose (iiwa14)",
        "solve_full, IPOPT (panda)",
        "mink.solve_ik iterated, daqp (zheng7)",
        "solve_best margin, sampled + polished, not certified (baxter, 1-D search)",
        "solve_full margin, IPOPT multi-start (baxter, 1-D search)",
    ],
    "plan": ["DP, 1 obstacle (iiwa14)", "NLP from the DP, 1 obstacle (iiwa14)", "DP, no obstacle (iiwa14)"],
    "batch": [
        "in this process",
        "2 local processes",
        "Dask LocalCluster, 1 worker(s)",
        "Dask LocalCluster, 2 worker(s)",
    ],
    "view": [
        "iiwa14: pose → scene",
        "iiwa14 + ball and table: pose → scene",
        "panda (q7 locked): pose → scene",
        "URDF pybullet kuka_iiwa: pose → scene",
        "URDF pybullet kuka_iiwa, bent: pose → scene",
        "URDF example-robot-data xArm7 (q7 locked, polished): pose → scene",
    ],
}


VIEW_LARGE = (
    "iiwa14 + ball and table",
    "URDF example-robot-data xArm7 (q7 locked, polished)",
    "URDF pybullet kuka_iiwa, bent",
)
"""The view bench's arms dragged with ``QPIK_TESTS_LARGE=1`` only: the first two build functions no other arm of the
bench does (the search among obstacles, a polished closed form), the bent URDF is the URDF's viewer again around
another pose; the drag loop they run is the other arms'."""


@pytest.mark.parametrize("name", BENCHES)
def test_bench_prints_every_row(name, monkeypatch):
    module = importlib.import_module(f"qpik.bench.{name}")
    expected = EXPECTED[name]
    if name == "view":
        pytest.importorskip("viser", reason="viser is not installed (pip install 'qpik[view]')")
        if not LARGE:
            arms = module._arms
            monkeypatch.setattr(module, "_arms", lambda: [arm for arm in arms() if arm[0] not in VIEW_LARGE])
            expected = [label for label in expected if label.split(": pose")[0] not in VIEW_LARGE]
    if name == "analytic" and not LARGE:  # of ssik's arms only the iiwa7 (ssik's solves take milliseconds)
        locked = importlib.import_module("qpik.bench.analytic_locked")
        arms = importlib.import_module("qpik.bench.ssik_arms")
        kept = [arm for arm in arms.seven_r_arms() if arm.name == "KUKA iiwa LBR 7"]
        monkeypatch.setattr(arms, "seven_r_arms", lambda: kept)
        monkeypatch.setattr(locked, "SET_POSES", 1)  # Baxter's sampled sets: seconds a pose
        expected = [label for label in expected if not label.startswith("UFactory xArm7")]
    if name == "nlp" and not LARGE:  # Baxter's sampled solve_best: a second a pose
        searched = module._searched_rows
        monkeypatch.setattr(module, "_searched_rows", lambda n: searched(3))
    if name == "controller" and not LARGE:  # the URDF's rows (not in EXPECTED) in the large run only
        monkeypatch.setattr(module, "LOADED", "pybullet/no such arm")
    args = argparse.Namespace(repeat=20, client="socket") if name == "view" else argparse.Namespace(repeat=100)
    rows = module.run(args)
    labels = [row.label for row in rows]
    for want in expected:
        assert want in labels, f"{name}: no row {want!r}"
    for row in rows:
        assert isinstance(row, Row) and math.isfinite(row.seconds) and row.seconds > 0.0
        assert row.ref is None or row.ref in labels
    text = render(module.TITLE, rows)
    assert all(label in text for label in labels)
    if name == "ik":  # every row gives p95 and the success rate, checked by FK
        assert all("p95" in row.note and "success" in row.note for row in rows)
    if name == "controller":  # the worst step, also as the best of the replays, is printed for every row
        spheres = [row for row in rows if not row.label.startswith("fold")]  # the fold rows: self pairs, below
        assert all("best of 3 replays" in row.note for row in spheres)
        # with obstacles, every row says how often its library's obstacle rows bind
        assert all("binding" in row.note for row in spheres if not row.label.startswith("no obstacles"))
        # the fold rows say what each side computes
        assert all(
            "self pairs" in row.note and "standing still" in row.note for row in rows if row.label.startswith("fold")
        )
    if name == "analytic":  # the numpy scalar rows give their ratio to the float call of the same run
        assert all("numpy scalar / float: " in row.note for row in rows if "numpy.float64" in row.label)
        for arm in (row for row in rows if ": qpik.ik, " in row.label and "ssik's fk" in row.note):  # ssik's arms
            good, total = map(int, re.search(r"\((\d+)/(\d+) solutions", arm.note).groups())
            assert good == total > 0 and "q among them 64/64" in arm.note, (arm.label, arm.note)
        searched = [row for row in rows if row.label.startswith("baxter q1 locked") and "feasible" not in row.label]
        sets = [row for row in rows if row.label.startswith("baxter q1 locked: qpik.feasible_intervals")]
        assert len(sets) == 1 and "no peer computes feasible sets" in sets[0].note
        for row in searched:  # every answer of both searches checked by FK, q's count given
            assert re.search(r"\(\d+/\d+ solutions of 64 poses reach the pose to 1e-9 by qpik's FK; q among", row.note)
        good, total = map(int, re.search(r"\((\d+)/(\d+) solutions", searched[0].note).groups())
        assert good == total > 0 and "q among them 64/64" in searched[0].note  # qpik's search: all, and q every time
        general = [row for row in rows if row.label.startswith("tiago pro q7 locked")]
        for row in general:  # both sides checked by FK; qpik's slots: every one reaches the pose, q every time
            assert re.search(r"\(\d+/\d+ solutions of 64 poses reach the pose to 1e-9 by qpik's FK; q among", row.note)
        good, total = map(int, re.search(r"\((\d+)/(\d+) solutions", general[0].note).groups())
        assert good == total > 0 and "q among them 64/64" in general[0].note
    if name == "view":  # every arm's drag updates were timed, with their p95 against the 50 ms budget
        assert all("p95" in row.note and "/20 ≤ 50 ms" in row.note and "/20 poses reached" in row.note for row in rows)
        assert all("CPU of the update median" in row.note for row in rows)
        # the websocket client received every update: the time to its last message is given for each pose
        assert all("drawing nothing" in row.note and "/20 ≤ 50 ms (" in row.note for row in rows)
        for bent in (row for row in rows if row.label.startswith("URDF pybullet kuka_iiwa, bent")):
            assert "20/20 poses reached" in bent.note  # the bent drag stays in reach
    if name == "plan":  # the planned path passes every check, and the quoted peer says it is quoted
        assert "all checks hold" in rows[1].note and "quoted, not measured" in rows[0].note


def test_placo_peer_steps_toward_the_target_within_its_limits():
    """The placo step of the controller bench is a working controller: from the scene's start, 300 closed-loop
    steps bring the end effector (by qpik's FK) closer to the target, every velocity within the robot's limits."""
    from qpik.bench.controller import DT, _placo_step, scene
    from qpik.robots.loader import load_robot

    robot = load_robot("iiwa14")
    q, target, _ = scene(robot, robot.q_home)
    step = _placo_step(robot, target)
    assert step is not None
    start = np.linalg.norm(robot.fk(q)[:3, 3] - target[:3, 3])
    for _ in range(300):
        v = step(q)
        assert np.all(np.abs(v) <= robot.v_max + 1e-9)
        q = q + v * DT
    assert np.all((q >= robot.q_min - 1e-9) & (q <= robot.q_max + 1e-9))
    assert np.linalg.norm(robot.fk(q)[:3, 3] - target[:3, 3]) < 0.5 * start


def test_a_slower_row_is_called_slower_never_a_fraction_faster():
    """The ratio column compares each row with its reference as the larger over the smaller: a row taking twice its
    reference's time is "2.00x slower", not "0.50x faster"."""
    rows = [Row("ref", 1e-3, None), Row("quick", 0.25e-3, "ref"), Row("slow", 2e-3, "ref"), Row("tie", 1e-3, "ref")]
    lines = render("t", rows).splitlines()[2:]
    assert "4.00x faster than ref" in lines[1]
    assert "2.00x slower than ref" in lines[2] and "faster" not in lines[2]
    assert "1.00x faster than ref" in lines[3]
