"""QP solvers: on QPs recorded from controller episodes, every backend agrees with daqp (via qpsolvers) to 1e-6."""

from __future__ import annotations

import sys

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_limits import D_SAFE, scene

import qpik
from qpik.control import Controller, RowLimit, VelocityLimit, get_solver
from qpik.control.limits_motion import AccelerationLimit, JerkLimit
from qpik.control.qp import QP
from qpik.control.solvers import available
from qpik.control.solvers.osqp import REUSED, polish
from qpik.control.solvers.qpsolvers import QpsolversSolver
from qpik.core.errors import SolverError
from qpik.geometry.shapes import Sphere

# --dist loadgroup: one worker runs the whole module, so its module- and session-scoped fixtures are built once
pytestmark = pytest.mark.xdist_group("control_solvers")

# tolerances that make the interior-point backends accurate to ~1e-9 (proxqp: its own defaults)
OPTIONS = {
    "clarabel": {"tol_gap_abs": 1e-11, "tol_gap_rel": 1e-11, "tol_feas": 1e-11},
    "piqp": {"eps_abs": 1e-12, "eps_rel": 1e-12, "eps_duality_gap_abs": 1e-12, "eps_duality_gap_rel": 1e-12},
}
SOLVERS = ("osqp", "daqp", "quadprog", "proxqp", "clarabel", "piqp")  # "daqp", "proxqp": our direct calls


@pytest.fixture(scope="module")
def recorded():
    """QPs of real control steps: reach/track with obstacles, starts past limits and inside d_s."""
    rng = np.random.default_rng(99)
    runs = []
    for name in ("iiwa14", "panda"):
        robot = qpik.load_robot(name)
        for ep in range(6):
            q = rng.uniform(robot.q_min + 0.02, robot.q_max - 0.02)
            obstacles = scene(robot, q, rng)
            if ep == 1:  # a sphere inside d_s of the longest link
                seg = robot.capsule_segments(q)
                c = int(np.argmax(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)))
                obstacles.append(Sphere(seg[c].mean(0) + np.array([0, 0, robot.capsule_radii[c] + 0.055]), 0.05))
            if ep == 2:  # past a position limit
                q[3] = robot.q_max[3] + 0.05
            ctrl = Controller.for_robot(robot, obstacles=obstacles, dt=0.01, d_safe=D_SAFE)
            ctrl.frame_task.set_target(robot.fk(rng.uniform(robot.q_min, robot.q_max)))
            qps = []
            for _ in range(40):
                q = q + ctrl.step(q) * ctrl.dt
                qps.append((ctrl.assembler.qp.copy(), ctrl.last.relaxation))
            runs.append(qps)
    return runs


def test_recorded_qps_are_interesting(recorded):
    qps = [qp for run in recorded for qp, _ in run]
    assert any(relaxed for run in recorded for _, relaxed in run)
    active_rows = sum(bool(np.isfinite(qp.l).any()) for qp in qps)
    separating = sum(bool((qp.l > 0).any()) for qp in qps)
    assert active_rows > 50 and separating > 5  # damper rows present in many steps


@pytest.mark.parametrize("name", SOLVERS)
def test_solvers_agree_with_daqp(recorded, name):
    if name not in available():
        pytest.skip(f"{name} not installed")
    ref = QpsolversSolver("daqp")  # reference: DAQP through qpsolvers' own conversion
    worst = 0.0
    for run in recorded:
        solver = get_solver(name, **OPTIONS.get(name, {}))  # persistent per run, as in a controller
        for qp, _ in run:  # relaxed steps included: damper rows pinned at l = 0 from opposite sides
            want = ref.solve(qp)
            got = solver.solve(qp)
            assert want.found, want.status
            assert qp.violation(want.x) < 1e-9
            assert got.found, got.status
            worst = max(worst, float(np.abs(got.x - want.x).max()))
    assert worst < 1e-6, worst


def test_osqp_reuses_the_active_set_and_stays_exact(recorded):
    """Most steps of a run are answered from the previous step's active set without ADMM, and the answer is
    daqp's; fed the QPs of every run back to back and in reverse (each start's active set unrelated to the
    previous QP's), it is still daqp's, through ADMM where the reused guess fails."""
    ref = QpsolversSolver("daqp")
    for qps in ([qp for qp, _ in run] for run in recorded), [[qp for run in recorded for qp, _ in run[::-1]]]:
        for run in qps:
            solver = get_solver("osqp")
            reused = 0
            for qp in run:
                want, got = ref.solve(qp), solver.solve(qp)
                assert got.found, got.status
                assert np.abs(got.x - want.x).max() < 1e-6
                reused += got.status == REUSED
            assert len(run) // 2 <= reused < len(run), (reused, len(run))  # the first step runs ADMM


def test_proxqp_reports_an_infeasible_qp_then_solves_the_next(recorded):
    """An infeasible QP (a row v_1 ≥ 10 rad/s beyond the box) gives no solution, not an
    iterate; the same solver object then answers a feasible QP as daqp does."""
    pytest.importorskip("proxsuite")
    solver = get_solver("proxqp")
    qp = recorded[0][5][0].copy()
    bad = qp.copy()
    bad.A[0], bad.l[0], bad.u[0] = np.eye(qp.n)[0], 10.0, np.inf
    assert not (bad.lb[0] <= 10.0 <= bad.ub[0])
    got = solver.solve(bad)
    assert not got.found and got.x is None
    got = solver.solve(qp)
    assert got.found
    np.testing.assert_allclose(got.x, QpsolversSolver("daqp").solve(qp).x, atol=1e-6)


def test_proxqp_without_proxsuite_is_a_solver_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "proxsuite", None)  # import proxsuite raises ImportError
    monkeypatch.delitem(sys.modules, "qpik.control.solvers.proxqp", raising=False)
    with pytest.raises(SolverError, match="proxsuite"):
        get_solver("proxqp")


def _stacked(qp):
    """Ā = [I; A], lo, hi of a QP, as OSQPSolver hands them to polish."""
    return np.vstack((np.eye(qp.n), qp.A)), np.concatenate((qp.lb, qp.l)), np.concatenate((qp.ub, qp.u))


def _guess(qp, want, guess):
    """The start (x, y) of polish for ``guess``: "none" (x = 0, no row active), or "every bound met" at the
    solution ``want`` (x = want, y = -1 / +1 on the rows at their lower / upper bound to 1e-9)."""
    Abar, lo, hi = _stacked(qp)
    if guess == "none":
        return np.zeros(qp.n), np.zeros(len(lo))
    z = Abar @ want
    return want, np.where(np.abs(z - lo) < 1e-9, -1.0, np.where(np.abs(hi - z) < 1e-9, 1.0, 0.0))


@pytest.mark.parametrize("guess", ("none", "every bound met"))
def test_polish_completes_any_guess_exactly(recorded, guess):
    """polish is exact from any active-set guess, not only ADMM's: from none (every active
    constraint must enter by a dual active-set step) and from every bound met at daqp's
    solution (duplicate and weakly active rows included: linearly dependent guesses)."""
    ref = QpsolversSolver("daqp")
    steps_needed = 0
    for run in recorded:
        for qp, _ in run:
            want = ref.solve(qp).x
            Abar, lo, hi = _stacked(qp)
            x, y = _guess(qp, want, guess)
            got = polish(qp.P, qp.c, Abar, lo, hi, (x, y), max_steps=100)
            assert got is not None
            np.testing.assert_allclose(got, want, atol=1e-8)
            steps_needed += polish(qp.P, qp.c, Abar, lo, hi, (np.zeros(qp.n), y), max_steps=0) is None
    assert guess != "none" or steps_needed > 50  # the cold start really exercised the steps


@pytest.mark.parametrize("guess", ("none", "every bound met"))
def test_compiled_polish_equals_daqp(recorded, guess):
    """polish.c (the controller's path with a compiler) from the same guesses: daqp's answer to 1e-8,
    and no answer exactly where the numpy polish has none (a bound on the steps)."""
    from qpik.control.solvers.osqp import _compiled_polish

    compiled = _compiled_polish()
    if compiled is None:
        pytest.skip("no C compiler or Python headers (QPIK_NATIVE=0): the numpy polish is the only one")
    ref = QpsolversSolver("daqp")
    for run in recorded:
        for qp, _ in run:
            want = ref.solve(qp).x
            Abar, lo, hi = _stacked(qp)
            x, y = _guess(qp, want, guess)
            got = compiled(qp.P, qp.c, qp.A, qp.lb, qp.ub, qp.l, qp.u, x, y, 1e-9, 100)
            assert got is not None
            np.testing.assert_allclose(got, want, atol=1e-8)
            none = polish(qp.P, qp.c, Abar, lo, hi, (np.zeros(qp.n), y), max_steps=0) is None
            cold = compiled(qp.P, qp.c, qp.A, qp.lb, qp.ub, qp.l, qp.u, np.zeros(qp.n), y, 1e-9, 0)
            assert none == (cold is None)


def test_compiled_polish_reads_the_qp_in_any_array_layout(recorded):
    """polish.c reads the QP's own arrays (box and rows apart) in any memory layout, or as lists: the same answer
    to the last bit, the numpy polish's to 1e-8 from the same guess; an array of the wrong size is a ValueError."""
    from qpik.control.solvers.osqp import _compiled_polish

    compiled = _compiled_polish()
    if compiled is None:
        pytest.skip("no C compiler or Python headers (QPIK_NATIVE=0): the numpy polish is the only one")
    ref = QpsolversSolver("daqp")
    compared = 0
    for run in recorded[::3]:
        for qp, _ in run[::4]:
            Abar, lo, hi = _stacked(qp)
            x, y = _guess(qp, ref.solve(qp).x, "every bound met")
            want = polish(qp.P, qp.c, Abar, lo, hi, (x, y), max_steps=100)
            got = compiled(qp.P, qp.c, qp.A, qp.lb, qp.ub, qp.l, qp.u, x, y, 1e-9, 100)
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-8)
            other = (np.asfortranarray(qp.P), qp.c.tolist(), np.asfortranarray(qp.A), qp.lb[::-1].copy()[::-1],
                     qp.ub.tolist(), np.repeat(qp.l, 2)[::2], qp.u)  # fmt: skip
            assert np.array_equal(compiled(*other, x, y, 1e-9, 100), got)
            compared += 1
    assert compared > 10
    qp = recorded[0][0][0]
    with pytest.raises(ValueError, match="A must have"):
        compiled(qp.P, qp.c, qp.A[:-1], qp.lb, qp.ub, qp.l, qp.u, np.zeros(qp.n), np.zeros(qp.n + len(qp.l)), 1e-9, 9)


def test_polish_rejects_an_infeasible_qp():
    robot_n = 3
    A = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])  # v_1 ≥ 1 and v_1 ≤ -1
    Abar = np.vstack((np.eye(robot_n), A))
    lo = np.r_[-np.ones(robot_n) * 5, 1.0, -np.inf]
    hi = np.r_[np.ones(robot_n) * 5, np.inf, -1.0]
    assert polish(np.eye(robot_n), np.zeros(robot_n), Abar, lo, hi, (np.zeros(robot_n), np.zeros(len(lo)))) is None


class _Impossible(RowLimit):
    """v_1 ≥ 10 rad/s (``upper=False``, relaxable) or v_1 ≤ −10 rad/s (``upper=True``, not relaxed):
    conflicts with any velocity limit below 10 rad/s."""

    name = "impossible"

    def __init__(self, upper: bool):
        self.upper = upper

    def size(self, robot):
        return 1

    def row_names(self, robot):
        return ["impossible"]

    def expr(self, s, p, lb, ub):
        A = ca.SX.zeros(1, s.n)
        A[0, 0] = 1.0
        if self.upper:
            return A, ca.SX(-np.inf), ca.SX(-10.0)
        return A, ca.SX(10.0), ca.SX(np.inf)


@pytest.mark.parametrize("name", ("osqp", "daqp", "quadprog", "proxqp"))
def test_failed_solve_returns_safe_velocity(name):
    robot = qpik.load_robot("iiwa14")
    tasks = Controller.for_robot(robot, target=robot.fk(robot.q_home)).tasks
    q = robot.q_home + 0.1
    relaxed = Controller(robot, tasks, [VelocityLimit(), _Impossible(upper=False)], solver=name)
    v = relaxed.step(q)
    # v_1 ≥ 10 k is met for k ≤ v_max / 10 = 0.148 (iiwa14: 1.48 rad/s): bisection finds 9/64, kept × 15/16
    kept = 9 / 64 * 15 / 16
    assert relaxed.last.relaxation == 1 - kept and relaxed.last.status == "ok"
    free = Controller(robot, tasks, [VelocityLimit()], solver=name).step(q)
    if free[0] >= 10 * kept:
        np.testing.assert_allclose(v, free, atol=1e-9)
    else:
        assert abs(v[0] - 10 * kept) < 1e-7
    ctrl = Controller(robot, tasks, [VelocityLimit(), _Impossible(upper=True)], solver=name)
    v = ctrl.step(q)
    assert ctrl.last.status == "failed"
    np.testing.assert_array_equal(v, np.zeros(7))
    strict = Controller(robot, tasks, [VelocityLimit(), _Impossible(upper=True)], solver=name, raise_on_failure=True)
    with pytest.raises(SolverError):
        strict.step(q)


class _Demands(RowLimit):
    """Two separating rows: v_1 ≥ 10 rad/s, marked inside its safety distance (a recovery, impossible), and
    v_2 ≥ 1 rad/s, not (an escape that can be met)."""

    name = "demands"

    def size(self, robot):
        return 2

    def row_names(self, robot):
        return ["recovery", "escape"]

    def expr(self, s, p, lb, ub):
        A = ca.SX.zeros(2, s.n)
        A[0, 0], A[1, 1] = 1.0, 1.0
        return A, ca.vertcat(10.0, 1.0), ca.SX.zeros(2) + np.inf

    def recovery_expr(self, s, p):
        return ca.vertcat(10.0, 0.0)


def test_conflicting_rows_relax_the_recovery_first():
    """The row already inside its safety distance gives way; the escape keeps its whole demand (a common
    fraction would have cut it to 0.148)."""
    robot = qpik.load_robot("iiwa14")
    tasks = Controller.for_robot(robot, target=robot.fk(robot.q_home)).tasks
    ctrl = Controller(robot, tasks, [VelocityLimit(), _Demands()])
    v = ctrl.step(robot.q_home)
    assert ctrl.last.status == "ok" and 0.0 < ctrl.last.relaxation < 1.0
    assert v[1] >= 1.0 - 1e-9
    assert v[0] >= 10.0 * (1.0 - ctrl.last.relaxation) - 1e-9


def test_failed_solve_brakes_at_the_acceleration_and_jerk_limits():
    """A failed step under motion limits returns the command nearest 0 in the caps' box: the arm, moving, brakes
    at the acceleration limit (v = 0 at once would break it); the acceleration and jerk stay in their limits."""
    robot = qpik.load_robot("iiwa14")
    tasks = Controller.for_robot(robot, target=robot.fk(robot.q_home)).tasks
    dt = 1e-3
    moving = np.linspace(-1.0, 1.0, 7)  # rad/s, every joint moving (one at rest)
    acc, jerk = AccelerationLimit(), JerkLimit()
    ctrl = Controller(robot, tasks, [VelocityLimit(), acc, jerk, _Impossible(upper=True)], dt=dt)
    acc.reset(moving)
    jerk.reset(moving, moving)
    v = ctrl.step(robot.q_home + 0.1)
    assert ctrl.last.status == "failed"
    a_step, j_step = robot.a_max * dt, robot.j_max * dt * dt  # the most a command may change (steady before)
    np.testing.assert_allclose(np.abs(v), np.maximum(np.abs(moving) - np.minimum(a_step, j_step), 0.0), atol=1e-12)
    assert np.all(np.abs(v - moving) <= a_step * (1 + 1e-12))  # acceleration
    assert np.all(np.abs(v - moving) <= j_step * (1 + 1e-12))  # jerk
    assert np.all(np.sign(v) * np.sign(moving) >= 0)  # toward rest, never beyond it


def test_conflicting_rows_of_a_moving_arm_brake_without_yielding():
    """An arm moving faster than its acceleration limit can stop in one step (its caps' box excludes 0 for
    every moving joint), with a separating row it cannot meet: the row is relaxed and the joints it does not
    move brake at their acceleration limit (the yielding QP's pull toward the bound nearer 0), but no joint is
    past a position limit, so the status is not "yielding"."""
    robot = qpik.load_robot("iiwa14")
    tasks = Controller.for_robot(robot, target=robot.fk(robot.q_home)).tasks
    dt = 1e-3
    moving = np.linspace(1.0, -1.0, 7) + 0.05  # rad/s, every joint moving (joint 1 toward the row)
    acc = AccelerationLimit()
    ctrl = Controller(robot, tasks, [VelocityLimit(), acc, _Impossible(upper=False)], dt=dt)
    acc.reset(moving)
    v = ctrl.step(robot.q_home + 0.1)
    assert ctrl.last.status == "ok" and 0.0 < ctrl.last.relaxation < 1.0
    a_step = robot.a_max * dt
    assert np.all(np.abs(v[1:]) <= np.abs(moving[1:]) - 0.9 * a_step[1:])  # the tasks pull a little against it
    assert np.all(np.sign(v) == np.sign(moving))
    assert v[0] >= 10.0 * (1.0 - ctrl.last.relaxation) - 1e-9


def test_unknown_solver():
    with pytest.raises(SolverError, match="available"):
        get_solver("no-such-solver")


@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 12))
@settings(max_examples=60, deadline=None)
def test_daqp_takes_absent_bounds_as_infinite(seed, rows):
    """The direct DAQP call hands ±inf (an absent bound) to DAQP as it is: on random strictly convex QPs with
    absent bounds (each bound absent with probability 0.4) its answer is quadprog's, through qpsolvers."""
    rng = np.random.default_rng(seed)
    n = 7
    M = rng.normal(size=(n, n))
    lo, hi = rng.uniform(-2.0, 0.0, n + rows), rng.uniform(0.0, 2.0, n + rows)
    lo[rng.random(n + rows) < 0.4], hi[rng.random(n + rows) < 0.4] = -np.inf, np.inf
    qp = QP(
        M @ M.T + 0.1 * np.eye(n),
        5.0 * rng.normal(size=n),
        rng.normal(size=(rows, n)),
        lo[n:],
        hi[n:],
        lo[:n],
        hi[:n],
        n,
    )
    got, ref = get_solver("daqp").solve(qp), QpsolversSolver("quadprog").solve(qp)
    assert got.found and ref.found  # 0 is feasible: every lower bound ≤ 0 ≤ every upper bound
    np.testing.assert_allclose(got.x, ref.x, atol=1e-7)
