"""The globally best branch and arm angle of the KUKA iiwa for a pose, and three ways to check it.

Run:  python examples/best_branch.py [OUTPUT_FOLDER]

1. qpik.solve_best searches every closed-form branch over its exact feasible arm-angle
   intervals for the largest joint-limit margin, keeping every link 3 cm from an obstacle,
   and proves that no other arm angle of any branch does better (the certificate).
2. The full-joint NLP (IPOPT over all 7 joints, pose as a constraint) started at that answer
   stays there; the QP controller started there does not move (qpik.checks.crosscheck).
3. A plot of the margin (maximised: qpik minimises −margin) against the arm angle for every branch goes to OUTPUT_FOLDER
   (default: qpik-out/examples).
"""

import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.checks.crosscheck import crosscheck
from qpik.geometry import Sphere
from qpik.plots import save
from qpik.plots.objective import objective_map

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples")
robot = qpik.load_robot("iiwa14")

# a target: the tool pointing down, 55 cm in front of the base; a ball where an elbow could go
pose = np.eye(4)
pose[:3, :3] = np.diag([1.0, -1.0, -1.0])
pose[:3, 3] = (0.55, 0.2, 0.55)
ball = Sphere((0.25, 0.35, 0.75), 0.08)

# 1. the best branch and arm angle: largest joint-limit margin, every capsule 3 cm from the ball
best = qpik.solve_best(robot, pose, "margin", obstacles=[ball], d_safe=0.03)
print(best.table())
print(best.summary())
print("q* =", np.array2string(best.q, precision=9, max_line_width=200))
print("forward kinematics error of q*:", float(np.abs(robot.fk(best.q) - pose).max()))

# 2. cross-check with a smooth objective (the soft minimum of the same normalised distances)
check = crosscheck(robot, pose, "smooth-margin", obstacles=[ball], d_safe=0.03)
print(check.report())

# 3. the picture
path = save(objective_map(qpik.Scene.of(robot, [ball], d_safe=0.03), pose, best), out / "best_branch.png")
print("plot written to", path)
