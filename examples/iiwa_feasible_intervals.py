"""Feasible arm angles of a KUKA iiwa 14 pose: the exact ψ intervals per branch, and the self-motion map.

An S-R-S arm (Shimizu et al. 2008) keeps its hand still while the elbow turns about the
shoulder–wrist line by the arm angle ψ. ``qpik.feasible_intervals`` gives, for each of the 8
branches, the exact set of ψ where every joint stays inside its limits: the interval ends are
roots of closed-form equations (a joint at a limit, ``a sin ψ + b cos ψ = c``), not samples.

    python examples/iiwa_feasible_intervals.py [OUT]    # OUT: qpik-out/examples/iiwa_feasible_intervals/

Prints the pose, the ψ and branch of the configuration it was made from, every branch's feasible
intervals, and the configuration in the middle of the widest interval of that branch.
Writes ``selfmotion.png``: each joint against ψ for all 8 branches, with the ψ ranges where the
configuration's branch leaves the limits shaded.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.plots import save
from qpik.plots.closed_form import selfmotion_map


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    robot = qpik.load_robot("iiwa14")
    q0 = np.array([0.3, 0.9, -0.4, -1.4, 0.5, 1.1, 0.2])  # rad, inside the limits
    pose = robot.fk(q0)  # (4, 4), base frame, m

    # The inverse of ik: which ψ (rad) and which branch (0-7) q0 has.
    psi0, branch = qpik.redundancy_parameter(robot, q0)
    np.set_printoptions(precision=6, suppress=True)
    print(f"{robot.name}: pose = fk(q0), q0 = {q0} rad")
    print(pose)
    print(f"q0 has ψ = {psi0:.6f} rad on branch {branch} (branch = 4·[θ2 < 0] + 2·[θ4 < 0] + [θ6 < 0])")

    fi = qpik.feasible_intervals(robot, pose)
    print("\nfeasible ψ per branch (rad; closed intervals inside (-π, π], joint limits kept):")
    for b in fi.branch:
        spans = " ".join(f"[{lo:.6f}, {hi:.6f}]" for lo, hi in fi[b]) or "none"
        singular = fi.singular[fi.index(b)] if fi.singular else []
        note = f"  singular at ψ = {', '.join(f'{s:.6f}' for s in singular)}" if singular else ""
        print(f"  branch {b}: {spans}  ({np.degrees(fi.measure(b)):.1f}° in all){note}")
    print(f"q0's own ψ is inside branch {branch}'s set: {fi.contains(branch, psi0)}")

    # Pick the arm angle in the middle of the widest interval of q0's branch: from there the elbow
    # can turn the furthest either way before some joint reaches its limit.
    lo, hi = max(fi[branch], key=lambda iv: iv[1] - iv[0])
    psi = 0.5 * (lo + hi)
    sols = qpik.ik(robot, pose, psi)
    q = sols.q[list(sols.branch).index(branch)]
    print(f"\nmiddle of branch {branch}'s widest interval: ψ = {psi:.6f} rad (±{0.5 * (hi - lo):.3f} rad to its ends)")
    print(f"  q = {q} rad")

    fig = selfmotion_map(robot, pose, shade_branch=branch)
    path = save(fig, out / "selfmotion.png")
    print(f"\nwrote {path} (each joint against ψ, 8 branches; grey: ψ where branch {branch} leaves the limits)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
