"""Controller: the same QP as mink on the MJCF twin, solve_ik against FK and the closed form, bad input."""

from __future__ import annotations

import mink
import numpy as np
import pytest
from conftest import SEEDS, random_q
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

import qpik
from qpik.control import (
    ConfigurationLimit,
    Controller,
    ControllerOptions,
    DampingTask,
    FrameTask,
    PostureTask,
    VelocityLimit,
    pose_error,
)
from qpik.geometry.distance import distances
from qpik.geometry.shapes import Sphere
from qpik.nlp.options import BestOptions


def _mink_v(robot, q, target, dt, cost_p, cost_o, gain, posture, limits):
    """mink.solve_ik on the MJCF twin: FrameTask on site "ee" (+ posture, damping), its v = Δq/dt."""
    model = robot.mj_model()
    conf = mink.Configuration(model)
    conf.update(q)
    frame = mink.FrameTask("ee", "site", position_cost=cost_p, orientation_cost=cost_o, gain=gain)
    frame.set_target(mink.SE3.from_matrix(target))
    tasks = [frame]
    if posture is not None:
        q_ref, cost_q, gain_q, cost_d = posture
        post = mink.PostureTask(model, cost=cost_q, gain=gain_q)
        post.set_target(q_ref)
        tasks += [post, mink.DampingTask(model, cost=cost_d)]
    lims = []
    if limits:
        vel = {f"joint{j + 1}": robot.v_max[j] for j in range(robot.dof)}
        lims = [mink.ConfigurationLimit(model, gain=1.0, min_distance_from_limits=0.0), mink.VelocityLimit(model, vel)]
    return mink.solve_ik(conf, tasks, dt, solver="daqp", limits=lims)


def _qpik_v(robot, q, target, dt, cost_p, cost_o, gain, posture, limits, solver, error="world"):
    r"""The same problem in qpik's terms.

    mink minimises ½ Σ ‖c_i (J_i Δq + g e_i)‖² (+ ½ 1e-12 ‖Δq‖²) over Δq = v dt. Its frame error
    is e = log(T⁻¹T*) with J = −jlog(T*⁻¹T) J_b: ``error="se3"`` with weights c², gains g/dt. With no
    rotation error mink takes jlog = I (it does below θ² < machine ε), so its error is the body-frame
    [Rᵀ(p* − p); 0] and its Jacobian the body Jacobian, and with isotropic costs the frame term is
    the world-frame ½ dt² (c_p² ‖J_v v − (g/dt)(p* − p)‖² + c_o² ‖J_ω v‖²). Dividing every term by dt²/2:
    weights c², gains g/dt; posture c² ‖v − (g/dt)(q* − q)‖²; damping c² ‖v‖² (mink's 1e-12
    matches our regularisation up to a factor 2, far below 1e-6). Limits: mink's
    ConfigurationLimit(gain=1) and VelocityLimit are our boxes
    (q_min − q)/dt ≤ v ≤ (q_max − q)/dt and |v| ≤ v_max.
    """
    tasks = [FrameTask(target, gain / dt, gain / dt, cost_p**2, cost_o**2, error=error)]
    if posture is not None:
        q_ref, cost_q, gain_q, cost_d = posture
        tasks += [PostureTask(q_ref, gain_q / dt, cost_q**2), DampingTask(cost_d**2)]
    lims = [ConfigurationLimit(), VelocityLimit()] if limits else []
    return Controller(robot, tasks, lims, solver=solver, dt=dt).step(q)


@pytest.mark.parametrize("error", ["world", "se3"])
@settings(max_examples=15, deadline=None)
@given(seed=SEEDS)
def test_same_velocity_as_mink(error, seed):
    """mink.solve_ik's v on the MJCF twin. "world": translation errors only (where the two conventions agree);
    "se3" (mink's own error): plus a rotation error of 0.01 to 1 rad about a random axis. Below ~1e-4 rad
    mink's jlog loses digits (cancellation in its closed forms; the identity below θ² < machine ε)."""
    rng = np.random.default_rng(seed)
    robot = qpik.load_robot(("iiwa14", "panda", "zheng7")[seed % 3])
    q = random_q(robot, 1, seed, margin=0.05)[0]
    dt = float(rng.choice([0.002, 0.01, 0.05]))
    target = robot.fk(q)
    target[:3, 3] += rng.normal(size=3) * rng.uniform(0.01, 0.2)
    if error == "se3":
        axis = rng.normal(size=3)
        target[:3, :3] = (
            Rotation.from_rotvec(rng.uniform(0.01, 1.0) * axis / np.linalg.norm(axis)).as_matrix() @ target[:3, :3]
        )
    cost_p, cost_o, gain = rng.uniform(0.5, 2.0), rng.uniform(0.05, 1.0), rng.uniform(0.1, 1.0)
    posture = (random_q(robot, 1, seed + 1)[0], rng.uniform(0.01, 0.3), rng.uniform(0.1, 1.0), rng.uniform(1e-3, 0.05))
    limits = bool(rng.integers(2))
    want = _mink_v(robot, q, target, dt, cost_p, cost_o, gain, posture, limits)
    for solver in ("osqp", "daqp"):
        got = _qpik_v(robot, q, target, dt, cost_p, cost_o, gain, posture, limits, solver, error)
        # 1e-6 rad/s, or 1e-9 relative near a singularity without limits (|v| up to ~1e3 rad/s)
        np.testing.assert_allclose(got, want, atol=1e-6, rtol=1e-9)


def test_same_velocity_as_mink_at_zero_error():
    """Target = current pose: the frame task acts as a null-space filter of the posture pull."""
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home + 0.2
    posture = (robot.q_home - 0.3, 0.2, 0.5, 0.01)
    want = _mink_v(robot, q, robot.fk(q), 0.01, 1.0, 1.0, 1.0, posture, True)
    got = _qpik_v(robot, q, robot.fk(q), 0.01, 1.0, 1.0, 1.0, posture, True, "osqp")
    assert np.abs(want).max() > 1e-2  # the posture task moves the arm
    np.testing.assert_allclose(got, want, atol=1e-6, rtol=0)


@settings(max_examples=25, deadline=None)
@given(seed=SEEDS)
def test_solve_ik_reaches_random_pose(seed):
    """solve_ik from a random start (uniform within the limits) reaches a random iiwa14 pose to 1e-9 (FK)."""
    robot = qpik.load_robot("iiwa14")
    q_goal, q0 = random_q(robot, 2, seed, margin=0.1)
    pose = robot.fk(q_goal)
    ctrl = Controller.for_robot(robot)
    q = ctrl.solve_ik(q0, pose, tol=1e-10)
    assert np.linalg.norm(pose_error(pose, robot.fk(q))) < 1e-9
    assert robot.within_limits(q, tol=1e-12)
    # the closed form sees the same configuration: ik(fk(q), ψ(q)).q[branch(q)] == q. At q's own pose:
    # q reaches `pose` only to 1e-10, which near a shoulder/elbow singularity is ~1e-7 in joint space.
    psi, branch = qpik.redundancy_parameter(robot, q)
    sols = qpik.ik(robot, robot.fk(q), psi)
    row = int(np.flatnonzero(np.asarray(sols.branch) == branch)[0])
    np.testing.assert_allclose(sols.q[row], q, atol=1e-8)


def test_solve_ik_unreachable_raises_with_residual():
    robot = qpik.load_robot("iiwa14")
    far = robot.fk(robot.q_home)
    far[:3, 3] = [3.0, 0.0, 0.5]  # beyond the 1.3 m reach
    ctrl = Controller.for_robot(robot)
    with pytest.raises(qpik.UnreachableError, match="pose error"):
        ctrl.solve_ik(robot.q_home, far, max_iters=50)
    # the control step still gives a bounded velocity toward it
    v = ctrl.step(robot.q_home, target=far)
    assert np.all(np.abs(v) <= robot.v_max + 1e-12)
    assert ctrl.last.status == "ok" and ctrl.last.task_error > 1.0


def test_step_reports_active_constraints_and_clearance():
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home.copy()
    T = robot.fk(q)
    sphere = Sphere(T[:3, 3] + [0.0, 0.0, -0.2], 0.05, name="ball")
    target = T.copy()
    target[2, 3] -= 0.3  # through the ball
    ctrl = Controller.for_robot(robot, target=target, obstacles=[sphere], dt=0.01)
    for _ in range(300):
        q = q + ctrl.step(q) * ctrl.dt
    d = distances(robot.capsule_segments(q), robot.capsule_radii, [sphere]).d.min()
    assert ctrl.last.min_clearance == pytest.approx(d, abs=0.02)  # one step older
    assert any(name.startswith("obstacle ball") for name in ctrl.last.active)
    assert ctrl.last.total_time >= ctrl.last.solve_time > 0


def test_bad_input():
    robot = qpik.load_robot("iiwa14")
    ctrl = Controller.for_robot(robot, target=robot.fk(robot.q_home))
    q = robot.q_home.copy()
    q[2] = np.nan
    with pytest.raises(qpik.InputError, match="q"):
        ctrl.step(q)
    with pytest.raises(qpik.InputError):
        ctrl.step(np.zeros(6))
    with pytest.raises(qpik.InputError):
        ctrl.step(np.zeros((2, 7)))
    with pytest.raises(qpik.InputError):
        ctrl.solve_ik(q, robot.fk(robot.q_home))
    with pytest.raises(qpik.InputError):
        Controller(robot, [DampingTask()], dt=0.0)
    with pytest.raises(qpik.InputError):
        Controller(robot, [PostureTask(np.zeros(6))])
    with pytest.raises(qpik.InputError):
        Controller(robot, [DampingTask()]).step(robot.q_home, target=robot.fk(robot.q_home))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"position_gain": np.nan}, "position_gain"),
        ({"orientation_gain": -1.0}, "orientation_gain"),
        ({"position_gain": np.inf}, "position_gain"),
        ({"posture_weight": np.nan}, "posture_weight"),
        ({"posture_weight": -1e-3}, "posture_weight"),
        ({"manipulability_weight": np.inf}, "manipulability_weight"),
        ({"damping": -1.0}, "damping"),
        ({"d_safe": "x"}, "d_safe"),
        ({"xi": np.nan}, "xi"),
        ({"margin": -0.1}, "margin"),
        ({"dt": "fast"}, "dt"),
        ({"solver": None}, "solver"),
        ({"solver": 3}, "solver"),
    ],
)
def test_bad_parameters_raise_at_construction(kwargs, name):
    """NaN, negative or infinite gains and weights, and wrong types, are refused when the controller is built
    (they used to give v = 0 with "failed", or an OSQP exception from step)."""
    robot = qpik.load_robot("iiwa14")
    own = {k: v for k, v in kwargs.items() if k in ("d_safe", "dt", "solver")}
    options = ControllerOptions(**{k: v for k, v in kwargs.items() if k not in own})
    with pytest.raises(qpik.InputError, match=name):
        Controller.for_robot(
            robot, target=robot.fk(robot.q_home), obstacles=[Sphere((1, 1, 1), 0.1)], options=options, **own
        )


def test_options_must_be_controller_options():
    robot = qpik.load_robot("iiwa14")
    with pytest.raises(qpik.InputError, match="options"):
        Controller.for_robot(robot, options={"position_gain": 1.0})


def test_for_scene_builds_the_scene_s_limits_and_posture():
    robot = qpik.load_robot("iiwa14")
    q_ref = robot.q_home + 0.1
    scene = qpik.Scene.of(robot, [Sphere((1, 1, 1), 0.1)], d_safe=0.03, q_ref=q_ref)
    ctrl = Controller.for_scene(scene, robot.fk(robot.q_home), options=ControllerOptions(d_influence=0.2))
    assert np.array_equal(ctrl.tasks[1].q_ref, q_ref)
    assert ctrl.obstacle_limits[0].d_safe == 0.03 and ctrl.obstacle_limits[0].d_influence == 0.2
    with pytest.raises(qpik.InputError, match="scene"):
        Controller.for_scene(robot)


@pytest.mark.parametrize(
    "make",
    [
        lambda r: FrameTask(None, np.nan),
        lambda r: FrameTask(None, 1.0, 1.0, -1.0),
        lambda r: FrameTask(None, 1.0, 1.0, 1.0, np.inf),
        lambda r: PostureTask(r.q_home, -1.0),
        lambda r: PostureTask(r.q_home, 1.0, np.nan),
        lambda r: DampingTask(-1e-4),
        lambda r: ConfigurationLimit(np.nan),
        lambda r: Controller(r, ["frame"]),
        lambda r: Controller(r, [DampingTask()], [VelocityLimit(), "position"]),
        lambda r: Controller(r, DampingTask()),
        lambda r: Controller("iiwa14", [DampingTask()]),
        lambda r: Controller.for_robot("iiwa14"),
    ],
)
def test_bad_tasks_limits_and_robots_raise_input_error(make):
    with pytest.raises(qpik.InputError):
        make(qpik.load_robot("iiwa14"))


def test_disjoint_configuration_limits_raise_at_construction():
    """Two limits whose ranges of a joint do not meet: InfeasibleError at construction, not at step time."""
    robot = qpik.load_robot("iiwa14")
    tasks = Controller.for_robot(robot, target=robot.fk(robot.q_home)).tasks
    lo, hi = robot.q_min.copy(), robot.q_max.copy()
    hi[3] = -1.5
    lo2 = robot.q_min.copy()
    lo2[3] = -1.0
    with pytest.raises(qpik.InfeasibleError, match=r"joint\(s\) 4$"):
        Controller(robot, tasks, [ConfigurationLimit(q_min=lo, q_max=hi), ConfigurationLimit(q_min=lo2)])
    # ranges that meet are fine, and the step keeps the intersection
    lo2[3] = -1.6
    ctrl = Controller(robot, tasks, [ConfigurationLimit(q_min=lo, q_max=hi), ConfigurationLimit(q_min=lo2)])
    q = robot.q_home.copy()
    q[3] = -1.55
    for _ in range(50):
        q = q + ctrl.step(q) * ctrl.dt
        assert -1.6 - 1e-12 <= q[3] <= -1.5 + 1e-12


def _return_toward_a_sphere(rng: np.random.Generator):
    """zheng7 with joints 3 and 5 2° past +170° and a sphere 42.5 mm from link 7, in the direction in which the
    return from the limits moves it (the issue's example)."""
    robot = qpik.load_robot("zheng7")
    q0 = rng.uniform(robot.q_min * 0.6, robot.q_max * 0.6)
    q0[[2, 4]] = robot.q_max[[2, 4]] + np.radians(2.0)
    v = np.zeros(7)
    v[[2, 4]] = -robot.v_max[[2, 4]]
    seg0, seg1 = robot.capsule_segments(q0), robot.capsule_segments(q0 + 0.01 * v)
    s = rng.uniform()
    p0, p1 = (sg[6, 0] + s * (sg[6, 1] - sg[6, 0]) for sg in (seg0, seg1))
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    return robot, q0, [Sphere(p0 + u * (robot.capsule_radii[6] + 0.05 + 0.0425), 0.05)]


@pytest.mark.parametrize("solver", ["osqp", "daqp"])
def test_return_from_a_limit_yields_to_an_obstacle(solver):
    """Started past a limit next to an obstacle, the return conflicts with the damper rows: safety wins. Clearance
    measured by MuJoCo never falls below min(its start, d_s) − 1e-4 m, the joints never move further out, and the
    status says "yielding" (it used to be infeasible, and the fallback was the full-speed return into the sphere)."""
    from qpik.sim import simulate

    d_safe, dt = 0.0213, 0.002
    rng = np.random.default_rng(7)
    yielded = 0
    for _ in range(6):
        robot, q0, obstacles = _return_toward_a_sphere(rng)
        ctrl = Controller.for_robot(robot, target=robot.fk(q0), obstacles=obstacles, dt=dt, solver=solver,
                                    d_safe=d_safe)  # fmt: skip
        log = simulate(robot, ctrl, q0, 0.3, dt, obstacles=obstacles)
        cl = log.clearance.min(axis=(1, 2))
        assert cl.min() >= min(cl[0], d_safe) - 1e-4
        excess = np.maximum(log.q - robot.q_max, robot.q_min - log.q).clip(0)
        assert np.all(np.diff(excess, axis=0) <= 1e-12)
        assert "failed" not in log.status
        yielded += int((log.status == "yielding").sum())
    assert yielded > 20


def test_set_posture_takes_the_nlp_answer():
    """The controller's posture reference is the answer of qpik.solve_best: the QP then settles on it."""
    robot = qpik.load_robot("iiwa14")
    target = robot.fk(robot.q_home + 0.2)
    best = qpik.solve_best(robot, target, options=BestOptions(certify=False))
    ctrl = Controller.for_robot(robot, target=target, dt=0.01,
                                options=ControllerOptions(posture_weight=1e-2, manipulability_weight=0.0))  # fmt: skip
    ctrl.set_posture(best.q)
    assert np.array_equal(ctrl.tasks[1].q_ref, best.q)
    q = best.q.copy()
    assert np.abs(ctrl.step(q)).max() < 1e-9  # on the target and on the reference: nothing to do
    with pytest.raises(qpik.InputError, match="q_ref"):
        ctrl.set_posture(np.zeros(3))


def test_a_floor_under_the_base_is_not_a_penetration():
    """A floor at the base (z <= 0) overlaps the iiwa's first capsule, which no joint moves: the controller
    still reaches the pose, never reports "penetrating", and its clearance is that of the moving capsules."""
    from qpik.geometry.shapes import HalfSpace

    robot = qpik.load_robot("iiwa14")
    floor = HalfSpace(np.array([0.0, 0.0, 1.0]), 0.0, name="floor")
    q = np.array([0.0, 0.5, 0.0, -1.2, 0.0, 0.8, 0.0])
    target = robot.fk(np.array([0.3, 0.6, 0.0, -1.0, 0.0, 0.9, 0.0]))
    ctrl = Controller.for_robot(robot, target=target, obstacles=[floor], dt=0.002)
    statuses = set()
    for _ in range(400):
        q_before = q
        q = q + ctrl.step(q) * ctrl.dt
        statuses.add(ctrl.last.status)
    segments = robot.capsule_segments(q_before)  # the configuration of the last step
    lowest = segments[..., 2].min(axis=1) - robot.capsule_radii  # capsule to plane z = 0, m
    assert lowest[0] < 0  # the first capsule overlaps the floor
    assert ctrl.last.min_clearance == pytest.approx(lowest[2:].min(), abs=1e-9)
    assert statuses == {"ok"}
    assert np.linalg.norm(pose_error(target, robot.fk(q))) < 1e-3
