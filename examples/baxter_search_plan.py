"""An arm with no closed form: Baxter's right arm (example-robot-data's URDF, ``pip install example-robot-data``).

Run:  python examples/baxter_search_plan.py [OUTPUT_FOLDER]

1. ``load_robot`` finds its geometry (axes 2-3, 4-5, 6-7 meet; offsets 69, 69 and 10 mm) and serves it by a certified
   1-D search over q4 with q1 locked: ``qpik.ik`` gives 16 slots at a value of q1, every root of the search's error
   functions, each solution polished to machine precision on the file's own chain.
2. ``plan_self_motion`` plans a path with the DP over the branches the search finds inside the limits at 64 values
   of q1 per waypoint, then the NLP over the joints; the plan follows the path exactly.
3. The plan goes to OUTPUT_FOLDER (default: qpik-out/examples/baxter_search_plan) as CSV with its self-motion map.
"""

import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.plots import save
from qpik.plots.plan import plan_map
from qpik.robots.packaged import packaged_model

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples/baxter_search_plan")
out.mkdir(parents=True, exist_ok=True)

# 1. the arm and its branches at one pose
try:
    robot = qpik.load_robot(packaged_model("erd/baxter"), base="right_arm_mount", tip="right_wrist")
except qpik.InputError as error:  # example-robot-data not installed: say so in one line
    sys.exit(f"{Path(__file__).name}: {error}")
print(f"{robot.name} right arm, family {robot.closed_form}: {robot.notes.split('; not srs')[0]}")
q = np.array([0.3, -0.4, 0.5, 1.2, -0.3, 0.8, 0.2])
T = robot.fk(q)
sols = qpik.ik(robot, T, q[0])
print(f"\nqpik.ik at q1 = {q[0]} rad: {int(sols.valid.sum())} of 16 slots reach the pose, "
      f"{int(sols.within_limits.sum())} inside the joint limits")  # fmt: skip
for b, qb, ok, inside in zip(sols.branch, sols.q, sols.valid, sols.within_limits):
    if ok:
        error = float(np.abs(robot.fk(qb) - T).max())
        print(f"  slot {b:2d}: q = {np.array2string(qb, precision=3)}, FK error {error:.1e}"
              f"{'' if inside else ' (outside the limits)'}")  # fmt: skip
here = np.abs(sols.q[sols.valid] - q).max(axis=1).min()
print(f"  the configuration the pose came from is slot {qpik.redundancy_parameter(robot, q[None])[1][0]} "
      f"(to {here:.1e} rad)")  # fmt: skip

# 2. a plan along a path: the DP over the searched branches, then the NLP over the joints
path = robot.fk(q + np.linspace(0.0, 1.0, 15)[:, None] * np.array([0.4, 0.3, -0.3, -0.4, 0.3, -0.3, 0.4]))
plan = qpik.plan_self_motion(robot, path, "margin", options=qpik.PlanOptions(mujoco=False))
print(f"\nplan along {len(path)} waypoints: {plan.summary()} ({plan.label}; DP {plan.timings['dp']:.1f} s)")
for check in plan.checks:
    print(f"  {'PASS' if check.ok else 'FAIL'}: {check.text}")

# 3. files
plan.to_csv(out / "baxter_plan.csv")
save(plan_map(plan), out / "baxter_map.png")
print(f"\nplan: {out / 'baxter_plan.csv'}; self-motion map: baxter_map.png")
