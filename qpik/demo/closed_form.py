"""Demo section: the closed form — Table 4 of Nammoto & Kosuge 2012, self-motion maps, branch poses, the p_z sweep."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qpik.analytic.api import ik, redundancy_parameter
from qpik.analytic.intervals import wrap
from qpik.plots import save
from qpik.plots.closed_form import branch_pictures, selfmotion_map, sweep_figure, symbol
from qpik.problems import find_problem, load

TITLE = "Closed-form IK"


def run(out: Path) -> None:
    _table4(out)
    _iiwa(out)
    _pz_sweep(out)


def _table4(out: Path) -> None:
    """Nammoto & Kosuge 2012 Table 4: the 16 branches at δ = -0.80, against the paper's rounded rows."""
    problem = load(find_problem("nammoto2012_table4"))
    robot, T, delta = problem.robot, problem.poses[0], float(problem.params[0])
    sols = ik(robot, T, delta)
    paper = problem.expected["q"]
    fk = robot.fk(sols.q)
    print(f"nammoto7, pose of eqs. (33)-(36) projected onto SO(3), δ = {delta:.2f} rad: all 16 branches")
    print(f"{'no.':>4} {'θ1..θ7 (qpik, rad)':^48} {'max |Δ| vs Table 4':>19} {'fk err [m]':>11}")
    for i, b in enumerate(sols.branch):
        row = " ".join(f"{v:6.2f}" for v in sols.q[i])
        d = np.abs(wrap(sols.q[i] - paper[i])).max()
        err = np.linalg.norm(fk[i, :3, 3] - T[:3, 3])
        print(f"{b:>4} {row} {d:19.3f} {err:11.1e}")
    files = [
        (
            save(selfmotion_map(robot, T), out / "closed_form_selfmotion_nammoto7.png"),
            "each joint against δ, 16 branches",
        ),
    ]
    how = branch_pictures(robot, sols, out / "closed_form_branches_nammoto7.png")
    files.append(
        (out / "closed_form_branches_nammoto7.png", f"the 16 poses of Table 4 (Nammoto & Kosuge 2012, Fig. 10; {how})")
    )
    _print_files(files)


def _iiwa(out: Path) -> None:
    """KUKA iiwa 14: the 8 S-R-S branches at the arm angle of one configuration."""
    problem = load(find_problem("shimizu2008_iiwa"))
    robot, T, q = problem.robot, problem.poses[0], problem.q_targets[0]
    psi, branch = redundancy_parameter(robot, q)
    sols = ik(robot, T, psi)
    print(f"\niiwa14, pose = fk({np.array2string(q, precision=3)}): ψ = {psi:.4f} rad, branch {branch}")
    valid, inside = sols.branch[sols.valid].tolist(), sols.branch[sols.within_limits].tolist()
    print(f"  valid branches: {valid}, within limits: {inside}")
    how = branch_pictures(robot, sols, out / "closed_form_branches_iiwa14.png")
    save(selfmotion_map(robot, T, shade_branch=branch), out / "closed_form_selfmotion_iiwa14.png")
    _print_files(
        [
            (
                out / "closed_form_selfmotion_iiwa14.png",
                f"each joint against ψ, 8 branches; grey: branch {branch} out of limits",
            ),
            (out / "closed_form_branches_iiwa14.png", f"the 8 branches at ψ = {psi:.2f} ({how})"),
        ]
    )


def _pz_sweep(out: Path) -> None:
    """Nammoto & Kosuge 2012 Figs. 15/16: branch 1 as p_z goes 0.3 -> 0.9 m, at δ = 0 and δ = 0.70."""
    problem = load(find_problem("nammoto2012_joint_limits"))
    robot, poses = problem.robot, problem.poses
    pz = poses[:, 2, 3]
    curves = []
    print(f"\nnammoto7, hand pointing down at (-0.18, 0.41, p_z), p_z = {pz[0]:.1f} -> {pz[-1]:.1f} m, branch 1:")
    for delta in problem.params:
        sols = ik(robot, poses, np.full(len(poses), delta))
        q, ok = sols.q[:, 0], sols.valid[:, 0]
        th6 = q[ok, 5]
        print(
            f"  {symbol(sols.param_name)} = {delta:.2f}: θ6 from {q[0, 5]:+.2f} (p_z = {pz[0]:.1f}) to "
            f"{q[-1, 5]:+.2f} (p_z = {pz[-1]:.1f}) rad, range {np.ptp(th6):.2f} rad; all valid: {bool(ok.all())}"
        )
        curves.append((f"Fig. {15 + len(curves)}: δ = {delta:.2f} rad", q, ok))
    print("  paper: θ6 grows as p_z falls at δ = 0 and saturates at δ = 0.70 (choosing δ avoids its limit)")
    path = out / "closed_form_pz_sweep.png"
    save(sweep_figure(robot, pz, curves, "p_z [m]", "nammoto7, branch 1: joint angles against p_z"), path)
    _print_files([(path, "joint angles of branch 1 against p_z at δ = 0 and 0.70 (Nammoto & Kosuge 2012 Figs. 15/16)")])


def _print_files(files: list[tuple[Path, str]]) -> None:
    for path, what in files:
        print(f"  {Path(path).name}: {what}")
