"""qpik.solve_ik: answers checked by an independent FK and the limits, the closed form's choice against dense
sampling of the parameter, the Levenberg–Marquardt Jacobian by finite differences, stalls, bad input."""

from __future__ import annotations

import contextlib
from concurrent.futures import ThreadPoolExecutor

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS, fd, q_within_limits, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.algebra.lie import pose_error
from qpik.analytic.api import closed_form_for
from qpik.core.errors import InputError, NoClosedFormError, RotationError, UnreachableError
from qpik.nlp.ik import ATTEMPT_ITERS, CLOSED_FORM_DEFAULT, IKSolver, ik_solver_for, residual_expr, solve_ik
from qpik.nlp.options import IKOptions

ARMS = ("nammoto7", "iiwa14", "zheng7", "panda")
CLOSED_FORM = ("nammoto7", "iiwa14")
POSES = 1000


def _errors(robot: qpik.Robot, qs: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """‖[Δp; rotation angle]‖ (N,) of configurations (N, n) toward targets (N, 4, 4), through the batched FK
    (numpy, not the compiled kinematics that solve_ik iterates) and an atan2 angle of R*ᵀR."""
    T = robot.fk(qs)
    dp = np.linalg.norm(T[:, :3, 3] - targets[:, :3, 3], axis=1)
    M = np.einsum("nji,njk->nik", targets[:, :3, :3], T[:, :3, :3])
    vee = np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], axis=1)
    angle = np.arctan2(0.5 * np.linalg.norm(vee, axis=1), 0.5 * (np.trace(M, axis1=1, axis2=2) - 1.0))
    return np.hypot(dp, angle)


def _far_pose(robot: qpik.Robot) -> np.ndarray:
    T = robot.fk(robot.q_home)
    T[:3, 3] = [3.0, 0.0, 0.5]  # beyond every arm's reach (< 1.4 m)
    return T


@pytest.mark.parametrize(
    ("name", "method"), [(name, None) for name in ARMS] + [(name, "levenberg-marquardt") for name in CLOSED_FORM]
)
def test_reaches_random_reachable_poses(name: str, method: str | None) -> None:
    """≥ 99.9 % of 1,000 seeded poses fk(q), q uniform inside the limits, from random starts: FK to 1e-9, in limits."""
    robot = qpik.load_robot(name)
    targets = robot.fk(random_q(robot, POSES, seed=21))
    starts = random_q(robot, POSES, seed=22)
    found = []
    for i in range(POSES):
        with contextlib.suppress(UnreachableError):  # counted as a failure
            found.append((i, solve_ik(robot, targets[i], starts[i], options=IKOptions(seed=i, method=method))))
    assert len(found) >= 0.999 * POSES
    idx = np.array([i for i, _ in found])
    qs = np.array([q for _, q in found])
    assert robot.within_limits(qs).all()
    assert _errors(robot, qs, targets[idx]).max() < 1e-9


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS, name=st.sampled_from(CLOSED_FORM))
def test_closed_form_keeps_the_start_parameter_or_takes_the_nearer_end_of_its_gap(seed: int, name: str) -> None:
    """Against 20,001 sampled values of δ/ψ: on q0's branch, if q0's own parameter is feasible the answer is there;
    else it is at the first or last feasible sample around it, whichever gives the q nearer q0. Checked by FK."""
    robot = qpik.load_robot(name)
    q_goal, q0 = random_q(robot, 2, seed)
    T = robot.fk(q_goal)
    res = ik_solver_for(robot).solve(T, q0)
    assert res.status == "ok" and res.method == "closed form"
    assert _errors(robot, res.q[None], T[None])[0] < 1e-9 and robot.within_limits(res.q)
    param0, branch0 = qpik.redundancy_parameter(robot, q0)
    grid = np.linspace(-np.pi, np.pi, 20_001)
    step = grid[1] - grid[0]
    dense = qpik.ik(robot, np.broadcast_to(T, (grid.size, 4, 4)), grid)
    k0 = list(dense.branch).index(branch0)
    feasible = np.flatnonzero(dense.within_limits[:, k0])
    if feasible.size == 0:  # q0's branch cannot reach the pose (or only on a set narrower than the samples)
        return
    assert res.branch == branch0
    offset = np.remainder(grid[feasible] - param0, 2 * np.pi)  # how far above param0, on the circle
    if min(offset.min(), 2 * np.pi - offset.max()) < step:  # param0 is (next to) a feasible sample: kept
        assert abs(np.remainder(res.param - param0 + np.pi, 2 * np.pi) - np.pi) < step
        return
    ends = feasible[[np.argmin(offset), np.argmax(offset)]]  # first feasible sample above param0, last below
    gaps = np.abs(np.remainder(res.param - grid[ends] + np.pi, 2 * np.pi) - np.pi)
    assert gaps.min() < 2 * step  # the answer is at one of the two ends
    dist = np.linalg.norm(dense.q[ends, k0] - q0, axis=1)
    sets = qpik.feasible_intervals(robot, T)
    narrow = any(hi - lo < 2 * step for lo, hi in sets.intervals[list(sets.branch).index(branch0)])
    if narrow:  # a feasible set between two samples: the samples do not see that end (tested against dense
        return  # sampling in the interval tests)
    if abs(dist[0] - dist[1]) > 0.5:  # rad: clearly apart (at a validity boundary q moves fast with δ/ψ)
        assert np.argmin(gaps) == np.argmin(dist)


@settings(max_examples=10, deadline=None)
@given(data=st.data(), name=st.sampled_from(ARMS))
def test_a_start_at_the_pose_is_kept(data: st.DataObject, name: str) -> None:
    robot = qpik.load_robot(name)
    q0 = data.draw(q_within_limits(robot))
    np.testing.assert_array_equal(solve_ik(robot, robot.fk(q0), q0), q0)


@pytest.mark.parametrize("name", ARMS)
def test_residual_jacobian_by_finite_differences(name: str) -> None:
    """G = -∂e/∂q of the Levenberg–Marquardt step, e = [p* − p; log(R* Rᵀ)], against central differences."""
    robot = qpik.load_robot(name)
    q, T = ca.SX.sym("q", robot.dof), ca.SX.sym("T", 4, 4)
    e, G = residual_expr(robot, q, T)
    f = ca.Function("residual", [q, T], [e, G])
    goals, points = random_q(robot, 20, seed=3), random_q(robot, 20, seed=4)
    for goal, x in zip(goals, points):
        target = robot.fk(goal)
        np.testing.assert_allclose(np.asarray(f(x, target)[0]).ravel(), pose_error(target, robot.fk(x)), atol=1e-14)
        want = -fd(lambda y, target=target: pose_error(target, robot.fk(y)), x)
        np.testing.assert_allclose(np.asarray(f(x, target)[1]), want, atol=1e-7)


@pytest.mark.parametrize("name", ("zheng7", "panda"))
def test_stalled_attempts_stop_early_and_restarts_are_seeded(name: str) -> None:
    """A pose out of reach: every attempt stalls; each stops well before ATTEMPT_ITERS, the budget holds."""
    robot = qpik.load_robot(name)
    solver = ik_solver_for(robot)
    res = solver.solve(_far_pose(robot), robot.q_home, max_iters=800)
    assert res.status == "not found" and res.residual > 1.0 and np.isfinite(res.q).all()
    assert robot.within_limits(res.q)
    assert res.iterations <= 800 and res.attempts >= 5
    assert res.iterations / res.attempts <= ATTEMPT_ITERS / 2
    # a reachable pose from a start that needs restarts: the same seed gives the same answer
    targets = robot.fk(random_q(robot, 200, seed=8))
    starts = random_q(robot, 200, seed=9)
    runs = [solver.solve(T, q0, seed=5) for T, q0 in zip(targets, starts)]
    hard = [i for i, r in enumerate(runs) if r.attempts > 1]
    assert hard
    for i in hard[:5]:
        again = solver.solve(targets[i], starts[i], seed=5)
        np.testing.assert_array_equal(again.q, runs[i].q)
        assert (again.attempts, again.iterations) == (runs[i].attempts, runs[i].iterations)


@pytest.mark.parametrize("name", ARMS)
def test_unreachable_pose(name: str) -> None:
    robot = qpik.load_robot(name)
    far = _far_pose(robot)
    with pytest.raises(UnreachableError, match="pose error"):
        solve_ik(robot, far, robot.q_home, options=IKOptions(max_iters=200))
    res = IKSolver(robot).solve(far, robot.q_home, max_iters=200)
    assert res.status == ("unreachable" if robot.closed_form in CLOSED_FORM_DEFAULT else "not found")
    assert np.isfinite(res.residual) and res.residual > 1.0 and robot.within_limits(res.q)


def test_reachable_only_outside_the_limits_is_unreachable() -> None:
    """iiwa14's elbow angle |θ4| is fixed by the shoulder–wrist distance: beyond its 120° no branch is feasible."""
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home.copy()
    q[3] = -2.5  # rad, past the limit -2.094
    res = ik_solver_for(robot).solve(robot.fk(q), robot.q_home)
    assert res.status == "unreachable" and res.residual > 1e-3 and robot.within_limits(res.q)
    with pytest.raises(UnreachableError, match="no configuration inside the joint limits"):
        solve_ik(robot, robot.fk(q), robot.q_home)


@pytest.mark.parametrize("key", ["erd_xarm7", "erd_baxter"])
def test_the_closed_form_path_says_unreachable_only_where_the_sets_are_proved(key: str) -> None:
    """A near member's sets and the 1-D search's are not proved: a pose they find no branch for, out of reach here,
    is "not found", never "unreachable" (the Panda's proved sets say "unreachable" for the same kind of pose)."""
    from conftest import model_robot

    for robot, status in ((model_robot(key), "not found"), (qpik.load_robot("panda"), "unreachable")):
        res = IKSolver(robot).solve(_far_pose(robot), robot.q_home, max_iters=200, method="closed form")
        assert res.status == status and res.residual > 1.0 and robot.within_limits(res.q)


def test_a_start_parameter_inside_its_set_needs_no_sets(monkeypatch) -> None:
    """Baxter's right arm (the 1-D search, whose sets take seconds): starts near configurations of random poses, with
    their q1 (the locked joint), keep their own q1 and slot, found by ``qpik.ik`` at q0's q1 without the feasible sets
    (which would raise here), and the answer reaches the pose by MuJoCo's FK of the file."""
    from conftest import model_robot, mujoco_poses

    robot = model_robot("erd_baxter")
    solver = closed_form_for(robot)
    monkeypatch.setattr(solver, "feasible_intervals", lambda *a, **k: pytest.fail("the sets were computed"))
    q_goal = random_q(robot, 3, 21, margin=0.3)
    q0 = q_goal.copy()
    q0[:, 1:] += np.random.default_rng(21).uniform(-0.01, 0.01, (3, 6))
    for qg, start in zip(q_goal, q0):
        T = mujoco_poses(robot, qg[None])[0]
        res = IKSolver(robot).solve(T, start, method="closed form")
        param0, branch0 = qpik.redundancy_parameter(robot, start)
        assert res.status == "ok" and res.method == "closed form", res
        assert res.branch == branch0 and res.param == pytest.approx(param0, abs=1e-15)
        np.testing.assert_allclose(mujoco_poses(robot, res.q[None])[0], T, atol=1e-9)
        assert robot.within_limits(res.q)


@pytest.mark.parametrize("name", ("iiwa14", "panda"))
def test_controller_solve_ik_delegates(name: str) -> None:
    robot = qpik.load_robot(name)
    ctrl = qpik.Controller.for_robot(robot)
    target = robot.fk(random_q(robot, 1, seed=30)[0])
    q0 = random_q(robot, 1, seed=31)[0]
    got = ctrl.solve_ik(q0, target, seed=7)
    np.testing.assert_array_equal(got, solve_ik(robot, target, q0, options=IKOptions(seed=7)))
    assert _errors(robot, got[None], target[None])[0] < 1e-9
    assert not any(isinstance(v, qpik.Controller) for v in vars(ctrl).values())  # no hidden second controller


def test_bad_input() -> None:
    robot = qpik.load_robot("panda")
    T = robot.fk(robot.q_home)
    q = robot.q_home.copy()
    bad = T.copy()
    bad[1, 3] = np.nan
    with pytest.raises(InputError, match=r"^pose"):
        solve_ik(robot, bad, q)
    with pytest.raises(InputError, match=r"^pose"):
        solve_ik(robot, np.stack([T, T]), q)
    with pytest.raises(InputError, match=r"^pose"):
        solve_ik(robot, T[:3], q)
    q[2] = np.inf
    with pytest.raises(InputError, match=r"^q0"):
        solve_ik(robot, T, q)
    for wrong in (np.zeros(6), np.zeros((2, 7))):
        with pytest.raises(InputError, match=r"^q0"):
            solve_ik(robot, T, wrong)
    for kwargs in ({"tol": 0.0}, {"tol": np.nan}, {"max_iters": 0}, {"max_time": -1.0}, {"method": "newton"}):
        args = kwargs if "tol" in kwargs else {"options": IKOptions(**kwargs)}
        with pytest.raises(InputError, match=rf"^{next(iter(kwargs))}"):
            solve_ik(robot, T, robot.q_home, **args)
    with pytest.raises(InputError, match=r"^options"):
        solve_ik(robot, T, robot.q_home, options={"seed": 1})
    with pytest.raises(NoClosedFormError, match=r"^method"):
        solve_ik(qpik.load_robot("zheng7"), T, robot.q_home, options=IKOptions(method="closed form"))
    skew = T.copy()
    skew[:3, :3] *= 1.001
    with pytest.raises(RotationError):
        solve_ik(robot, skew, robot.q_home)
    q_star = solve_ik(robot, skew, robot.q_home + 0.1, project=True)
    assert _errors(robot, q_star[None], T[None])[0] < 1e-9


@pytest.mark.parametrize("name", ["iiwa14", "panda"])
def test_threads_sharing_an_arm_get_the_answers_of_one_thread(name: str) -> None:
    """Four threads calling ``solve_ik`` on one robot at once (the closed form on iiwa14, Levenberg–Marquardt on
    panda) get exactly what one thread gets: the solvers hold their locks around their compiled calls."""
    robot = qpik.load_robot(name)
    rng = np.random.default_rng(5)
    T = robot.fk(rng.uniform(robot.q_min, robot.q_max, (16, robot.dof)))
    Q0 = rng.uniform(robot.q_min, robot.q_max, (16, robot.dof))

    def answers(k: int) -> list:
        return [qpik.solve_ik(robot, T[i], Q0[i]).tolist() for i in range(k, len(T), 4)]

    serial = [answers(k) for k in range(4)]
    with ThreadPoolExecutor(4) as pool:
        for _ in range(3):
            assert list(pool.map(answers, range(4))) == serial
