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

For ``qpik plan`` on local processes or a Dask cluster the client reads, the workers compute, the client writes:
:func:`plan_job` (on the client) turns a problem into a :class:`PlanJob`, pure data (the robot as a
:class:`~qpik.robots.bundle.RobotBundle`); :func:`solve` (on a worker) returns a :class:`PlanReport` (the plan, the
report's text, its files' bytes); :meth:`PlanReport.write` (on the client) writes them under the output folder.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from qpik.core.errors import InputError, ProblemFileError
from qpik.geometry.shapes import Shape
from qpik.objectives import resolve
from qpik.planning import Plan, PlanOptions, plan_self_motion
from qpik.planning.baselines import constant_parameter, online
from qpik.planning.many import detach
from qpik.plots import save
from qpik.plots.plan import joint_trajectories, plan_map, render_plan
from qpik.problems.runners import runner
from qpik.problems.schema import Problem
from qpik.robots.bundle import RobotBundle
from qpik.robots.robot import Robot


def waypoints(problem: Problem) -> tuple[np.ndarray, np.ndarray | None]:
    """The problem's waypoints (N, 4, 4) and their times (N,) (s; None for a sequence of poses)."""
    if problem.poses is not None:
        return problem.poses, None
    path = problem.path
    times = np.linspace(0.0, path.duration, int(problem.solver["waypoints"]))
    return path.pose(times), times


@dataclass(frozen=True, eq=False)
class PlanJob:
    """A ``plan`` problem as data for a worker that shares no folder with the client: made by :func:`plan_job`
    on the client, solved by :func:`solve` wherever it runs.

    Attributes:
        name, description: the problem's. file: the problem file it was read from (for messages only).
        robot: the arm (:class:`~qpik.robots.bundle.RobotBundle`: a catalog name, or the robot and its model files).
        poses: (N, 4, 4) the waypoints, base frame, m. times: (N,) s, or None.
        obstacles: the obstacle shapes (world frame). params: (M,) the ``[parameter]`` values, rad, or None.
        solver: the ``[solver]`` settings.
    """

    name: str
    description: str
    file: str
    robot: RobotBundle
    poses: np.ndarray
    times: np.ndarray | None
    obstacles: tuple[Shape, ...]
    params: np.ndarray | None
    solver: dict[str, Any]


def plan_job(problem: Problem) -> PlanJob:
    """The :class:`PlanJob` of a ``plan`` problem (the path sampled, the robot's model files read).

    Raises:
        ProblemFileError: the problem is not of kind ``plan``.
        InputError: a file of the robot's model cannot be read.
    """
    if problem.kind != "plan":
        raise ProblemFileError(f'{problem.file}: kind {problem.kind!r} is not a planning problem (kind = "plan")')
    poses, times = waypoints(problem)
    return PlanJob(problem.name, problem.description, str(problem.file), RobotBundle.of(problem.robot), poses, times,
                   problem.obstacles, problem.params, dict(problem.solver))  # fmt: skip


def check_names(problems: Sequence[Problem]) -> None:
    """Check the problems' names as output folder names, before anything runs: each one folder inside the output
    folder, none shared by two files (ignoring case, for file systems that do).

    Raises:
        InputError: a name that is empty, ``.`` or ``..``, or holds a path separator or a control character; a name
            given by two files (both named).
    """
    seen: dict[str, Problem] = {}
    for problem in problems:
        name = problem.name
        if name in ("", ".", "..") or any(c in name for c in "/\\") or any(ord(c) < 32 for c in name):
            raise InputError(f"{problem.file}: name: {name!r} cannot be an output folder's name (an empty name, "
                             "'.', '..', a path separator or a control character)")  # fmt: skip
        other = seen.setdefault(name.casefold(), problem)
        if other is not problem:
            raise InputError(f"name: {other.file} and {problem.file} both have the name {name!r}, which names their "
                             "output folder; give each file its own name")  # fmt: skip


@dataclass(eq=False)
class PlanReport:
    """What :func:`solve` returns: the plan, the report and its files, as data.

    Attributes:
        name: the problem's name (the output folder's). plan: the plan, without its robot
            (:func:`qpik.planning.many.attach` gives it the client's). ok: every check of the report holds.
        text: the Markdown report. files: ``{file name: bytes}`` (CSV, NPZ, figures).
    """

    name: str
    plan: Plan
    ok: bool
    text: str
    files: dict[str, bytes]

    def write(self, folder: str | os.PathLike) -> Path:
        """Write ``report.md`` and the files into ``folder`` (created), the layout of a local run; returns the
        report's path."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        for name, blob in self.files.items():
            (folder / name).write_bytes(blob)
        (folder / "report.md").write_text(self.text + "\n")
        return folder / "report.md"


def solve(job: PlanJob) -> PlanReport:
    """Plan ``job``, compare with the baselines and make the report and its files (in a temporary folder that is
    read back and deleted): the whole work of one file of ``qpik plan``, run on a worker or in this process.
    The returned plan carries no robot (:func:`qpik.planning.many.detach`); nothing is written anywhere else."""
    robot = job.robot.robot()
    with tempfile.TemporaryDirectory(prefix="qpik-plan-") as tmp:
        folder = Path(tmp)
        text, plan, ok = _report(job, robot, folder)
        files = {f.name: f.read_bytes() for f in sorted(folder.iterdir()) if f.is_file()}
    return PlanReport(job.name, detach(plan), ok, text, files)


def _plan(job: PlanJob, robot: Robot, mujoco: bool = True) -> Plan:
    s = job.solver
    objective = None if s["objective"] == "none" else resolve(s["objective"]) * s["objective_weight"]
    a_max = s["a_max"] if job.times is not None else None
    branches = None if s["branch"] is None else [s["branch"]]
    options = PlanOptions(max_joint_step=s["max_joint_step"], reconfigure=s["reconfigure"], a_max=a_max,
                          resolution=s["resolution"], branches=branches, mujoco=mujoco)  # fmt: skip
    return plan_self_motion(robot, job.poses, objective, job.obstacles, times=job.times, d_safe=s["d_safe"],
                            options=options)  # fmt: skip


def plan_problem(problem: Problem, mujoco: bool = True) -> Plan:
    """:func:`qpik.plan_self_motion` of a ``plan`` problem with its ``[solver]`` settings."""
    job = plan_job(problem)
    return _plan(job, job.robot.robot(), mujoco)


def baselines(job: PlanJob, robot: Robot, plan: Plan, mujoco: bool = True) -> list[Plan]:
    """The DP-only plan, the constant-parameter plans of ``[parameter]`` and the online QP controller."""
    out = []
    if plan.dp_plan is not None:
        out.append(plan.dp_plan)
    if plan.status == "failed" or not len(plan.q):
        return out
    if robot.branch_functions and job.params is not None:
        branch = job.solver["baseline_branch"]
        branch = int(plan.branch[0]) if branch is None else branch
        out += [constant_parameter(plan, float(v), branch, mujoco) for v in job.params]
    if robot.branch_functions:
        out.append(online(plan, mujoco))
    return out


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
    report = solve(plan_job(problem))
    report.write(out)
    return report.text


def _report(job: PlanJob, robot: Robot, out: Path) -> tuple[str, Plan, bool]:
    plan = _plan(job, robot)
    name, solver = job.name, job.solver
    others = baselines(job, robot, plan)
    lines = [f"# {name} (plan)", "", job.description, ""]
    times = plan.times is not None
    lines.append(
        f"{robot.name}, {len(plan.poses)} waypoints" + (f" over {plan.progress[-1]:g} s" if times else "")
        + f", {len(job.obstacles)} obstacle(s), d_s = {plan.d_safe:g} m,"
        + f" joint step ≤ {solver['max_joint_step']:g} rad"
        + (" and ≤ v_max·Δt" if times else "") + f"; objective: {solver['objective']}"
        + (f" × {solver['objective_weight']:g}" if solver["objective"] != "none" else "")
        + f"; reconfigurations: {solver['reconfigure']}."
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
    lines += [f"- fact: {fact}" for fact in plan.facts]  # pairs no motion changes (qpik.geometry.contacts)
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
        save(plan_map(plan, others=others), out / f"{name}_map.png")
        files.append(f"{name}_map.png")
    lines.append("Files: " + ", ".join(files))
    return "\n".join(lines), plan, verdict
