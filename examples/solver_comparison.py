"""One control step's QP, solved by every installed QP backend and by mink on the MJCF twin.

The QP is recorded from a KUKA iiwa 14 controller at its first step toward a target, with a ball
next to the forearm: the velocity damper of that ball and several joint velocity bounds are active.
Each backend of ``qpik.control.solvers.get_solver`` solves the recorded arrays; their answers are
compared with DAQP's, an exact active-set solution. mink (``mink.solve_ik``) builds the same
problem on its own from the MJCF twin (MuJoCo kinematics, mink's tasks and limits) and solves it
with DAQP through qpsolvers.

    python examples/solver_comparison.py [OUT]    # OUT: qpik-out/examples/solver_comparison/

Prints each answer's largest difference to DAQP's (rad/s) and its median wall time. A backend's
time is one solve of the recorded arrays by a new solver object (OSQP's setup and factorisation
included, no warm start); osqp, daqp and proxqp are called directly, the others through qpsolvers
(its conversion included). mink's time and qpik's ``Controller.step`` time are a whole step:
kinematics, building the QP and solving it. Writes ``qp.npz``: the QP arrays, the configuration
and every answer.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import mink
import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

import qpik
from qpik.control import (
    ConfigurationLimit,
    Controller,
    DampingTask,
    FrameTask,
    ObstacleLimit,
    PostureTask,
    VelocityLimit,
    get_solver,
)
from qpik.core.errors import SolverError
from qpik.geometry import Sphere
from qpik.robots.mjcf import to_mjcf

DT = 0.01  # s
D_I, D_S, XI, BUFFER = 0.10, 0.02, 0.5, 1e-3  # the velocity damper: m, m, m/s, m
# mink's task costs and gains (a gain is the fraction of the error removed per step)
COST_P, COST_O, GAIN, COST_Q, GAIN_Q, COST_D = 1.0, 0.5, 0.1, 0.1, 0.1, 0.01
# "osqp" and "daqp" always come with qpik; get_solver raises SolverError for a backend that is not
# installed (proxqp, quadprog, clarabel, piqp: pip install -e ".[test]"; highs, qpoases: qpsolvers'
# other exact solvers, installed separately).
BACKENDS = ("osqp", "daqp", "proxqp", "quadprog", "clarabel", "piqp", "highs", "qpoases")
# Interior-point backends stop at their default tolerances (clarabel: ~1e-5 rad/s off here); these
# are the tolerances tests/control/test_solvers.py uses.
OPTIONS = {
    "clarabel": {"tol_gap_abs": 1e-11, "tol_gap_rel": 1e-11, "tol_feas": 1e-11},
    "piqp": {"eps_abs": 1e-12, "eps_rel": 1e-12, "eps_duality_gap_abs": 1e-12, "eps_duality_gap_rel": 1e-12},
}
REPEATS = 20


def median_time(fn) -> float:
    """Median wall time (s) of ``fn()`` over REPEATS calls."""
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home.copy()
    target = robot.fk(q)  # 20-30 cm away, turned by 0.36 rad
    target[:3, 3] += (0.15, 0.10, -0.20)
    target[:3, :3] = Rotation.from_rotvec([0.3, 0.0, 0.2]).as_matrix() @ target[:3, :3]
    forearm = robot.capsule_segments(q)[4]  # capsule of link 5, (2, 3) end points
    ball = Sphere(forearm.mean(axis=0) - (0, 0, 0.155), 0.05, name="ball")  # 4 cm under it

    # The tasks in qpik's terms. mink minimises ½ Σ ‖c_i (J_i Δq + g_i e_i)‖² over Δq = v·dt with the
    # body-frame SE(3) error; divided by dt²/2 that is qpik's weights c², gains g/dt and error="se3"
    # (the derivation is in tests/control/test_controller.py).
    tasks = [
        FrameTask(target, GAIN / DT, GAIN / DT, COST_P**2, COST_O**2, error="se3"),
        PostureTask(robot.q_home, GAIN_Q / DT, COST_Q**2),
        DampingTask(COST_D**2),
    ]
    limits = [ConfigurationLimit(), VelocityLimit(), ObstacleLimit([ball], D_I, D_S, XI, BUFFER)]
    ctrl = Controller(robot, tasks, limits, solver="daqp", dt=DT)
    ctrl.step(q)
    qp = ctrl.assembler.build(q).copy()  # the step's QP (the assembler reuses its buffers: copy it)
    active = ctrl.last.active
    print(
        f"iiwa14 at q_home, dt = {DT:g} s: QP with n = {qp.n} joint velocities, box lb <= v <= ub, "
        f"{len(qp.l)} damper rows (one per link capsule)"
    )
    print(f"  active at the solution: {', '.join(active)}")
    print(f"  smallest capsule-ball distance {ctrl.last.min_clearance * 1e3:.1f} mm (d_i = {D_I * 1e3:g} mm)")

    ref = get_solver("daqp").solve(qp).x  # exact active-set answer
    answers = {}
    print(f"\n{'solver':34} {'max |v - v_daqp| [rad/s]':>25} {'time [µs]':>10}  what is timed (median of {REPEATS})")
    for name in BACKENDS:
        options = OPTIONS.get(name, {})
        try:
            get_solver(name, **options)
        except SolverError:
            print(f"{name:34} {'not installed: skipped':>25}")
            continue
        sol = get_solver(name, **options).solve(qp)
        label = name + (" (tight tolerances)" if options else "")
        if not sol.found:
            print(f"{label:34} {'no solution: ' + sol.status:>25}")
            continue
        answers[name] = sol.x
        # a new solver object each time: OSQP's setup (factorisation) is included, no warm start
        t = median_time(lambda name=name, options=options: get_solver(name, **options).solve(qp))
        print(f"{label:34} {np.abs(sol.x - ref).max():25.2e} {t * 1e6:10.1f}  one solve, new solver object")

    # mink: the same tasks and limits, built by mink from the MJCF twin with the ball as a geom.
    model = mujoco.MjModel.from_xml_string(to_mjcf(robot, [ball.to_mjcf_geom()]))
    conf = mink.Configuration(model)
    frame = mink.FrameTask("ee", "site", position_cost=COST_P, orientation_cost=COST_O, gain=GAIN)
    frame.set_target(mink.SE3.from_matrix(target))
    posture = mink.PostureTask(model, cost=COST_Q, gain=GAIN_Q)
    posture.set_target(robot.q_home)
    mink_tasks = [frame, posture, mink.DampingTask(model, cost=COST_D)]
    capsules = [f"link{k}_capsule" for k in range(1, robot.dof + 1)]
    mink_limits = [
        mink.ConfigurationLimit(model, gain=1.0, min_distance_from_limits=0.0),
        mink.VelocityLimit(model, {f"joint{j + 1}": robot.v_max[j] for j in range(robot.dof)}),
        # mink 1.3 bounds the approach per step by gain·(d - d_min)/dt; qpik's damper allows
        # ξ·dt·(d - d_s - δ)/(d_i - d_s - δ): the same row with gain = ξ·dt²/(d_i - d_s - δ).
        mink.CollisionAvoidanceLimit(
            model,
            [(capsules, ["ball"])],
            gain=XI * DT**2 / (D_I - D_S - BUFFER),
            minimum_distance_from_collisions=D_S + BUFFER,
            collision_detection_distance=D_I,
        ),
    ]

    def mink_step():
        conf.update(q)
        return mink.solve_ik(conf, mink_tasks, DT, solver="daqp", limits=mink_limits)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # qpsolvers may warn about dense matrices
        answers["mink"] = v_mink = mink_step()
        t_mink = median_time(mink_step)
    t_qpik = median_time(lambda: ctrl.step(q))
    d_mink = np.abs(v_mink - ref).max()
    print(f"{'mink.solve_ik (daqp)':34} {d_mink:25.2e} {t_mink * 1e6:10.1f}  kinematics + building its QP + solve")
    print(
        f"{'qpik Controller.step (daqp)':34} {np.abs(ctrl.step(q) - ref).max():25.2e} {t_qpik * 1e6:10.1f}"
        "  kinematics + building the QP + solve"
    )

    np.savez(
        out / "qp.npz",
        q=q,
        P=qp.P,
        c=qp.c,
        A=qp.A,
        l=qp.l,
        u=qp.u,
        lb=qp.lb,
        ub=qp.ub,
        **{f"x_{name}": x for name, x in answers.items()},
    )
    print(f"\nwrote {out / 'qp.npz'} (the QP: ½ vᵀPv + cᵀv, l <= Av <= u, lb <= v <= ub; and every answer x_<solver>)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
