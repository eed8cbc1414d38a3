"""The ``plan`` runner of ``qpik run`` and ``qpik plan``: plan the self-motion along a problem's path.

Waypoints: the problem's poses (``pose``, a ``rotation``/``position`` sweep, ``q`` or ``random``), or its
named path sampled at ``[solver] waypoints`` even times over its duration (the times then bound the
joint velocities). :func:`qpik.plan_self_motion` plans them with the ``[solver]`` settings
(:data:`qpik.problems.schema.SOLVER_KEYS`: ``objective`` and ``objective_weight``, ``max_joint_step``
(rad), ``d_safe`` (m), ``resolution``, ``reconfigure``, ``a_max`` (rad/s²), ``branch``: the only branch the
plan may use).

The report compares, on the same waypoints and with the same checks (:mod:`qpik.planning.plan`):
the plan; the DP-only plan; each ``[parameter]`` value held constant on one branch (``[solver]
baseline_branch``, default the plan's first); the QP controller tracking the waypoints online. Per row: FK error,
waypoints outside the joint limits and closer than d_s (capsules and MuJoCo), the largest joint step
over its bound, the joint path length and the objective J. Files: the plan as CSV and NPZ, the
self-motion map, the joint trajectories against their limits, an image strip of the arm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qpik.errors import ProblemFileError
from qpik.objectives import resolve
from qpik.planning import Plan, plan_self_motion
from qpik.planning.baselines import constant_parameter, online
from qpik.plots import save
from qpik.plots.plan import joint_trajectories, render_plan, selfmotion_map
from qpik.problems.runners import runner
from qpik.problems.schema import Problem


def waypoints(problem: Problem) -> tuple[np.ndarray, np.ndarray | None]:
    """The problem's waypoints (N, 4, 4) and their times (N,) (s; None for a sequence of poses)."""
    if problem.poses is not None:
        return problem.poses, None
    path = problem.path
    times = np.linspace(0.0, path.duration, int(problem.solver["waypoints"]))
    return path.pose(times), times


def plan_problem(problem: Problem, mujoco: bool = True) -> Plan:
    """:func:`qpik.plan_self_motion` of a ``plan`` problem with its ``[solver]`` settings."""
    if problem.kind != "plan":
        raise ProblemFileError(f"{problem.file}: kind {problem.kind!r} is not a planning problem (kind = \"plan\")")
    s = problem.solver
    poses, times = waypoints(problem)
    objective = None if s["objective"] == "none" else resolve(s["objective"]) * s["objective_weight"]
    return plan_self_motion(problem.robot, poses, objective, problem.obstacles, times, s["max_joint_step"],
                            s["reconfigure"], d_safe=s["d_safe"], a_max=s["a_max"] if times is not None else None,
                            resolution=s["resolution"], mujoco=mujoco,
                            branches=None if s["branch"] is None else [s["branch"]])  # fmt: skip


def baselines(problem: Problem, plan: Plan, mujoco: bool = True) -> list[Plan]:
    """The DP-only plan, the constant-parameter plans of ``[parameter]`` and the online QP controller."""
    out = []
    if plan.dp_plan is not None:
        out.append(plan.dp_plan)
    if plan.status == "failed" or not len(plan.q):
        return out
    if problem.robot.closed_form is not None and problem.params is not None:
        branch = problem.solver["baseline_branch"]
        branch = int(plan.branch[0]) if branch is None else branch
        out += [constant_parameter(plan, float(v), branch, mujoco) for v in problem.params]
    if problem.robot.closed_form is not None:
        out.append(online(plan, mujoco))
    return out


def plan_file(job: tuple[str, str | None]) -> dict:
    """One job of a batch (``qpik plan`` over many files, :func:`qpik.planning.batch.run_batch`): the problem
    file ``job[0]`` planned; with an output folder ``job[1]``, its report (``report.md``) and files written there.

    Returns a picklable summary: ``name``, ``file``, ``ok`` (every check holds), ``summary`` (one line),
    ``q`` (K, n) the plan, ``cost``, ``reconfigurations``, ``report`` (the Markdown text or "")."""
    from qpik.problems.schema import load

    path, out = job
    problem = load(path)
    if out is None:
        plan = plan_problem(problem, mujoco=False)
        report = ""
    else:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        report, plan = _report(problem, folder)
        (folder / "report.md").write_text(report + "\n")
    return {"name": problem.name, "file": str(path), "ok": plan.ok, "summary": plan.summary(), "q": plan.q,
            "cost": plan.cost, "reconfigurations": list(plan.reconfigurations), "report": report}  # fmt: skip


def _row(p: Plan) -> str:
    K = len(p.q)
    outside = int(np.sum(p.margin < 0)) if K else 0
    viol = float(np.maximum(-p.margin, 0.0).max(initial=0.0))
    close = int(np.sum(p.clearance < p.d_safe - 1e-12)) if len(p.obstacles) else 0
    close_mj = int(np.sum(p.clearance_mujoco < p.d_safe - 1e-6)) if len(p.obstacles) else 0
    clear = f"{p.clearance.min() * 1e3:.1f} / {p.clearance_mujoco.min() * 1e3:.1f}" if len(p.obstacles) else "—"
    return (f"| {p.label} | {max(p.fk_error):.1e} | {outside} ({viol:.3g} rad) | {close} / {close_mj} | {clear} |"
            f" {p.max_step_ratio:.3g} | {p.path_length:.4f} | {p.cost:.6g} | {len(p.reconfigurations)} |")  # fmt: skip


@runner("plan")
def run_plan(problem: Problem, out: Path) -> str:
    """Plan, compare with the baselines, write the files; return the Markdown report."""
    return _report(problem, out)[0]


def _report(problem: Problem, out: Path) -> tuple[str, Plan]:
    plan = plan_problem(problem)
    robot, name = problem.robot, problem.name
    others = baselines(problem, plan)
    lines = [f"# {name} (plan)", "", problem.description, ""]
    times = plan.times is not None
    lines.append(
        f"{robot.name}, {len(plan.poses)} waypoints" + (f" over {plan.progress[-1]:g} s" if times else "")
        + f", {len(problem.obstacles)} obstacle(s), d_s = {plan.d_safe:g} m,"
        + f" joint step ≤ {problem.solver['max_joint_step']:g} rad"
        + (" and ≤ v_max·Δt" if times else "") + f"; objective: {problem.solver['objective']}"
        + (f" × {problem.solver['objective_weight']:g}" if problem.solver["objective"] != "none" else "")
        + f"; reconfigurations: {problem.solver['reconfigure']}."
    )  # fmt: skip
    lines += ["", f"**Plan: {plan.summary()}**", ""]
    if plan.status == "failed":
        lines += [f"- first waypoint that cannot be planned: {plan.failure_waypoint} (pose p = "
                  f"{np.array2string(plan.poses[plan.failure_waypoint, :3, 3], precision=4)} m)",
                  f"- why: {plan.failure}", f"- at that waypoint: {plan.least_violating}", ""]  # fmt: skip
    if plan.reconfigurations:
        lines += [f"The arm stops and reconfigures after waypoint(s) {', '.join(map(str, plan.reconfigurations))}.", ""]
    stages = ", ".join(f"{k} {v:.3f} s" for k, v in plan.timings.items())
    lines += [f"Time (the solves; building and compiling their functions not counted): {stages}.", ""]
    lines += [
        "| plan | FK error (m, rad) | waypoints outside the limits (max) | closer than d_s (capsules / MuJoCo) |"
        " min clearance (mm, capsules / MuJoCo) | max joint step / bound | joint path length (rad) |"
        " objective J (minimised) | reconfigurations |",
        "|---|---|---|---|---|---|---|---|---|",
        *(_row(p) for p in (plan, *others) if len(p.q)),
        "",
    ]
    checks = [(c.text, c.ok) for c in plan.checks]
    if plan.status != "failed":
        checks.append((f"every waypoint planned ({len(plan.q)})", True))
        if plan.dp_plan is not None:
            checks.append((f"NLP objective J {plan.cost:.8g} ≤ DP objective J {plan.dp_cost:.8g} (minimised)",
                           plan.cost <= plan.dp_cost + 1e-12 * max(1.0, abs(plan.dp_cost))))  # fmt: skip
    else:
        checks.append((f"path planned: failed at waypoint {plan.failure_waypoint}", False))
    lines += [f"- {'PASS' if ok else 'FAIL'}: {text}" for text, ok in checks]
    lines += [f"- fact: {fact}" for fact in plan.facts]  # pairs no motion changes (qpik.contacts)
    verdict = all(ok for _, ok in checks)
    lines += ["", f"Overall: {'PASS' if verdict else 'FAIL'}", ""]
    files = []
    if len(plan.q):
        plan.to_csv(out / f"{name}_plan.csv")
        plan.to_npz(out / f"{name}_plan.npz")
        files += [f"{name}_plan.csv", f"{name}_plan.npz"]
        save(joint_trajectories(plan, others), out / f"{name}_joints.png")
        files.append(f"{name}_joints.png")
        strip = render_plan(plan, out / f"{name}_strip.png")
        files.append(strip.name if strip is not None else "(no image strip: it needs OpenGL)")
    if plan.profile is not None:
        save(selfmotion_map(plan, others=others), out / f"{name}_map.png")
        files.append(f"{name}_map.png")
    lines.append("Files: " + ", ".join(files))
    return "\n".join(lines), plan
