"""Demo section: the closed form — Table 4 of Nammoto & Kosuge 2012, self-motion maps, branch poses, the p_z sweep."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qpik.analytic.api import ik, redundancy_parameter
from qpik.analytic.intervals import wrap
from qpik.plots import save
from qpik.plots.closed_form import branch_pictures, flip_lines, same_links, selfmotion_map, sweep_figure, symbol
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
    _print_groups(robot, sols)
    files.append(
        (
            out / "closed_form_branches_nammoto7.png",
            f"the 16 poses of Table 4 (Nammoto & Kosuge 2012, Fig. 10; {how}), one picture per placement of the links",
        )
    )
    _print_files(files)


def _print_groups(robot, sols) -> None:
    """Which branches put every link at the same place, and how their joint angles differ (checked numerically)."""
    ids = sols.branch.tolist()
    groups = same_links(robot, sols.q)
    sets = "; ".join(", ".join(str(ids[k]) for k in g) for g in groups)
    print(f"  the links lie at the same place (to 1e-9 m) within each of: {sets}")
    for line in flip_lines(ids, sols.q, groups):
        print(f"    {line}")


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
    _print_groups(robot, sols)
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
    """Nammoto & Kosuge 2012 Figs. 15/16: branch 1 as p_z goes 0.3 -> 0.9 m, at δ = 0 and δ = 0.70; what θ6 does
    against the catalog's limit of θ6, checked at every sample."""
    problem = load(find_problem("nammoto2012_joint_limits"))
    robot, poses = problem.robot, problem.poses
    pz = poses[:, 2, 3]
    curves = []
    print(f"\nnammoto7, hand pointing down at (-0.18, 0.41, p_z), p_z = {pz[0]:.1f} -> {pz[-1]:.1f} m, branch 1:")
    facts = theta6_limits(problem)
    hi = float(robot.q_max[5])
    for (delta, q, ok), (_, peak, at, runs) in zip(_branch1(problem), facts):
        where = (f"past its limit {hi:+.2f} rad for p_z from " + ", ".join(f"{a:.2f} to {b:.2f} m" for a, b in runs)
                 if runs else f"inside its limits (±{hi:.2f} rad) at every p_z")  # fmt: skip
        print(
            f"  {symbol('delta')} = {delta:.2f}: θ6 from {q[0, 5]:+.2f} (p_z = {pz[0]:.1f}) to {q[-1, 5]:+.2f}"
            f" (p_z = {pz[-1]:.1f}) rad, largest {peak:+.2f} rad at p_z = {at:.2f} m: {where};"
            f" every IK valid: {bool(ok.all())}"
        )
        curves.append((f"Fig. {15 + len(curves)}: δ = {delta:.2f} rad", q, ok))
    print("  paper: θ6 grows as p_z falls at δ = 0 and saturates at δ = 0.70, which keeps it from its limit")
    print("  here: " + theta6_verdict(facts, hi))
    path = out / "closed_form_pz_sweep.png"
    title = "nammoto7, branch 1: joint angles against p_z (limits: qpik's catalog; the paper gives none)"
    save(sweep_figure(robot, pz, curves, "p_z [m]", title), path)
    _print_files(
        [
            (
                path,
                "joint angles of branch 1 against p_z at δ = 0 and 0.70 (Nammoto & Kosuge 2012 Figs. 15/16),"
                " θ6's limits dashed, × outside them",
            )
        ]
    )


def _branch1(problem) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``(δ, q (S, n), valid (S,))`` of branch 1 along the sweep, per δ of the problem."""
    out = []
    for delta in problem.params:
        sols = ik(problem.robot, problem.poses, np.full(len(problem.poses), delta))
        out.append((float(delta), sols.q[:, 0], sols.valid[:, 0]))
    return out


def theta6_limits(problem) -> list[tuple[float, float, float, list[tuple[float, float]]]]:
    """Per δ of the p_z sweep: ``(δ, largest θ6 (rad), its p_z (m), the p_z runs (first, last sample, m) where θ6 is
    outside its limits)``, from branch 1's IK at every sample."""
    robot, pz = problem.robot, problem.poses[:, 2, 3]
    out = []
    for delta, q, ok in _branch1(problem):
        th6 = np.where(ok, q[:, 5], np.nan)
        past = ok & ((q[:, 5] < robot.q_min[5]) | (q[:, 5] > robot.q_max[5]))
        cuts = np.flatnonzero(np.diff(past.astype(int))) + 1
        runs = [(float(pz[seg[0]]), float(pz[seg[-1]])) for seg in np.split(np.arange(len(pz)), cuts) if past[seg[0]]]
        k = int(np.nanargmax(th6))
        out.append((delta, float(th6[k]), float(pz[k]), runs))
    return out


def theta6_verdict(facts: list, limit: float) -> str:
    """What the sweep shows about θ6 and its limit (rad), from :func:`theta6_limits`' facts (the first δ = 0)."""
    (d0, peak0, _, runs0), (d1, peak1, _, runs1) = facts[0], facts[-1]
    lowered = f"δ = {d1:.2f} lowers θ6's largest value from {peak0:.2f} (δ = {d0:.2f}) to {peak1:.2f} rad"
    if not runs1:
        return f"{lowered} and keeps it inside its limit of {limit:.2f} rad at every p_z: choosing δ avoids the limit"
    spans = ", ".join(f"{a:.2f} to {b:.2f} m" for a, b in runs1)
    neither = "neither constant δ keeps" if runs0 else f"only δ = {d0:.2f} keeps"
    return (
        f"{lowered}, but that is still past the catalog's limit of {limit:.2f} rad"
        f" ({np.degrees(limit):.0f}°, qpik's choice: the paper gives no limits) for p_z from {spans}:"
        f" {neither} θ6 inside it"
    )


def _print_files(files: list[tuple[Path, str]]) -> None:
    for path, what in files:
        print(f"  {Path(path).name}: {what}")
