"""Offline self-motion planning: the joint motion that follows an end-effector path exactly and uses the
redundancy best, for the offset-shoulder arm of Nammoto & Kosuge 2012 and a KUKA iiwa wiping a table.

Run:  python examples/plan_path.py [OUTPUT_FOLDER]

1. nammoto7 keeps its hand pointing down while p_z falls from 0.9 to 0.3 m. At δ = 0 the sixth joint runs
   past its limit (the paper's Fig. 15); δ = 0.70 keeps it inside (Fig. 16). qpik.plan_self_motion
   chooses δ at every waypoint (DP over the exact feasible intervals, then a sparse NLP).
2. The iiwa wipes a table past a post standing on it; the plan keeps every link 2 cm from both, and is
   retimed time-optimally under the joint velocity and acceleration limits (toppra).
3. The iiwa plan goes to OUTPUT_FOLDER (default: qpik-out/examples/plan_path) as CSV, with its
   self-motion map, its joints against their limits and an image strip.
"""

import sys
from pathlib import Path

import numpy as np

from qpik.planning.baselines import constant_parameter
from qpik.plots import save
from qpik.plots.plan import joint_trajectories, plan_map, render_plan
from qpik.problems import find_problem, load
from qpik.problems.plan import plan_problem, waypoints

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("qpik-out/examples/plan_path")
out.mkdir(parents=True, exist_ok=True)

# 1. the joint-limit sweep of Nammoto & Kosuge 2012 (limits of the problem file: θ6 within ±125°)
sweep = load(find_problem("nammoto2012_joint_limits_plan"))
plan = plan_problem(sweep)
robot = sweep.robot
print(f"{robot.name}, p_z from 0.9 to 0.3 m, hand down: {plan.summary()}")
branches = sorted({int(b) for b in plan.branch})
print(
    f"  plan: δ from {plan.param[0]:.3f} to {plan.param[-1]:.3f} rad on branch(es) {branches},"
    f" max |θ6| = {np.abs(plan.q[:, 5]).max():.3f} rad (limit {robot.q_max[5]:.3f})"
)
length = lambda q: float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())  # noqa: E731
for delta in (0.0, 0.70):
    base = constant_parameter(plan, delta, 1, mujoco=False)
    outside = int(np.sum(~robot.within_limits(base.q)))
    print(
        f"  δ = {delta:.2f} held on branch 1: {outside} waypoints outside the limits,"
        f" max |θ6| = {np.abs(base.q[:, 5]).max():.3f} rad, joint path {length(base.q):.3f} rad"
    )
print(f"  planned joint path {length(plan.q):.3f} rad")

# 2. the iiwa wiping a table past a post (problems/iiwa_wiping_plan.toml)
wipe = load(find_problem("iiwa_wiping_plan"))
plan = plan_problem(wipe)
print(
    f"\n{wipe.robot.name} wiping past a post: {plan.summary()} (solve times, building the functions not counted:"
    f" DP {plan.timings['dp']:.2f} s, NLP {plan.timings['nlp']:.2f} s)"
)
for check in plan.checks:
    print(f"  {'PASS' if check.ok else 'FAIL'}: {check.text}")
print(f"  NLP objective J {plan.cost:.6g} ≤ DP objective J {plan.dp_cost:.6g} (J is minimised)")
timed = plan.retime(wipe.robot.v_max, 2.0 * wipe.robot.v_max)
print(
    f"  retimed (toppra, v_max and a_max = 2 v_max per s): {timed.duration:.3f} s instead of"
    f" {waypoints(wipe)[1][-1]:.0f} s"
)

# 3. files
plan.to_csv(out / "iiwa_wiping_plan.csv")
save(plan_map(plan), out / "iiwa_wiping_map.png")
save(joint_trajectories(plan), out / "iiwa_wiping_joints.png")
strip = render_plan(plan, out / "iiwa_wiping_strip.png")
print(
    f"\nplan: {out / 'iiwa_wiping_plan.csv'}; pictures: iiwa_wiping_map.png, iiwa_wiping_joints.png"
    + (", iiwa_wiping_strip.png" if strip else " (no image strip: no OpenGL)")
)
