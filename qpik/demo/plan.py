"""Demo section: offline self-motion planning along a path (:func:`qpik.plan_self_motion`).

1. ``problems/nammoto2012_joint_limits_plan.toml``: the hand pointing down while p_z falls (Nammoto &
   Kosuge 2012, Figs. 15-16): the planned δ against δ = 0 and 0.70 held constant.
2. ``problems/iiwa_reconfiguration_plan.toml``: an iiwa wiping past a post where no continuous motion
   follows the whole path: where ``reconfigure="forbid"`` stops and why, and the plan with the fewest
   reconfigurations.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qpik.planning import PlanOptions, plan_self_motion
from qpik.planning.baselines import constant_parameter
from qpik.plots import save
from qpik.plots.plan import joint_trajectories, plan_map, render_plan
from qpik.problems import find_problem, load
from qpik.problems.plan import plan_problem, waypoints

TITLE = "Self-motion planning along a path (DP over the exact feasible sets + sparse NLP)"


def run(out: Path) -> None:
    folder = out / "plan"
    folder.mkdir(parents=True, exist_ok=True)
    sweep = load(find_problem("nammoto2012_joint_limits_plan"))
    plan = plan_problem(sweep)
    length = lambda q: float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())  # noqa: E731
    print(f"{sweep.robot.name}, hand down, p_z 0.9 → 0.3 m (Nammoto & Kosuge 2012, Figs. 15-16): {plan.summary()}")
    robot = sweep.robot
    print(f"  limits of this problem: θ6 within ±{robot.q_max[5]:.4f} rad ({np.degrees(robot.q_max[5]):.0f}°)")
    print(f"  {'plan':28} {'waypoints outside the limits':>28} {'joint path [rad]':>17}")
    baselines = [constant_parameter(plan, d, sweep.solver["baseline_branch"], mujoco=False) for d in sweep.params]
    for p in (plan, *baselines):
        print(f"  {p.label:28} {int(np.sum(p.margin < 0)):>28} {length(p.q):>17.3f}")
    save(plan_map(plan, others=baselines), folder / "nammoto_sweep_map.png")
    save(joint_trajectories(plan, baselines), folder / "nammoto_sweep_joints.png")
    print(f"  nammoto_sweep_joints.png, nammoto_sweep_map.png: the plan and the {len(baselines)} constant-δ baselines")

    problem = load(find_problem("iiwa_reconfiguration_plan"))
    poses, times = waypoints(problem)
    options = PlanOptions(max_joint_step=problem.solver["max_joint_step"], refine=False, mujoco=False)
    forbid = plan_self_motion(problem.robot, poses, None, problem.obstacles, times=times, options=options)
    print(f"\n{problem.robot.name} wiping past a post, reconfigure='forbid': {forbid.summary()}")
    fewest = plan_problem(problem)
    print(f"reconfigure='fewest': {fewest.summary()}")
    for check in fewest.checks:
        print(f"  {'PASS' if check.ok else 'FAIL'}: {check.text}")
    save(plan_map(fewest), folder / "iiwa_reconfiguration_map.png")
    strip = render_plan(fewest, folder / "iiwa_reconfiguration_strip.png")
    print(f"pictures: {folder}/ (self-motion maps, joints" + (", image strip)" if strip else ")"))
