"""Property-based fuzzing of the public API: bad input gives a qpik error or a documented answer, never NaN.

:data:`CASES` is a table: one row per public call, with a good value and a bad-value strategy for each
argument (:class:`Arg`). Each example keeps every argument good but (at most) one, drawn from its bad
values (NaN, inf, huge, complex, text, None, a robot's name where a Robot is expected, wrong shapes, empty
batches, ...) or from :data:`ANY_BAD`. The call must either return — outputs without NaN, statuses as
documented (:func:`check_output`) — or raise a :class:`qpik.QpikError` (``InputError`` is also a
``ValueError``); any other exception fails the test. Adding a public function is one row.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from conftest import LARGE
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import qpik
from qpik import control, geometry
from qpik import objectives as objs
from qpik.checks.crosscheck import crosscheck
from qpik.control import clik
from qpik.control.solvers import get_solver
from qpik.nlp import BestResult, solve_full
from qpik.nlp.options import BestOptions, FullOptions
from qpik.objectives import JointLimitMargin, Manipulability
from qpik.problems import load
from qpik.scene.evaluator import Evaluator
from qpik.sim import SimLog, simulate

IIWA, NAMMOTO, PANDA = (qpik.load_robot(n) for n in ("iiwa14", "nammoto7", "panda"))
ROBOTS = tuple(qpik.load_robot(n) for n in qpik.CATALOG)
STATUSES = {"ok", "recovering", "penetrating", "yielding", "failed"}
FUZZ = settings(
    max_examples=200 if LARGE else 40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
    database=None,
)
FEW = settings(FUZZ, max_examples=30 if LARGE else 8)
"""For the calls that solve several problems each (:data:`SLOW_CASES`)."""

# ---- bad values -------------------------------------------------------------------------


ANY_BAD = st.sampled_from(
    [
        np.nan,
        np.inf,
        -np.inf,
        1e300,
        -1e155,
        1 + 1j,
        "iiwa14",
        "abc",
        "",
        None,
        True,
        [],
        [[1.0, 2.0], [3.0]],
        np.zeros(0),
        np.zeros((0, 7)),
        np.zeros((0, 4, 4)),
        np.zeros((2, 3)),
        np.full(7, np.nan),
        object(),
        {"type": "sphere"},
        -1.0,
        0.0,
    ]
)
"""Values that are wrong for (almost) any argument."""


def _poisoned(good: np.ndarray) -> st.SearchStrategy:
    """``good`` with one entry NaN, inf, huge or complex, reshaped, emptied or given as text."""
    flat = np.asarray(good, dtype=float).ravel()

    def poison(i: int, value: object) -> np.ndarray:
        arr = flat.astype(complex if isinstance(value, complex) else float)
        arr[i % len(arr)] = value
        return arr.reshape(np.shape(good))

    return st.one_of(
        st.builds(poison, st.integers(0, 1000), st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1e155, 1e7, 2j])),
        st.just(flat[:-1]),
        st.just(np.concatenate([flat, flat])),
        st.just(np.zeros((0, *np.shape(good)))),
        st.just(np.stack([good, good]).astype(float)),
        st.just(np.asarray(good).astype(str)),
        st.just(np.asarray(good).tolist()),
    )


def _rotations(draw_seed: int) -> np.ndarray:
    Q, R = np.linalg.qr(np.random.default_rng(draw_seed).normal(size=(3, 3)))
    return Q * np.sign(np.diag(R)) * np.sign(np.linalg.det(Q * np.sign(np.diag(R))))


def _bad_pose(good: np.ndarray) -> st.SearchStrategy:
    """Poses that are not: a reflection, a singular or scaled rotation, a wrong last row, a huge position."""

    def with_rotation(R: np.ndarray) -> np.ndarray:
        T = good.copy()
        T[:3, :3] = R
        return T

    def with_row(row: Sequence[float]) -> np.ndarray:
        T = good.copy()
        T[3] = row
        return T

    def with_position(p: float) -> np.ndarray:
        T = good.copy()
        T[:3, 3] = p
        return T

    R = good[:3, :3]
    return st.one_of(
        _poisoned(good),
        st.sampled_from([with_rotation(-R), with_rotation(np.zeros((3, 3))), with_rotation(3.0 * R)]),
        st.sampled_from([with_rotation(np.outer(R[:, 0], R[:, 0])), with_rotation(R * 1.001)]),
        st.sampled_from([with_row([0, 0, 0, 2]), with_row([1, 0, 0, 1]), with_position(1e155)]),
    )


NOTHING = st.nothing()


@dataclass(frozen=True)
class Arg:
    """One argument: a strategy of good values and one of bad values (with :data:`ANY_BAD`), or ``bad=None``
    for an argument that is never made bad (the object whose method is called)."""

    good: st.SearchStrategy
    bad: st.SearchStrategy | None = NOTHING


def q_arg(robot: qpik.Robot) -> Arg:
    good = st.integers(0, 2**16).map(lambda s: np.random.default_rng(s).uniform(robot.q_min, robot.q_max))
    return Arg(good, _poisoned(robot.q_home))


def pose_arg(robot: qpik.Robot) -> Arg:
    good = st.integers(0, 2**16).map(lambda s: robot.fk(np.random.default_rng(s).uniform(robot.q_min, robot.q_max)))
    return Arg(good, _bad_pose(robot.fk(robot.q_home)))


def robot_arg(robots: Sequence[qpik.Robot] = ROBOTS) -> Arg:
    return Arg(st.sampled_from(list(robots)), st.sampled_from([r.name for r in robots] + [None, 7, "ur5"]))


def number_arg(good: float, *bad: float) -> Arg:
    return Arg(st.just(good), st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1.0, "1", None, 1j, *bad]))


INTS = st.sampled_from([0, -1, 1.5, "2", None])
FLAG = Arg(st.booleans(), st.sampled_from(["no", "yes", 1, None, "True"]))
ROBOT = Arg(st.sampled_from(list(ROBOTS)), None)  # a Robot whose method is called
SPHERE = geometry.Sphere((0.5, 0.2, 0.6), 0.1)
BOX = geometry.Box((0.4, -0.3, 0.3), (0.1, 0.2, 0.05))
SHAPES = [SPHERE, geometry.Capsule((0.3, 0.4, 0.2), (0.3, 0.4, 0.9), 0.05), BOX, geometry.HalfSpace((0, 0, 1), -0.2)]
OBSTACLES = Arg(st.sampled_from([SHAPES, SHAPES[:1], []]), st.sampled_from([[1], "box", [SPHERE, None], 5, [{}]]))
VEC3 = Arg(st.just(np.array([0.4, 0.1, 0.5])), _poisoned(np.array([0.4, 0.1, 0.5])))
SEGMENTS = Arg(st.just(IIWA.capsule_segments(IIWA.q_home)), _poisoned(IIWA.capsule_segments(IIWA.q_home)))
RADII = Arg(st.just(IIWA.capsule_radii), _poisoned(IIWA.capsule_radii))
SPEC = {"type": "box", "center": [0, 0, 1], "half_extents": [0.1, 0.1, 0.1], "rotation": np.eye(3).tolist()}


def _bad_specs() -> st.SearchStrategy:
    def replaced(key: str, new: object) -> dict:
        return {**SPEC, key: new}

    keys = st.sampled_from([*SPEC, "unknown"])
    return st.one_of(st.builds(replaced, keys, ANY_BAD), st.just({**SPEC, "type": ["box"]}), st.just([SPEC]))


# ---- the calls ---------------------------------------------------------------------------


def _controller(robot, target, obstacles, solver, gain, dt, q):
    ctrl = qpik.Controller.for_robot(robot, target=target, obstacles=obstacles, solver=solver,
                                     options=qpik.ControllerOptions(position_gain=gain), dt=dt)  # fmt: skip
    v = ctrl.step(q)
    return v, ctrl.last


def _view(robot, target, obstacles, objective, d_safe):
    viewer = qpik.view(
        robot, target, obstacles, objective, d_safe=d_safe, options=qpik.ViewOptions(port=0, block=False)
    )
    viewer.close()
    return viewer.state.q


def _steps(robot, q, target, twist):
    ctrl = qpik.Controller.for_robot(robot, target=robot.fk(robot.q_home), obstacles=SHAPES[:1])
    outs = [ctrl.step(q, target, twist), ctrl.last]
    outs += [ctrl.step(q), ctrl.last]
    return outs


def _serial_chain(post, offset, kind, tool):
    joint = qpik.Joint(post=post, offset=offset, kind=kind)
    chain = qpik.SerialChain([joint, qpik.Joint(post=post)], tool=tool)
    return chain.fk(np.zeros(2)), chain.jacobian(np.zeros((3, 2)))


def _solve_best(robot, pose, objective, obstacles, d_safe):
    from qpik.nlp.best_result import STATUSES, BestResults

    best = qpik.solve_best(robot, pose, objective, obstacles, d_safe=d_safe, options=BestOptions(certify=False))
    results = list(best) if isinstance(best, BestResults) else [best]  # a batch of poses is a batch of answers
    assert all(r.status in STATUSES for r in results)
    return results


def _solve_full(robot, pose, objective, obstacles, q0, d_safe, starts, seed):
    res = solve_full(
        robot,
        pose,
        objective,
        obstacles,
        d_safe=d_safe,
        options=FullOptions(q0=q0, starts=starts, max_starts=2, seed=seed),
    )
    assert res.status in ("optimal", "unreachable", "not found", "solver failed")
    return res


def _objectives(smooth, sharpness, cap, weights, weight, fn):
    """Every objective's constructor, a weighted sum of them, and its evaluation (f, ∇f, distances)."""
    terms = [objs.JointLimitMargin(smooth, sharpness), objs.Clearance(cap, smooth, sharpness),
             objs.ReferenceDistance(weights), objs.Manipulability(smooth), objs.Expression(fn, smooth)]  # fmt: skip
    total = terms[0] + weight * terms[1] + terms[2] + weight * terms[3] + terms[4]
    ev = Evaluator(IIWA, total, SHAPES[:1])  # every example has a new expression: CasADi's VM, no compiling
    out = ev.function()(IIWA.q_home, ev.params, IIWA.q_home + 0.1, ev.obstacles.params)
    return np.asarray(out).ravel()


def _crosscheck(robot, pose, objective, obstacles, q_ref, d_safe, random_starts):
    check = crosscheck(robot, pose, objective, obstacles, q_ref, d_safe=d_safe, random_starts=random_starts)
    assert isinstance(check.report(), str)
    return check


def _objective_task(robot, objective, weight, q):
    task = qpik.control.ObjectiveTask(robot, objective, weight)
    ctrl = qpik.Controller(robot, [task, qpik.control.DampingTask()], [qpik.control.VelocityLimit()])
    return ctrl.step(q)


def _solve_ik(robot, q0, pose, tol, iters):
    ctrl = qpik.Controller.for_robot(robot)
    try:
        return ctrl.solve_ik(q0, pose, tol=tol, max_iters=iters)
    except qpik.UnreachableError:
        return None


def _simulate(robot, q0, obstacles, duration, dt, target):
    ctrl = qpik.Controller.for_robot(robot, obstacles=obstacles, dt=dt) if isinstance(robot, qpik.Robot) else None
    return simulate(robot, ctrl if ctrl is not None else (lambda t, q: np.zeros(7)), q0, duration, dt,
                    obstacles=obstacles, target=target)  # fmt: skip


def _limits(robot, margin, q_min, v_max, d_safe, xi):
    limits = [
        control.ConfigurationLimit(margin, q_min=q_min),
        control.VelocityLimit(v_max),
        control.ObstacleLimit(SHAPES, d_safe=d_safe, xi=xi),
    ]
    ctrl = qpik.Controller(robot, [control.FrameTask(robot.fk(robot.q_home)), control.DampingTask()], limits)
    return ctrl.step(robot.q_home), ctrl.last


def _tasks(robot, target, twist, weight, error, q_ref):
    tasks = [
        control.FrameTask(target, 10.0, 10.0, weight, 0.1, twist, error),
        control.PostureTask(q_ref, 1.0, weight),
        control.ManipulabilityTask(weight),
        control.DampingTask(weight),
    ]
    return qpik.Controller(robot, tasks, [control.VelocityLimit()]).step(robot.q_home)


def _clik(kind, robot, gain, dt, q, target):
    law = kind(robot, dt=dt) if kind is clik.VelocityOnly else kind(robot, gain, gain, dt=dt)
    return law.step(q, target), law.last


def _plan(robot, path, objective, obstacles, step, reconfigure):
    return qpik.plan_self_motion(
        robot,
        path,
        objective,
        obstacles,
        options=qpik.PlanOptions(
            max_joint_step=step, reconfigure=reconfigure, resolution=36, refine=False, mujoco=False
        ),
    )


PLAN_PATH = IIWA.fk(IIWA.q_home + np.linspace(0.0, 0.2, 4)[:, None])


def _plan_many(robot, paths, obstacles, workers, errors):
    scene = qpik.Scene.of(robot, obstacles) if isinstance(robot, qpik.Robot) else robot
    return qpik.plan_many(scene, paths, qpik.PlanOptions(resolution=36, refine=False, mujoco=False), workers=workers,
                          errors=errors, progress=False)  # fmt: skip


def _intervals(robot, pose, branch, value):
    fi = qpik.feasible_intervals(robot, pose)
    return fi[branch], fi.measure(branch), fi.contains(branch, value)


def _problem(tmp: Path, text: str):
    f = tmp / "fuzz.toml"
    f.write_text(text)
    return load(f)


TOML = """kind = "reach"
[robot]
name = "iiwa14"
[target]
q = [0.1, 0.2, 0.3, -0.4, 0.5, 0.6, 0.7]
[[obstacles]]
type = "sphere"
center = [0.5, 0.0, 0.6]
radius = 0.1
[solver]
dt = 0.002
d_safe = 0.03
"""
TOML_VALUES = st.sampled_from(['"fast"', "nan", "inf", "-1", "0", "1e300", "[1, 2]", "true", '"iiwa14"', "{ a = 1 }"])


def _toml(line: str, new: str) -> str:
    key = line.split("=")[0]
    return TOML.replace(line, f"{key}= {new}") if line and "=" in line else TOML + new


@dataclass(frozen=True)
class Case:
    """A public call: ``fn(*args)`` with one :class:`Arg` per argument."""

    name: str
    fn: Callable
    args: tuple[Arg, ...]


CASES = [
    Case("load_robot", qpik.load_robot, (Arg(st.sampled_from(list(qpik.CATALOG)), st.sampled_from(["ur5", "X"])),)),
    Case("ik", lambda r, T, p, pr: qpik.ik(r, T, p, project=pr),
         (robot_arg((IIWA, NAMMOTO)), pose_arg(IIWA), number_arg(0.3), FLAG)),
    Case("ik batch", lambda r, T, p: qpik.ik(r, T, p), (robot_arg((NAMMOTO,)),
         Arg(st.just(NAMMOTO.fk(np.stack([NAMMOTO.q_home, NAMMOTO.q_home + 0.1]))), _poisoned(np.eye(4)[None])),
         Arg(st.just(np.array([0.1, -0.2])), _poisoned(np.array([0.1, -0.2]))))),
    Case("feasible_intervals", lambda r, T, pr: qpik.feasible_intervals(r, T, project=pr),
         (robot_arg((IIWA, NAMMOTO)), pose_arg(NAMMOTO), FLAG)),
    Case("FeasibleIntervals", _intervals, (robot_arg((IIWA,)), pose_arg(IIWA), Arg(st.integers(0, 7),
         st.sampled_from([99, -1, "a", None, 1.5])), Arg(st.floats(-3.0, 3.0), _poisoned(np.zeros(3))))),
    Case("redundancy_parameter", qpik.redundancy_parameter, (robot_arg((IIWA, NAMMOTO)), q_arg(IIWA))),
    Case("IKSolutions.table", lambda T: qpik.ik(IIWA, T, 0.2).table(), (pose_arg(IIWA),)),
    Case("Robot.fk", lambda r, q: r.fk(q), (ROBOT, q_arg(PANDA))),
    Case("Robot.frames", lambda r, q: r.frames(q), (ROBOT, q_arg(PANDA))),
    Case("Robot.fk_jacobian", lambda r, q: r.fk_jacobian(q), (ROBOT, q_arg(PANDA))),
    Case("Robot.hessian", lambda r, q: r.hessian(q), (ROBOT, q_arg(PANDA))),
    Case("Robot.manipulability", lambda r, q, t: (r.manipulability(q, t), r.manipulability_gradient(q, t)),
         (ROBOT, q_arg(PANDA), FLAG)),
    Case("Robot.within_limits", lambda r, q, tol: r.within_limits(q, tol),
         (ROBOT, q_arg(PANDA), number_arg(1e-3))),
    Case("Robot.capsule_segments", lambda r, q: r.capsule_segments(q), (ROBOT, q_arg(PANDA))),
    Case("Joint + SerialChain", _serial_chain, (Arg(st.just(np.eye(4)), _poisoned(np.eye(4))), number_arg(0.1),
         Arg(st.sampled_from(["revolute", "prismatic"]), st.sampled_from(["ball", None, 1])),
         Arg(st.just(np.eye(4)), _poisoned(np.eye(4))))),
    Case("DHChain", lambda a, d: qpik.DHChain(a=a, d=d, alpha=(0.0,) * 7).fk(np.zeros(7)),
         (Arg(st.just((0.1,) * 7), _poisoned(np.full(7, 0.1))), Arg(st.just((0.2,) * 7), _poisoned(np.full(7, 0.2))))),
    Case("Controller.for_robot + step", _controller, (robot_arg(), pose_arg(PANDA), OBSTACLES,
         Arg(st.sampled_from(["osqp", "daqp"]), st.sampled_from([None, "nope", 3])), number_arg(50.0),
         number_arg(0.002, 0.0, 10.0), q_arg(PANDA))),
    Case("Controller.step target, twist", _steps, (ROBOT, q_arg(PANDA), pose_arg(PANDA),
         Arg(st.just(np.zeros(6)), _poisoned(np.zeros(6))))),
    Case("solve_best BestResult", _solve_best, (robot_arg((IIWA, NAMMOTO)), pose_arg(IIWA),
         Arg(st.sampled_from(["margin", "smooth-margin", "manipulability"]),
             st.sampled_from(["nope", None, 3, ["margin"]])),
         OBSTACLES, number_arg(0.02))),
    Case("ObjectiveTask", _objective_task, (robot_arg((IIWA, PANDA)),
         Arg(st.sampled_from([JointLimitMargin(smooth=True), Manipulability()]), st.sampled_from(["margin", None, 3])),
         number_arg(1e-2), q_arg(IIWA))),
    Case("solve_full FullResult", _solve_full, (robot_arg((PANDA, IIWA)), pose_arg(PANDA),
         Arg(st.sampled_from([None, "smooth-margin"]), st.sampled_from(["nope", 3, ["margin"]])), OBSTACLES,
         Arg(st.just(None), _poisoned(PANDA.q_home)), number_arg(0.02), Arg(st.just(2), INTS), Arg(st.just(0), INTS))),
    Case("objectives Evaluator", _objectives, (FLAG, number_arg(20.0, 0.0), number_arg(0.1, 0.0),
         Arg(st.just(np.ones(7)), _poisoned(np.ones(7))), number_arg(0.5),
         Arg(st.just(lambda q: q[0] ** 2), st.sampled_from([lambda q: "x", lambda q: q, lambda q: None, 3])))),
    Case("Controller.solve_ik", _solve_ik, (robot_arg((IIWA,)), q_arg(IIWA), pose_arg(IIWA),
         number_arg(1e-6, 0.0), Arg(st.just(20), st.sampled_from([0, -1, 1.5, "20", None])))),
    Case("Controller limits", _limits, (Arg(st.just(PANDA), None), number_arg(0.0),
         Arg(st.just(None), _poisoned(PANDA.q_min)), Arg(st.just(None), _poisoned(PANDA.v_max)),
         number_arg(0.02, 0.2), number_arg(0.5))),
    Case("Controller tasks", _tasks, (Arg(st.just(IIWA), None), pose_arg(IIWA),
         Arg(st.just(None), _poisoned(np.zeros(6))), number_arg(1e-3),
         Arg(st.sampled_from(["world", "se3"]), st.sampled_from(["SE3", None, 1])), q_arg(IIWA))),
    Case("CLIK", _clik, (Arg(st.sampled_from([clik.PseudoInverseCLIK, clik.DampedLeastSquares,
         clik.GradientProjection, clik.VelocityOnly]), None), robot_arg(), number_arg(20.0), number_arg(0.01, 0.0),
         q_arg(PANDA), pose_arg(PANDA))),
    Case("State", lambda r, q, dt: control.State(r, q, dt).J, (robot_arg(), q_arg(PANDA), number_arg(0.001))),
    Case("get_solver", get_solver, (Arg(st.sampled_from(["osqp", "daqp"]), st.sampled_from(["nope", "OSQP"])),)),
    Case("pose_error", control.pose_error, (pose_arg(IIWA), pose_arg(IIWA))),
    Case("so3_log", control.so3_log, (Arg(st.integers(0, 99).map(_rotations), _poisoned(np.eye(3))),)),
    Case("Sphere", geometry.Sphere, (VEC3, number_arg(0.1, 0.0, 1e7))),
    Case("Capsule", geometry.Capsule, (VEC3, VEC3, number_arg(0.1, 0.0))),
    Case("Box", lambda c, h, R, pr: geometry.Box(c, h, R, project=pr),
         (VEC3, Arg(st.just(np.full(3, 0.1)), _poisoned(np.full(3, 0.1))),
          Arg(st.integers(0, 99).map(_rotations), _poisoned(np.eye(3))), FLAG)),
    Case("HalfSpace", geometry.HalfSpace, (VEC3, number_arg(0.2, 1e7))),
    Case("shape_from_spec", geometry.shape_from_spec, (Arg(st.just(SPEC), _bad_specs()),)),
    Case("obstacles_from_specs", geometry.obstacles_from_specs, (Arg(st.just([SPEC]), _bad_specs()),)),
    Case("ObstacleSet", lambda shapes: len(geometry.ObstacleSet(shapes)), (OBSTACLES,)),
    Case("distances", geometry.distances, (SEGMENTS, RADII, OBSTACLES)),
    Case("distance", geometry.distance, (VEC3, VEC3, number_arg(0.05), Arg(st.sampled_from(SHAPES)))),
    Case("plan_self_motion", _plan, (robot_arg((IIWA, NAMMOTO)), Arg(st.just(PLAN_PATH), _poisoned(PLAN_PATH)),
         Arg(st.just(None), st.sampled_from(["nope", 3, object(), "margin"])),
         Arg(st.sampled_from([SHAPES[:1], []]), OBSTACLES.bad),
         number_arg(0.2, 0.0), Arg(st.sampled_from(["forbid", "fewest"]), st.sampled_from(["", None, 1])))),
    Case("Scene.of", lambda r, obs, d, obj, q: qpik.Scene.of(r, obs, d_safe=d, objective=obj, q_ref=q).clearance(
         r.q_home[None]), (robot_arg(), OBSTACLES, number_arg(0.02), Arg(st.sampled_from(["margin", "distance"]),
         st.sampled_from(["nope", 3, None])), Arg(st.just(None), _poisoned(PANDA.q_home)))),
    Case("plan_many", _plan_many, (robot_arg((IIWA, NAMMOTO)),
         Arg(st.just([PLAN_PATH, PLAN_PATH]), st.sampled_from([PLAN_PATH, [PLAN_PATH[:1]], [np.nan], "path", [None]])),
         Arg(st.sampled_from([SHAPES[:1], []]), OBSTACLES.bad), Arg(st.just(1), st.sampled_from([0, -1, 2.5, "2"])),
         Arg(st.sampled_from(["raise", "keep"]), st.sampled_from(["", None, "ignore"])))),
    Case("simulate", _simulate, (Arg(st.sampled_from([IIWA, PANDA]), st.sampled_from(["iiwa14", None, "<mujoco/>"])),
         q_arg(IIWA), OBSTACLES, number_arg(0.02), number_arg(0.01, 0.0),
         Arg(st.just(None), _bad_pose(IIWA.fk(IIWA.q_home))))),
]  # fmt: skip
SLOW_CASES = [
    Case("view", _view, (robot_arg((IIWA, PANDA)), pose_arg(IIWA), OBSTACLES,
         Arg(st.sampled_from(["margin", "manipulability"]), st.sampled_from(["nope", 3, None])), number_arg(0.02))),
    Case("crosscheck CrossCheck", _crosscheck, (robot_arg((IIWA, NAMMOTO)), pose_arg(IIWA),
         Arg(st.just("smooth-margin"), st.sampled_from(["margin", "nope", 3, None])), OBSTACLES, q_arg(IIWA),
         number_arg(0.02), Arg(st.just(0), INTS))),
]  # fmt: skip


# ---- the checks --------------------------------------------------------------------------


def check_output(out: object) -> None:
    """No NaN anywhere in an output (arrays, numbers, dataclasses, tuples); statuses from the documented sets."""
    if isinstance(out, qpik.StepInfo):
        assert out.status in STATUSES, out.status
        assert not np.isnan(out.min_clearance) and 0.0 <= out.relaxation <= 1.0
        return  # task_error is NaN without a FrameTask, as documented
    if isinstance(out, SimLog):
        for x in (out.q, out.v, out.ee, out.clearance, out.manipulability):
            assert not np.isnan(x).any()
        assert set(out.status) <= STATUSES | {""}
        return
    if isinstance(out, np.ndarray) and out.dtype.kind in "fc":
        assert not np.isnan(out).any()
    elif isinstance(out, float):
        assert not np.isnan(out)
    elif dataclasses.is_dataclass(out) and not isinstance(out, type):
        for f in dataclasses.fields(out):
            check_output(getattr(out, f.name))
        if isinstance(out, BestResult):
            check_output(out.branches)  # built when first read, not a field
    elif isinstance(out, tuple | list):
        for x in out:
            check_output(x)


def _call(case: Case, data) -> None:
    corruptible = [-1] + [i for i, a in enumerate(case.args) if a.bad is not None]
    bad = data.draw(st.sampled_from(corruptible), label="bad argument")
    args = [
        data.draw(st.one_of(a.bad, ANY_BAD) if i == bad else a.good, label=f"arg {i}") for i, a in enumerate(case.args)
    ]
    try:
        out = case.fn(*args)
    except qpik.QpikError:
        return
    check_output(out)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
@FUZZ
@given(data=st.data())
def test_public_call(case: Case, data):
    _call(case, data)


@pytest.mark.parametrize("case", SLOW_CASES, ids=[c.name for c in SLOW_CASES])
@FEW
@given(data=st.data())
def test_public_call_that_solves_several_problems(case: Case, data):
    _call(case, data)


@FUZZ
@given(line=st.sampled_from(["", *TOML.splitlines()]), new=TOML_VALUES)
def test_problem_loader(tmp_path_factory, line, new):
    """A problem file with one value replaced loads or raises ProblemFileError (never another error)."""
    try:
        problem = _problem(tmp_path_factory.mktemp("p"), _toml(line, new))
    except qpik.ProblemFileError:
        return
    check_output(problem.poses)
    for key, x in problem.solver.items():
        assert x is None or np.isfinite(x), key


def test_every_public_name_is_fuzzed_or_a_type():
    """Each callable of qpik.__all__, qpik.geometry and qpik.control is in the table or is a plain type
    (errors, records, bases, options whose fields the calls above fuzz): a new public function has to be added
    here."""
    covered = " ".join(c.name for c in CASES + SLOW_CASES)
    plain = {"QpikError", "InputError", "RotationError", "UnknownRobotError", "NoClosedFormError", "ProblemFileError",
             "UnreachableError", "InfeasibleError", "SolverError", "RenderUnavailable", "ViewerError", "StepInfo",
             "LinkCapsule", "Robot", "IKSolutions", "FeasibleIntervals", "CATALOG", "Shape", "Distances",
             "PairDistance", "QP", "Solution", "Solver", "Task", "Limit", "BoxLimit", "RowLimit", "CLIK",
             "Plan", "PlanningError", "BestOptions", "ControllerOptions", "PlanOptions",
             "ViewOptions"}  # fmt: skip
    names = {*qpik.__all__, *geometry.__all__, *control.__all__}
    tasks_and_limits = {"FrameTask", "PostureTask", "ManipulabilityTask", "DampingTask", "ConfigurationLimit",
                        "VelocityLimit", "ObstacleLimit", "PseudoInverseCLIK", "DampedLeastSquares",
                        "GradientProjection", "VelocityOnly", "Controller"}  # fmt: skip
    missing = sorted(n for n in names - plain - tasks_and_limits if n not in covered)
    assert not missing, f"not fuzzed: {missing}"
