"""Path tracking on the offset-wrist arm of Zheng et al. 2019: the QP controller against their CLIK schemes.

``problems/zheng2019_clik.toml`` holds the arm (``zheng7``, Zheng et al. 2019, Table I), the initial
configuration and the spatial curve of eq. (19), moved so that it starts at the initial pose
(the file explains that reading). Three controllers follow it from the same configuration, each
given the path's pose and feed-forward twist at every step, in closed loop on the MuJoCo twin:

- the QP controller (``qpik.Controller``, frame task with gains K = 50/s),
- pseudo-inverse CLIK with proportional feedback, Zheng et al. 2019, eq. (18) (``PseudoInverseCLIK``),
- velocity-only feed-forward, Zheng et al. 2019, Fig. 3a (``VelocityOnly``): no position feedback.

The file runs 6 s at dt = 1 ms; this example runs the first 4 s of it.

    python examples/clik_comparison.py [OUT]    # OUT: qpik-out/examples/clik_comparison/

Prints each controller's tracking errors (measured from the MuJoCo site pose) and writes
``tracking_errors.png`` (position and orientation error against time) and ``runs.npz``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from qpik import Controller, ControllerOptions
from qpik.control.clik import PseudoInverseCLIK, VelocityOnly
from qpik.plots.runs import plot_comparison
from qpik.problems import find_problem, load
from qpik.sim import SimOptions, simulate

DURATION = 4.0  # s
TRANSIENT = 1.0  # s: errors are compared after this (the file's [expected] transient)
GAIN = 50.0  # 1/s, position and orientation feedback (the file's kp_position, kp_orientation)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    problem = load(find_problem("zheng2019_clik"))
    robot, path = problem.robot, problem.path  # zheng7; path.pose(t), path.twist(t) in the base frame
    dt = float(problem.solver["dt"])  # 1 ms
    q0 = path.q0  # the paper's initial configuration, rad

    # No target yet: simulate() hands the path's pose and twist to every step. The QP's posture
    # and damping terms are faint (they would pull the hand off the path) and it has no
    # manipulability term, as in the file's runner.
    controllers = {
        "QP (OSQP)": Controller.for_robot(
            robot,
            dt=dt,
            q_ref=q0,
            options=ControllerOptions(
                position_gain=GAIN, orientation_gain=GAIN, posture_weight=1e-5, manipulability_weight=0.0, damping=1e-8
            ),
        ),
        "PD CLIK, eq. (18)": PseudoInverseCLIK(robot, GAIN, GAIN, dt=dt),
        "velocity-only, Fig. 3a": VelocityOnly(robot, dt=dt),
    }
    logs = [
        simulate(robot, ctrl, q0, DURATION, dt, target=path, options=SimOptions(record_every=10, label=label))
        for label, ctrl in controllers.items()
    ]

    print(
        f"{robot.name} on the path of Zheng et al. 2019, eq. (19), for {DURATION:g} s at dt = {dt:g} s, "
        f"K = {GAIN:g}/s; errors after t = {TRANSIENT:g} s (MuJoCo site pose vs path)"
    )
    head = f"{'controller':24} {'max pos err [mm]':>17} {'max rot err [rad]':>18} {'final pos err [mm]':>19}"
    print(head + f" {'max |v|/v_max':>14}")
    sums = [log.summary(TRANSIENT) for log in logs]
    for log, s in zip(logs, sums):
        print(
            f"{log.label:24} {s.max_pos_error * 1e3:17.6f} {s.max_rot_error:18.3e} {s.final_pos_error * 1e3:19.6f}"
            f" {s.max_velocity_ratio:14.3f}"
        )
    qp, pd, vel = sums
    print(f"velocity-only drift: {vel.max_pos_error / pd.max_pos_error:.1f}x the error of PD CLIK")
    print(
        f"Zheng et al. 2019 report 0.01 mm for eq. (18); here PD CLIK {pd.max_pos_error * 1e3:.4f} mm, "
        f"QP {qp.max_pos_error * 1e3:.4f} mm"
    )

    path_png = plot_comparison(logs, out / "tracking_errors.png", title="zheng7: tracking error on eq. (19)")
    print(f"\nwrote {path_png} (position and orientation error of the three controllers)")
    np.savez(
        out / "runs.npz",
        t=logs[0].t,
        q0=q0,
        labels=[log.label for log in logs],
        q=np.stack([log.q for log in logs]),
        transient=TRANSIENT,
    )
    print(f"wrote {out / 'runs.npz'} (t and q of each run)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
