"""qpik.nlp.solve_full: the full-joint NLP reaches seeded random reachable poses (FK-checked) on every arm.

Poses are fk of configurations drawn uniformly inside the limits; the answers are checked by
the DH forward kinematics and the limits, independently of the NLP; with an objective, the
answer's KKT residual is recomputed and compared with a dense-sampled closed-form optimum.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from conftest import model_robot, random_q

import qpik
from qpik.algebra.lie import pose_error
from qpik.core.errors import InputError
from qpik.geometry import Sphere, distances
from qpik.nlp import solve_best, solve_full
from qpik.nlp.full import REACHED
from qpik.nlp.options import BestOptions, FullOptions
from qpik.scene import Scene


@pytest.mark.parametrize("name", ["zheng7", "panda"])
def test_reaches_every_seeded_pose(name):
    """The issue asks ≥ 99.9 %; on this seeded set of 150 poses that means all of them. Reach over the limits alone,
    self-collision off: a pose whose every configuration brings two capsules closer than d_s has no answer with it,
    and zheng7's capsules of links 3 and 5 are never more than 21 mm apart, so at d_s = 2 cm its clear
    configurations are a sliver."""
    robot = qpik.load_robot(name)
    scene = Scene.of(robot, self_collision=False)
    T = robot.fk(random_q(robot, 150, 21))
    starts = random_q(robot, 150, 22)
    for k in range(len(T)):
        res = solve_full(scene, T[k], options=FullOptions(q0=starts[k], seed=k))
        assert res.status == "optimal", (k, res.message)
        assert np.linalg.norm(pose_error(T[k], robot.fk(res.q))) < REACHED
        assert robot.within_limits(res.q)


@pytest.mark.parametrize("name", ["iiwa14", "zheng7"])
def test_objective_and_obstacles(name):
    robot = qpik.load_robot(name)
    T = robot.fk(random_q(robot, 4, 23))
    ball = [Sphere((0.4, 0.2, 0.7), 0.08)]
    for k in range(len(T)):
        res = solve_full(robot, T[k], "smooth-margin", ball, d_safe=0.02, options=FullOptions(starts=3))
        assert res.status == "optimal"
        np.testing.assert_allclose(robot.fk(res.q), T[k], atol=1e-9)
        moving = ~robot.fixed_capsules  # the clearance of the capsules a joint moves
        d = distances(robot.capsule_segments(res.q)[moving], robot.capsule_radii[moving], ball).d
        own = Scene.of(robot).self_clearance(res.q[None])[0]  # the arm's own capsule pairs, kept by default
        assert d.min() >= 0.02 - 1e-8 and own >= 0.02 - 1e-8
        assert res.clearance == pytest.approx(min(d.min(), own), abs=1e-12)
        assert res.kkt <= 1e-8


def test_from_the_closed_form_optimum_it_stays_there():
    """Started at solve_best's answer (a smooth objective), the 7-variable NLP keeps it: same q and f."""
    robot = qpik.load_robot("nammoto7")
    for q in random_q(robot, 3, 24):
        T = robot.fk(q)
        best = solve_best(robot, T, "smooth-margin", options=BestOptions(certify=False))
        full = solve_full(robot, T, "smooth-margin", options=FullOptions(q0=best.q, starts=1, max_starts=1))
        assert full.status == "optimal" and full.kkt <= 1e-8
        assert np.abs(full.q - best.q).max() <= 1e-6
        assert abs(full.objective - best.objective) <= 1e-8


def test_the_pose_error_is_the_log_and_differentiable_at_zero():
    """qpik.algebra.lie.pose_error_expr (the NLP's equality) has finite derivatives at its solution, equal to finite
    differences, and its value is scipy's rotation vector."""
    import casadi as ca
    from scipy.spatial.transform import Rotation

    from qpik.algebra.lie import pose_error_expr

    C = ca.SX.sym("C", 3, 4)
    T = np.eye(4)
    fn = ca.Function("e", [C], [ca.jacobian(pose_error_expr(ca.SX(T), C), C), pose_error_expr(ca.SX(T), C)])
    u = np.array([0.6, -0.48, 0.64])
    for angle in (0.0, 1e-9, 1e-4, 0.3, 2.0, 3.1):
        Ct = np.hstack([Rotation.from_rotvec(-angle * u).as_matrix(), np.zeros((3, 1))])  # R* Rᵀ = exp(angle u)
        J, e = (np.asarray(x) for x in fn(Ct))
        np.testing.assert_allclose(e.ravel()[3:], angle * u, atol=1e-12)
        assert np.isfinite(J).all()
    # at the solution: d e / d C against central differences along rotations (C = exp(ε k) Rᵀ... of the identity)
    J = np.asarray(fn(np.hstack([np.eye(3), np.zeros((3, 1))]))[0])
    for k in np.eye(3):
        h = 1e-6
        plus = np.hstack([Rotation.from_rotvec(h * k).as_matrix(), np.zeros((3, 1))])
        minus = np.hstack([Rotation.from_rotvec(-h * k).as_matrix(), np.zeros((3, 1))])
        fd = (np.asarray(fn(plus)[1]) - np.asarray(fn(minus)[1])).ravel() / (2 * h)
        lin = J @ ((plus - minus).ravel(order="F") / (2 * h))
        np.testing.assert_allclose(lin, fd, atol=1e-8)


def test_unreachable_and_bad_input():
    """Out of reach: "unreachable" where proved feasible sets prove it (iiwa14, and the Panda's locked-q7 sets, proved
    at this pose); "not found" where the sets are not proved (example-robot-data's xArm7, a near member) or there is
    no closed form (that xArm7 with axis 3 moved 1 mm)."""
    far = np.eye(4)
    far[:3, 3] = (2.0, 0.0, 0.5)
    robot = qpik.load_robot("panda")
    assert qpik.feasible_intervals(robot, far).proved
    for arm in (qpik.load_robot("iiwa14"), robot):
        res = solve_full(arm, far, options=FullOptions(max_starts=3))
        assert res.status == "unreachable" and res.pose_error > 0.5
    for arm in (model_robot("erd_xarm7"), model_robot("xarm7_offset")):
        res = solve_full(arm, far, options=FullOptions(max_starts=3))
        assert res.status == "not found" and res.pose_error > 0.5 and res.starts == 3
    with pytest.raises(InputError, match="pose"):
        solve_full(robot, np.full((4, 4), np.nan))
    with pytest.raises(InputError, match="pose"):
        solve_full(robot, np.stack([far, far]))
    with pytest.raises(InputError, match="q0"):
        solve_full(robot, far, options=FullOptions(q0=np.zeros(5)))
    with pytest.raises(InputError, match="q_ref"):
        solve_full(robot, far, "distance")


def test_threads_sharing_an_nlp_get_the_answers_of_one_thread() -> None:
    """Four threads calling ``solve_full`` on one robot at once get exactly what one thread gets (IPOPT's memory
    is the cached NLP's: each solve holds its lock; without it, concurrent solves crash inside CasADi)."""
    robot = qpik.load_robot("zheng7")
    T = robot.fk(np.random.default_rng(9).uniform(robot.q_min, robot.q_max, (8, robot.dof)))

    def answers(k: int) -> list:
        return [solve_full(robot, T[i]).q.tolist() for i in range(k, len(T), 4)]

    serial = [answers(k) for k in range(4)]
    with ThreadPoolExecutor(4) as pool:
        assert list(pool.map(answers, range(4))) == serial


def test_an_arm_of_the_search_starts_from_its_branches():
    """The Sawyer's branches are found by the 1-D search (no expressions of the parameter): after q0, solve_full's
    starts are qpik.ik's within-limits branches at the parameters of SEARCHED, in that order, each reaching the pose
    by MuJoCo's FK of the file, before any random start; and an answer from them reaches the pose too."""
    from conftest import mujoco_poses

    from qpik.nlp.full import SEARCHED, _starts

    robot = model_robot("robosuite_sawyer")
    assert robot.closed_form == "locked_search" and not robot.branch_functions
    scene = Scene.of(robot, objective="smooth-margin", self_collision=False)
    for k, q in enumerate(random_q(robot, 3, 24)):
        T = mujoco_poses(robot, q[None])[0]
        expected = [x for p in SEARCHED for x in qpik.ik(robot, T, p).q[qpik.ik(robot, T, p).within_limits]]
        assert len(expected) >= 2
        queue = _starts(robot, T, q[None], k)
        np.testing.assert_array_equal(next(queue), q)
        got = np.array([next(queue) for _ in expected])
        np.testing.assert_array_equal(got, expected)
        np.testing.assert_allclose(mujoco_poses(robot, got), np.broadcast_to(T, (len(got), 4, 4)), atol=1e-10)
        res = solve_full(scene, T, options=FullOptions(starts=2, seed=k))
        assert res.status == "optimal", res.message
        np.testing.assert_allclose(mujoco_poses(robot, res.q[None])[0], T, atol=1e-9)
