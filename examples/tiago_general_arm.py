"""An arm of no special geometry: the left arm of example-robot-data's TIAGo Pro (``pip install example-robot-data``).

Run:  python examples/tiago_general_arm.py [OUTPUT_FOLDER]

1. ``load_robot`` finds no closed form and no 1-D search in its axes (consecutive axes 20-70 mm apart) and serves it
   with q7 locked: the 6-R chain left is eliminated to one eigenproblem of size 24 (Raghavan & Roth 1993; Manocha &
   Canny 1994), whose real eigenvalues give every solution, each polished on the file's own chain.
2. ``feasible_intervals``: per slot, the values of q7 keeping every joint inside its limits, sampled (not proved).
3. ``solve_best``: the configuration of largest joint-limit margin for the pose, sampled along q7 and polished.
4. The slots and the best answer go to OUTPUT_FOLDER (default: qpik-out/examples/tiago_general_arm) as CSV.
"""

import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.robots.packaged import packaged_model


def left_arm() -> qpik.Robot:
    """The TIAGo Pro's left arm, from the torso lift to the tool; where example-robot-data is not installed, the
    script ends with one line saying so."""
    try:
        return qpik.load_robot(packaged_model("erd/tiago_pro"), base="torso_lift_link", tip="arm_left_tool_link")
    except qpik.InputError as error:
        sys.exit(f"{Path(__file__).name}: {error}")


robot = left_arm()
print(f"{robot.name}, family {robot.closed_form}:\n  {robot.notes.split(', no closed form')[0]}")

# 1. every solution at the configuration's own q7: qpik.ik's table, then each valid slot's FK residual
q = np.array([0.4, -0.6, 0.8, 1.1, -0.5, 0.7, 0.3])
T, q7 = robot.fk(q), q[6]
sols = qpik.ik(robot, T, q7)
print(f"\nqpik.ik at q7 = {q7} rad:\n{sols.table()}")
fk_error = np.abs(robot.fk(sols.q) - T).max(axis=(1, 2))
print("FK residual of every valid slot: " + ", ".join(f"{e:.0e}" for e in fk_error[sols.valid]))
rows = np.column_stack([sols.branch, sols.q, fk_error, sols.within_limits])[sols.valid]

# 2. the slots' feasible q7 (sampled at 512 values per turn, every change moved onto the answers)
fi = qpik.feasible_intervals(robot, T)
print(f"\nfeasible q7 per slot ({'proved' if fi.proved else 'sampled, not proved'}):")
for b in fi.branch:
    if fi[int(b)]:
        print(f"  slot {b:2d}: " + ", ".join(f"[{lo:+.3f}, {hi:+.3f}]" for lo, hi in fi[int(b)]))

# 3. the best margin over every slot and q7
best = qpik.solve_best(robot, T, "margin")
print(f"\nsolve_best: {best.summary()}")

# 4. files
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples/tiago_general_arm")
out.mkdir(parents=True, exist_ok=True)
header = "slot," + ",".join(f"q{j + 1}" for j in range(7)) + ",fk_error,inside_limits"
np.savetxt(out / "tiago_slots.csv", rows, delimiter=",", header=header, comments="")
np.savetxt(out / "tiago_best.csv", best.q[None], delimiter=",", header=",".join(f"q{j + 1}" for j in range(7)),
           comments="")  # fmt: skip
print(f"\nslots: {out / 'tiago_slots.csv'}; best answer: tiago_best.csv")
