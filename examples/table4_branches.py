"""All 16 closed-form branches of Table 4 of Nammoto & Kosuge 2012, each checked by forward kinematics.

The arm is ``nammoto7`` (offset shoulder, Nammoto & Kosuge 2012, Tables 1 and 3). The pose is
eqs. (33)-(36): the columns n, t, b of the rotation and the position p. The paper rounds the
rotation to 2 decimals (det = 1.008), so it is projected onto SO(3) first. The redundancy
parameter is δ = -0.80 rad (eq. (37)): θ1 = atan2(w_y, w_x) + δ, w the wrist centre (eq. 4).

    python examples/table4_branches.py [OUT]    # OUT: qpik-out/examples/table4_branches/

Prints qpik's branch table, then each branch's FK residual and its largest difference to the
paper's Table 4 (which is rounded to 2 decimals). Writes ``branches.csv`` (every branch, full
precision) and ``branches.png`` (the 16 poses: MuJoCo pictures, or stick figures without OpenGL).
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.analytic.intervals import wrap
from qpik.control import pose_error
from qpik.plots.closed_form import branch_pictures
from qpik.problems import find_problem, load


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)

    # problems/nammoto2012_table4.toml holds the pose, δ and the paper's Table 4 ([expected] q).
    problem = load(find_problem("nammoto2012_table4"))
    robot = problem.robot  # nammoto7
    pose = problem.poses[0]  # (4, 4), base frame, m; its rotation already projected (project = true in the file)
    delta = float(problem.params[0])  # rad
    paper = problem.expected["q"]  # (16, 7), rad, row i = branch i + 1

    # The same pose written inline (as in the README):
    #   pose = np.eye(4)
    #   pose[:3, :3] = [[0.18, 0.63, 0.76], [-0.16, 0.78, -0.61], [-0.97, -0.01, 0.25]]
    #   pose[:3, 3] = (-0.18, 0.41, 0.41)
    #   sols = qpik.ik(robot, pose, -0.80, project=True)
    sols = qpik.ik(robot, pose, delta)

    np.set_printoptions(precision=6, suppress=True)
    print(f"{robot.name}: Nammoto & Kosuge 2012, eqs. (33)-(36), rotation projected onto SO(3):")
    print(pose)
    print(f"\nall {len(sols)} branches at δ = {delta:.2f} rad (q in rad, wrapped to (-π, π]):")
    print(sols.table())

    # Check every branch by forward kinematics: the pose error [Δp; log(R* Rᵀ)] of fk(q) (m; rad).
    residual = np.array([pose_error(pose, robot.fk(q)) for q in sols.q])
    pos_err = np.linalg.norm(residual[:, :3], axis=1)
    rot_err = np.linalg.norm(residual[:, 3:], axis=1)
    vs_paper = np.abs(wrap(sols.q - paper)).max(axis=1)  # the paper prints 2 decimals
    print("\nforward kinematics of each branch, and the paper's Table 4:")
    print(f"{'branch':>6} {'fk pos [m]':>11} {'fk rot [rad]':>13} {'max |q - Table 4| [rad]':>24}")
    for b, p, r, d in zip(sols.branch, pos_err, rot_err, vs_paper):
        print(f"{b:>6} {p:11.2e} {r:13.2e} {d:24.3f}")
    print(
        f"largest FK residual: {pos_err.max():.1e} m, {rot_err.max():.1e} rad; "
        f"largest difference to Table 4: {vs_paper.max():.3f} rad"
    )

    with open(out / "branches.csv", "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["branch", "valid", "within_limits", "singular", *(f"q{j + 1}" for j in range(robot.dof))])
        for i, b in enumerate(sols.branch):
            flags = (int(sols.valid[i]), int(sols.within_limits[i]), int(sols.singular[i]))
            writer.writerow([int(b), *flags, *(repr(float(v)) for v in sols.q[i])])
    # MuJoCo pictures of the twin when OpenGL works here, else matplotlib stick figures
    how = branch_pictures(robot, sols, out / "branches.png")
    print(f"\nwrote {out / 'branches.csv'} (q of every branch, full precision)")
    print(
        f"wrote {out / 'branches.png'} (the 16 poses, one picture per placement of the links,"
        f" {'MuJoCo' if how == 'render' else 'stick figures'})"
    )


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
