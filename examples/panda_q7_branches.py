"""The Franka Panda's 8 IK branches with q7 locked, the exact feasible q7 of each, and the best q7.

With q7 given, the Panda's joints 1-6 form a chain whose axes 1-2-3 meet (the shoulder) and whose axes 5-6 meet:
qpik solves it in closed form by the subproblems of Elias & Wen 2022 (He & Liu 2021 and Tittel 2021 solve the
Panda this way), 8 branches numbered ``4·[q2 < 0] + 2·[q4 > −0.467] + [cos q5 > 0]``. As q7 turns, each branch
moves continuously; ``qpik.feasible_intervals`` gives the q7 where every joint is inside Franka's limits, its ends
found as roots and proved per pose, and ``qpik.solve_best`` the branch and q7 of the largest joint-limit margin.

    python examples/panda_q7_branches.py [OUT]    # OUT: qpik-out/examples/panda_q7_branches/

Prints the pose, q7 and the branch of the configuration it was made from, every branch at that q7 (whether it
reaches the pose and stays inside the limits), every branch's feasible q7, and the best answer with its
certificate. Writes ``selfmotion.png``: each joint against q7 for all 8 branches, with the q7 where q0's branch
leaves the limits shaded.
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
    robot = qpik.load_robot("panda")
    q0 = np.array([0.4, -0.5, 0.3, -2.0, 0.6, 1.6, 0.9])  # rad, inside Franka's limits
    pose = robot.fk(q0)  # (4, 4), base frame, m

    q7, branch = qpik.redundancy_parameter(robot, q0)  # q7 is q0's own last joint
    np.set_printoptions(precision=6, suppress=True)
    print(f"{robot.name}: pose = fk(q0), q0 = {q0} rad")
    print(pose)
    print(f"q0 has q7 = {q7:.6f} rad on branch {branch}")

    sols = qpik.ik(robot, pose, q7)  # every branch at q7: q (8, 7), valid, within_limits, singular (8,)
    print(f"\nthe 8 branches at q7 = {q7:.6f} rad:")
    for k, b in enumerate(sols.branch):
        state = "reaches the pose" if sols.valid[k] else "does not reach the pose"
        inside = ", inside the limits" if sols.within_limits[k] else ""
        print(f"  branch {b}: q = {sols.q[k]} rad  ({state}{inside})")

    fi = qpik.feasible_intervals(robot, pose)
    print(f"\nfeasible q7 per branch (rad; Franka's limits kept; proved: {fi.proved}):")
    for b in fi.branch:
        spans = " ".join(f"[{lo:.6f}, {hi:.6f}]" for lo, hi in fi[b]) or "none"
        print(f"  branch {b}: {spans}  ({np.degrees(fi.measure(b)):.1f}° in all)")

    best = qpik.solve_best(robot, pose, "margin")  # the largest joint-limit margin over every branch and q7
    print(f"\n{best.summary()}")
    print(f"  q = {best.q} rad")

    fig = selfmotion_map(robot, pose, shade_branch=branch)
    path = save(fig, out / "selfmotion.png")
    print(f"\nwrote {path} (each joint against q7, 8 branches; grey: q7 where branch {branch} leaves the limits)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples") / Path(__file__).stem)
