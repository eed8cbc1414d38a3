"""The QP controller in closed loop on the MuJoCo twin: a KUKA iiwa 14 reaches down past a ball to a table.

Each control step is one QP over the joint velocity v (``qpik.Controller``): track the target
pose (frame task), stay near a posture, respect the joint position and velocity limits, and keep
every link capsule away from every obstacle with a velocity damper
``ḋ ≥ -ξ (d - d_s)/(d_i - d_s)``. ``qpik.sim.simulate`` runs it on the robot's MJCF twin with
the obstacles added as MuJoCo geoms, and measures the clearances with MuJoCo's own
``mj_geomDistance``, not with the controller's distance code.

    python examples/controller_obstacles.py [OUT]    # OUT: qpik-out/examples/controller_obstacles/

Prints the final pose error, the smallest clearance to each obstacle (MuJoCo), joint-limit and
velocity-limit figures, and the same run without the obstacle limit. Writes ``run.png`` (errors,
clearances, joints), ``strip.png`` (snapshots, when OpenGL is available) and ``run.npz``.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.geometry import HalfSpace, Sphere
from qpik.plots.runs import plot_log, render_strip
from qpik.render.pictures import unavailable_reason
from qpik.sim import SimOptions, simulate

DT = 0.002  # s, control period (and integration step)
DURATION = 3.0  # s
D_SAFE, D_INFLUENCE, XI = 0.03, 0.12, 0.3  # m, m, m/s: the velocity damper


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    iiwa = qpik.load_robot("iiwa14")
    # The arm stands on the table. Link 1 only turns about the vertical axis and its capsule
    # reaches 8 cm below the base, into the table, whatever the joints do: leave it out of the
    # collision model (controller and clearance log) rather than report a constant overlap.
    robot = dataclasses.replace(iiwa, capsules=iiwa.capsules[1:])

    ball = Sphere(center=(0.30, 0.22, 0.64), radius=0.07, name="ball")  # where the elbow would pass
    # The table is the solid normal·x <= offset: z <= 2 mm, just above the floor that the twin
    # draws (a plane exactly on it would flicker in the pictures).
    table = HalfSpace(normal=(0, 0, 1), offset=0.002, name="table")
    obstacles = [ball, table]
    target = np.eye(4)
    target[:3, :3] = np.diag([1.0, -1.0, -1.0])  # tool z axis pointing down
    target[:3, 3] = (0.35, 0.55, 0.10)  # m: 5 cm between the hand capsule and the table

    def controller(obs):
        """Frame task (gains 1/s), weak posture pull toward q_home, joint limits, dampers for ``obs``."""
        options = qpik.ControllerOptions(position_gain=10.0, orientation_gain=10.0, posture_weight=1e-5,
                                         manipulability_weight=0.0, d_influence=D_INFLUENCE, xi=XI)  # fmt: skip
        return qpik.Controller.for_robot(robot, target=target, obstacles=obs, dt=DT, d_safe=D_SAFE, options=options)

    # Closed loop on the twin from the home configuration, a record every 5 steps (10 ms). The
    # obstacles are in the MuJoCo scene of both runs; only the first controller knows them.
    scene = dict(obstacles=obstacles, target=target)
    log = simulate(
        robot,
        controller(obstacles),
        robot.q_home,
        DURATION,
        DT,
        **scene,
        options=SimOptions(record_every=5, d_safe=D_SAFE, label="with obstacle limit"),
    )
    free = simulate(
        robot,
        controller(()),
        robot.q_home,
        DURATION,
        DT,
        **scene,
        options=SimOptions(record_every=5, d_safe=D_SAFE, label="without obstacle limit"),
    )

    s = log.summary()
    print(f"iiwa14 from q_home to p* = {target[:3, 3]} m (tool down), {DURATION:g} s at dt = {DT:g} s")
    print(
        f"final error (MuJoCo site vs target): position {s.final_pos_error:.4e} m, "
        f"orientation {s.final_rot_error:.4e} rad"
    )
    print(f"min clearance measured by MuJoCo (d_s = {D_SAFE * 1e3:g} mm, d_i = {D_INFLUENCE * 1e3:g} mm):")
    for o, name in enumerate(log.obstacle_names):
        d = log.clearance[:, :, o]  # (records, links), m
        k, link = np.unravel_index(np.argmin(d), d.shape)
        print(f"  {name}: {d[k, link] * 1e3:.4f} mm ({log.link_names[link]}, t = {log.t[k]:.2f} s)")
    print(
        f"joint limits: max violation {s.max_limit_violation:.3g} rad, min margin {s.min_limit_margin:.4f} rad; "
        f"max |v|/v_max = {s.max_velocity_ratio:.4f}"
    )
    print(
        f"controller: {', '.join(f'{k} x{n}' for k, n in s.statuses.items())} (recorded steps); "
        f"median QP solve {s.solve_time['median'] * 1e6:.0f} µs"
    )
    ball_free = free.clearance[:, :, log.obstacle_names.index("ball")].min()
    print(f"without the obstacle limit the arm goes through the ball: min clearance {ball_free * 1e3:.4f} mm")

    plot_log(log, out / "run.png", title="iiwa14 past a ball to a table (QP controller, MuJoCo twin)")
    print(f"\nwrote {out / 'run.png'} (errors, clearance per link, manipulability, joints)")
    reason = unavailable_reason()  # why MuJoCo cannot render here, or None
    if reason:
        print(f"snapshot strip skipped: {reason}")
    else:
        render_strip(log, out / "strip.png")
        print(f"wrote {out / 'strip.png'} (snapshots along the run)")
    np.savez(
        out / "run.npz",
        t=log.t,
        q=log.q,
        v=log.v,
        q_free=free.q,
        target=target,
        dt=DT,
        ball_center=ball.center,
        ball_radius=ball.radius,
        table_normal=table.normal,
        table_offset=table.offset,
    )
    print(f"wrote {out / 'run.npz'} (t, q, v of the run, q of the run without the limit, target, obstacles)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
