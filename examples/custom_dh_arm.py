"""Your own arm from a DH table: forward kinematics, the closed form when the table fits, the QP otherwise.

1. An S-R-S arm (spherical shoulder and wrist, one elbow joint: the joint axes of the KUKA iiwa)
   with other link lengths. Its table has the form the closed form of Shimizu et al. 2008 is
   written for, so ``Robot(closed_form="srs")`` gives all 8 branches at any arm angle ψ.
2. An offset-wrist arm (the table of Zheng et al. 2019, Table I, with other lengths). No closed
   form applies; ``Controller.solve_ik`` iterates the QP (Gauss-Newton steps inside the joint
   limits) to one configuration reaching the pose.

    python examples/custom_dh_arm.py [OUT]    # OUT: qpik-out/examples/custom_dh_arm/

Prints the FK of both arms, the 8 branches of the S-R-S arm with their FK residuals, and the QP
answer of the offset-wrist arm. Writes ``arms.json``: both DH tables, limits, target poses and answers.
The arms' compiled functions are built on the first run (cached in ~/.cache/qpik).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import mujoco
import numpy as np

import qpik
from qpik.control import pose_error
from qpik.robots.robot import default_capsules

PI = np.pi


def make_robot(name: str, chain: qpik.DHChain, q_max_deg, closed_form) -> qpik.Robot:
    """A Robot from a DH chain: symmetric limits (deg), 1.5 rad/s on every joint, one capsule per link."""
    q_max = np.radians(q_max_deg)
    return qpik.Robot(
        name=name,
        chain=chain,
        q_min=-q_max,
        q_max=q_max,
        v_max=np.full(chain.dof, 1.5),  # rad/s
        q_home=np.zeros(chain.dof),
        capsules=default_capsules(chain, radii=(0.07, 0.07, 0.06, 0.06, 0.05, 0.05, 0.04)),  # m, per link
        closed_form=closed_form,
    )


def residual(robot: qpik.Robot, q: np.ndarray, pose: np.ndarray) -> tuple[float, float]:
    """FK error of q against pose: position (m) and rotation (rad)."""
    e = pose_error(pose, robot.fk(q))
    return float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    np.set_printoptions(precision=6, suppress=True)
    report = {}

    # 1. S-R-S: standard DH, a = 0, twists of the iiwa, lengths d = (base-shoulder, 0,
    #    shoulder-elbow, 0, elbow-wrist, 0, wrist-flange) in metres.
    srs = make_robot(
        "my_srs",
        qpik.DHChain(
            a=(0.0,) * 7,
            d=(0.30, 0.0, 0.45, 0.0, 0.38, 0.0, 0.10),
            alpha=(-PI / 2, PI / 2, PI / 2, -PI / 2, -PI / 2, PI / 2, 0.0),
        ),
        q_max_deg=(170, 120, 170, 120, 170, 120, 175),
        closed_form="srs",
    )
    q_goal = np.array([0.4, 0.7, -0.3, -1.3, 0.6, 0.8, -0.2])  # rad
    pose = srs.fk(q_goal)  # (4, 4) base frame, m
    print(f"1. {srs.name}: S-R-S, d = {srs.chain.d} m; fk(q) for q = {q_goal} rad:")
    print(pose)
    # The MJCF twin of the same table: MuJoCo puts its end-effector site at the same point.
    model = srs.mj_model()
    data = mujoco.MjData(model)
    data.qpos[:] = q_goal
    mujoco.mj_kinematics(model, data)
    print(f"   MuJoCo twin, site 'ee': position differs by {np.linalg.norm(data.site('ee').xpos - pose[:3, 3]):.1e} m")

    psi, branch = qpik.redundancy_parameter(srs, q_goal)  # the arm angle of q_goal and its branch
    sols = qpik.ik(srs, pose, psi)
    print(f"   closed form at ψ = {psi:.6f} rad (q_goal is branch {branch}):")
    print("   " + sols.table().replace("\n", "\n   "))
    print(f"   {'branch':>6} {'fk pos [m]':>11} {'fk rot [rad]':>13}")
    for b, q in zip(sols.branch, sols.q):
        pos, rot = residual(srs, q, pose)
        print(f"   {b:>6} {pos:11.2e} {rot:13.2e}")
    row = list(sols.branch).index(branch)
    print(f"   branch {branch} gives back q_goal to {np.abs(sols.q[row] - q_goal).max():.1e} rad")
    report["srs"] = {
        "dh": {"a": srs.chain.a, "d": srs.chain.d, "alpha": srs.chain.alpha, "offset": srs.chain.offset},
        "q_min": srs.q_min.tolist(),
        "q_max": srs.q_max.tolist(),
        "q_goal": q_goal.tolist(),
        "pose": pose.tolist(),
        "psi": psi,
        "branch": sols.branch.tolist(),
        "q": sols.q.tolist(),
        "valid": sols.valid.tolist(),
    }

    # 2. Offset wrist: the joint layout of Zheng et al. 2019, Table I (joints 2, 3 and 4 parallel,
    #    a wrist whose axes do not meet), with other lengths.
    wrist = make_robot(
        "my_offset_wrist",
        qpik.DHChain(
            a=(0.0, 0.45, 0.38, 0.0, 0.0, 0.0, 0.0),
            d=(0.16, 0.18, -0.18, 0.12, 0.12, 0.12, 0.09),
            alpha=(PI / 2, 0.0, 0.0, -PI / 2, PI / 2, -PI / 2, 0.0),
        ),
        q_max_deg=(170, 170, 170, 170, 170, 170, 175),
        closed_form=None,
    )
    q_goal2 = np.array([0.3, 1.0, -0.8, -1.5, 0.4, 1.2, -0.6])  # rad
    pose2 = wrist.fk(q_goal2)
    print(f"\n2. {wrist.name}: offset wrist, a = {wrist.chain.a} m, d = {wrist.chain.d} m; fk(q) for q = {q_goal2}:")
    print(pose2)
    try:
        qpik.ik(wrist, pose2, 0.0)
    except qpik.NoClosedFormError as exc:
        print(f"   qpik.ik: {exc}")
    q_start = np.array([0.0, 0.8, -0.5, -1.2, 0.0, 1.0, 0.0])  # rad, where the iteration starts
    ctrl = qpik.Controller.for_robot(wrist)
    q = ctrl.solve_ik(q_start, pose2)  # raises qpik.UnreachableError if no attempt converges
    pos, rot = residual(wrist, q, pose2)
    print(f"   Controller.solve_ik from {q_start}: q = {q} rad")
    print(
        f"   fk residual {pos:.1e} m, {rot:.1e} rad; within the limits: {wrist.within_limits(q)}; "
        f"max |q - q_goal| = {np.abs(q - q_goal2).max():.3f} rad (the arm is redundant: any point "
        "of the self-motion will do)"
    )
    report["offset_wrist"] = {
        "dh": {"a": wrist.chain.a, "d": wrist.chain.d, "alpha": wrist.chain.alpha, "offset": wrist.chain.offset},
        "q_min": wrist.q_min.tolist(),
        "q_max": wrist.q_max.tolist(),
        "q_goal": q_goal2.tolist(),
        "pose": pose2.tolist(),
        "q_start": q_start.tolist(),
        "q": q.tolist(),
    }

    (out / "arms.json").write_text(json.dumps(report, indent=1))
    print(f"\nwrote {out / 'arms.json'} (DH tables, limits, poses and answers, full precision)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
