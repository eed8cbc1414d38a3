"""Bring your own arm: the Franka Panda from a package's URDF, controlled past a ball in MuJoCo on its own model.

``qpik.load_robot`` reads the URDF of the ``example-robot-data`` package (installed with
``pip install -e '.[test]'``; its mesh paths are ``package://example-robot-data/...``, resolved
against the package's own folders) through MuJoCo: a serial chain from the world to the hand,
the joint limits and the URDF's velocity limits, and one capsule per link fitted around the
link's collision meshes. The QP controller (``qpik.Controller``) then drives it from the Franka
"ready" configuration to a goal pose while a ball sits where link 6 would pass, and
``qpik.sim.simulate`` runs it on the URDF's own MuJoCo model: clearances are MuJoCo's distances
between the Panda's collision meshes and the ball, not the capsules the controller uses.

    python examples/package_arm.py [OUT]    # OUT: qpik-out/examples/package_arm/

Prints the model file, the joints with their limits, the capsules, why the Panda has no closed
form, and for the run with and without the obstacle limit: the final pose error, the smallest
clearance of the meshes to the ball, and the joint-limit figures. Writes ``run.png`` (errors,
clearances, joints), ``strip.png`` (snapshots with the capsules drawn, when OpenGL is available)
and ``run.npz`` (t, q, target, ball, the model file).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.geometry import Sphere
from qpik.plots.runs import plot_log, render_strip
from qpik.render.pictures import unavailable_reason
from qpik.robots.packaged import packaged_model
from qpik.sim import SimOptions, simulate

DT = 0.002  # s, control period (and integration step)
DURATION = 3.0  # s
D_SAFE, D_INFLUENCE = 0.02, 0.10  # m: the velocity damper's safety and influence distances


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    path = packaged_model("erd/panda")  # .../example-robot-data/robots/panda_description/urdf/panda.urdf
    panda = qpik.load_robot(path)  # the chain from the world to panda_hand (the fingers are left at 0)
    print(f"model: {path}")
    print(f"{panda.name}: {panda.dof} joints, end effector {panda.model.tip_body!r}")
    for name, lo, hi, v in zip(panda.joint_names, panda.q_min, panda.q_max, panda.v_max):
        print(f"  {name:13} [{lo: .4f}, {hi: .4f}] rad, |v| <= {v:.4f} rad/s")
    radii = ", ".join(f"{c.radius * 1e3:.1f}" for c in panda.capsules)
    print(f"capsules around the collision meshes, radius (mm) of links 1-{panda.dof}: {radii}")
    print(panda.notes)  # which closed form the axes admit (for the Panda: q7 locked), or why none

    q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])  # Franka's "ready"
    goal = np.array([1.2, 0.3, 0.0, -1.9, 0.0, 2.2, 0.4])
    target = panda.fk(goal)  # a reachable pose, m and rad (base frame)
    # the ball: on link 6's capsule half way along the straight joint path from q0 to the goal
    seg = panda.capsule_segments(0.5 * (q0 + goal))[5]
    ball = Sphere(center=seg.mean(axis=0), radius=0.05, name="ball")

    def controller(obstacles):
        return qpik.Controller.for_robot(
            panda, target=target, obstacles=obstacles, dt=DT, d_safe=D_SAFE,
            options=qpik.ControllerOptions(d_influence=D_INFLUENCE),
        )  # fmt: skip

    scene = dict(obstacles=[ball], target=target)
    log = simulate(
        panda,
        controller([ball]),
        q0,
        DURATION,
        DT,
        **scene,
        options=SimOptions(record_every=5, d_safe=D_SAFE, label="with obstacle limit"),
    )
    free = simulate(
        panda,
        controller(()),
        q0,
        DURATION,
        DT,
        **scene,
        options=SimOptions(record_every=5, d_safe=D_SAFE, label="without obstacle limit"),
    )

    print(f"\nfrom Franka's ready pose to p* = {np.round(target[:3, 3], 4)} m, {DURATION:g} s at dt = {DT:g} s")
    for run in (log, free):
        s = run.summary()
        d = run.clearance[:, :, 0]  # (records, collision geoms), m, by MuJoCo
        k, g = np.unravel_index(np.argmin(d), d.shape)
        print(f"{run.label}:")
        print(f"  final error: position {s.final_pos_error:.4e} m, orientation {s.final_rot_error:.4e} rad")
        where = f"{run.link_names[g]}, t = {run.t[k]:.2f} s"
        print(f"  min clearance of the meshes to the ball: {d[k, g] * 1e3:.4f} mm ({where})")
        print(f"  joint limits: max violation {s.max_limit_violation:.3g} rad, min margin {s.min_limit_margin:.4f} rad")

    plot_log(log, out / "run.png", title="Panda (example-robot-data URDF) past a ball, QP controller, MuJoCo")
    print(f"\nwrote {out / 'run.png'} (errors, clearance per collision mesh, manipulability, joints)")
    reason = unavailable_reason()  # why MuJoCo cannot render here, or None
    if reason:
        print(f"snapshot strip skipped: {reason}")
    else:
        render_strip(log, out / "strip.png")
        print(f"wrote {out / 'strip.png'} (snapshots along the run, capsules drawn translucent)")
    np.savez(
        out / "run.npz",
        t=log.t,
        q=log.q,
        q_free=free.q,
        target=target,
        ball_center=ball.center,
        ball_radius=ball.radius,
        model=str(path),
        joint_names=np.array(panda.joint_names),
    )
    print(f"wrote {out / 'run.npz'} (t, q with and without the limit, target, ball, model file, joint names)")


if __name__ == "__main__":
    try:
        main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
    except qpik.InputError as error:  # example-robot-data not installed: say so in one line
        sys.exit(f"{Path(__file__).name}: {error}")
