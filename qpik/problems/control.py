r"""Runners of ``qpik run`` for the controller: ``track`` (follow a path) and ``reach`` (go to a pose).

Both run closed loops in MuJoCo (:func:`qpik.sim.simulate`) and judge them on the
simulator's own measurements (tracking error from the MuJoCo site pose, clearance
from ``mj_geomDistance``), not on what the controller believes.

``track`` (Zheng et al. 2019): the QP controller, the PD CLIK of eq. (18)
(:class:`~qpik.control.clik.PseudoInverseCLIK`) and the velocity-only scheme of
Fig. 3a (:class:`~qpik.control.clik.VelocityOnly`) follow the same path from the
same configuration. Reported: each one's largest position error after the
transient, and the drift of velocity-only feedback (its error over PD CLIK's).

``reach``: the QP controller takes the arm from its home configuration to a target
pose among obstacles. Its posture reference :math:`q_{ref}` is the NLP's answer
(:func:`qpik.solve_best`): over the exact feasible arm-angle intervals of the start's branch
(the branch a continuous motion keeps unless it passes a singular configuration), the
configuration that minimises :func:`reach_objective`, certified. The same controller without
the obstacle limit is run on the same scene to show that the limit is needed.

``[solver]`` keys (all optional; their defaults and values: :data:`qpik.problems.schema.SOLVER_KEYS`):
``dt`` (s), ``duration`` (s), ``kp_position``, ``kp_orientation`` (1/s), ``posture_weight``,
``manipulability_weight``, ``damping``; ``reach`` also ``d_safe``, ``d_influence`` (m), ``xi`` (m/s).
``[expected]`` keys:
``track``: ``tracking_error`` (m), ``transient`` (s); ``reach``: ``position_error`` (m),
``orientation_error`` (rad), ``psi_tolerance`` (rad).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from qpik.analytic import feasible_intervals, redundancy_parameter
from qpik.analytic.intervals import wrap
from qpik.control.clik import PseudoInverseCLIK, VelocityOnly
from qpik.control.controller import Controller
from qpik.control.options import ControllerOptions
from qpik.core.errors import ProblemFileError, UnreachableError
from qpik.geometry import distances
from qpik.nlp import BestResult, solve_best
from qpik.nlp.options import BestOptions
from qpik.objectives import Clearance, JointLimitMargin, Objective
from qpik.plots.runs import plot_comparison, plot_log, render_strip
from qpik.problems.runners import runner
from qpik.problems.schema import Problem
from qpik.sim import SimLog, SimOptions, Summary, simulate

SINGULAR_FRACTION = 0.01
"""A track report flags a singular passage when the manipulability falls below this fraction of its start."""
MARGIN_WEIGHT = 0.1
"""Weight of the joint-limit margin beside the clearance in the reach runner's objective."""


def reach_objective(d_influence: float) -> Objective:
    """The posture reference's objective: the soft minimum of every capsule–obstacle clearance, capped at
    the dampers' influence distance (m), plus :data:`MARGIN_WEIGHT` times the joint-limit margin."""
    return Clearance(cap=d_influence, smooth=True) + MARGIN_WEIGHT * JointLimitMargin()


def _settings(problem: Problem) -> dict[str, Any]:
    s = problem.solver
    return {"position_gain": s["kp_position"], "orientation_gain": s["kp_orientation"]}


def _verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def _error_row(label: str, s: Summary, log: SimLog) -> str:
    return (
        f"| {label} | {s.max_pos_error * 1e3:.4g} | {s.max_rot_error:.3g} | {s.final_pos_error * 1e3:.4g} |"
        f" {float(log.manipulability.min()):.3g} | {s.max_velocity_ratio:.3g} | {s.max_limit_violation:.3g} |"
    )


def track_runs(problem: Problem) -> list[SimLog]:
    """The three closed loops of a ``track`` problem: QP, PD CLIK, velocity-only (in that order)."""
    robot, path = problem.robot, problem.path
    s = problem.solver
    dt = s["dt"]
    duration = path.duration if s["duration"] is None else s["duration"]
    q0 = robot.q_home if path.q0 is None else path.q0
    gains = _settings(problem)
    options = ControllerOptions(
        posture_weight=s["posture_weight"], manipulability_weight=s["manipulability_weight"], damping=s["damping"],
        **gains,
    )  # fmt: skip
    qp = Controller.for_robot(robot, dt=dt, q_ref=q0, options=options)
    policies = {
        "QP (OSQP)": qp,
        "PD CLIK, eq. (18)": PseudoInverseCLIK(robot, dt=dt, **gains),
        "velocity-only, Fig. 3a": VelocityOnly(robot, dt=dt),
    }
    every = max(1, round(0.01 / dt))
    return [
        simulate(robot, c, q0, duration, dt, target=path, options=SimOptions(record_every=every, label=k))
        for k, c in policies.items()
    ]


@runner("track")
def run_track(problem: Problem, out: Path) -> str:
    """QP controller vs PD CLIK vs velocity-only CLIK on the problem's path; see the module docstring."""
    robot, path = problem.robot, problem.path
    logs = track_runs(problem)
    dt, duration = logs[0].dt, float(logs[0].t[-1])
    gains = _settings(problem)
    transient = problem.expected_number("transient", 1.0)
    sums = [log.summary(transient) for log in logs]
    qp_s, pd_s, vel_s = sums
    figure = plot_comparison(logs, out / f"{problem.name}_errors.png", title=f"{problem.name}: tracking error")
    qp_plot = plot_log(logs[0], out / f"{problem.name}_qp.png")

    drift = vel_s.max_pos_error / max(pd_s.max_pos_error, 1e-15)
    tol = problem.expected_number("tracking_error")
    lines = [
        f"# {problem.name} (track)",
        "",
        problem.description,
        "",
        f"{robot.name}, path `{path.name}` for {duration:g} s, dt = {dt:g} s, gains"
        f" {gains['position_gain']:g}/{gains['orientation_gain']:g} 1/s; errors after t = {transient:g} s,"
        " measured on the MuJoCo twin.",
        "",
        "| controller | max position error (mm) | max orientation error (rad) | final position error (mm) |"
        " min manipulability | max abs(v)/v_max | max limit violation (rad) |",
        "|---|---|---|---|---|---|---|",
        *(_error_row(log.label, s, log) for log, s in zip(logs, sums)),
        "",
        f"Velocity-only drift: its error is {drift:.3g}× PD CLIK's"
        f" ({vel_s.max_pos_error * 1e3:.4g} mm vs {pd_s.max_pos_error * 1e3:.4g} mm).",
        f"QP solve time: median {qp_s.solve_time.get('median', np.nan) * 1e6:.0f} µs,"
        f" p99 {qp_s.solve_time.get('p99', np.nan) * 1e6:.0f} µs.",
        "",
    ]
    checks = [("velocity-only drifts more than PD CLIK", drift > 1.0)]
    if tol is not None:
        checks += [
            (f"PD CLIK error ≤ {tol:g} m (the paper's claim)", pd_s.max_pos_error <= tol),
            (f"QP error ≤ {tol:g} m", qp_s.max_pos_error <= tol),
        ]
    lines += [f"- {_verdict(ok)}: {text}" for text, ok in checks]
    m0 = logs[1].manipulability[0]
    k = int(np.argmin(logs[1].manipulability))
    if logs[1].manipulability[k] < SINGULAR_FRACTION * m0:
        lines += ["", f"Note: along PD CLIK's run the manipulability falls from {m0:.3g} to"
                  f" {logs[1].manipulability[k]:.3g} at t = {logs[1].t[k]:.2f} s: the path passes near a singular"
                  " configuration, where every controller here loses the path."]  # fmt: skip
    lines += ["", f"Overall: {_verdict(all(ok for _, ok in checks))}", "", f"Plots: {figure.name}, {qp_plot.name}"]
    return "\n".join(lines)


@dataclass
class ReachRuns:
    """The closed loops of a ``reach`` problem.

    Attributes:
        reference: the NLP's answer, the posture reference; start_branch: the branch of q_home (searched).
        log: the QP controller with the obstacle limit; free: the same without it.
        d_safe, d_influence, xi: the obstacle-limit settings (m, m, m/s).
    """

    reference: BestResult
    start_branch: int
    log: SimLog
    free: SimLog
    d_safe: float
    d_influence: float
    xi: float


def reach_runs(problem: Problem) -> ReachRuns:
    """The NLP's posture reference, then the QP controller with and without the obstacle limit, same scene."""
    robot = problem.robot
    if len(problem.poses) != 1:
        raise ProblemFileError(f"{problem.file}: target: kind 'reach' takes one pose, got {len(problem.poses)}")
    pose = problem.poses[0]
    obstacles = problem.obstacles
    s = problem.solver
    dt, duration = s["dt"], s["duration"]
    d_safe, d_influence, xi = s["d_safe"], s["d_influence"], s["xi"]
    q0 = robot.q_home
    start_branch = redundancy_parameter(robot, q0)[1]
    ref = solve_best(
        robot,
        pose,
        reach_objective(d_influence),
        obstacles,
        d_safe=d_safe,
        options=BestOptions(branches=[start_branch]),
    )
    if ref.status != "optimal":
        raise UnreachableError(
            f"{robot.name}: no arm angle of branch {start_branch} reaches the target ({ref.summary()})"
        )
    options = ControllerOptions(
        d_influence=d_influence,
        xi=xi,
        posture_weight=s["posture_weight"],
        manipulability_weight=s["manipulability_weight"],
        damping=s["damping"],
        **_settings(problem),
    )
    kwargs = dict(target=pose, dt=dt, q_ref=ref.q, d_safe=d_safe, options=options)
    every = max(1, round(0.01 / dt))
    logs = []
    for label, obs in (("QP with obstacle limit", obstacles), ("QP without obstacle limit", ())):
        ctrl = Controller.for_robot(robot, obstacles=obs, **kwargs)
        logs.append(
            simulate(
                robot,
                ctrl,
                q0,
                duration,
                dt,
                obstacles=obstacles,
                target=pose,
                options=SimOptions(record_every=every, d_safe=d_safe, label=label),
            )
        )
    return ReachRuns(ref, int(start_branch), logs[0], logs[1], d_safe, d_influence, xi)


@runner("reach")
def run_reach(problem: Problem, out: Path) -> str:
    """QP controller from home to a pose among obstacles, posture from the NLP; see the module docstring."""
    robot = problem.robot
    runs = reach_runs(problem)
    ref, log, free = runs.reference, runs.log, runs.free
    d_safe, d_influence, xi = runs.d_safe, runs.d_influence, runs.xi
    dt, duration = log.dt, float(log.t[-1])
    summ, free_s = log.summary(), free.summary()
    psi, branch = redundancy_parameter(robot, log.q[-1])
    dpsi = abs(float(wrap(psi - ref.param)))
    plot_log(log, out / f"{problem.name}_log.png", title=f"{problem.name}: {log.label}")
    plot_log(free, out / f"{problem.name}_free_log.png", title=f"{problem.name}: {free.label}")
    strip = render_strip(log, out / f"{problem.name}_strip.png")

    pos_tol = problem.expected_number("position_error", 1e-3)
    rot_tol = problem.expected_number("orientation_error", 1e-2)
    psi_tol = problem.expected_number("psi_tolerance", 0.05)
    margins = log.limit_margin.min(axis=0)
    closest, free_closest = (float(sm.min_clearance.min(initial=np.inf)) for sm in (summ, free_s))
    checks = [
        (f"reached: final position error {summ.final_pos_error * 1e3:.3g} mm ≤ {pos_tol * 1e3:g} mm",
         summ.final_pos_error <= pos_tol),
        (f"reached: final orientation error {summ.final_rot_error:.3g} rad ≤ {rot_tol:g} rad",
         summ.final_rot_error <= rot_tol),
        (f"joint limits kept: max violation {summ.max_limit_violation:.3g} rad", summ.max_limit_violation <= 1e-9),
        (f"velocity limits kept: max abs(v)/v_max = {summ.max_velocity_ratio:.4g}",
         summ.max_velocity_ratio <= 1 + 1e-6),
        (f"final q on the chosen branch {ref.branch} (got {branch}), abs(Δψ) = {dpsi:.3g} rad ≤ {psi_tol:g}",
         branch == ref.branch and dpsi <= psi_tol),
    ]  # fmt: skip
    if problem.obstacles:
        checks += [
            (f"clearance ≥ d_s: min {closest * 1e3:.2f} mm vs d_s = {d_safe * 1e3:g} mm", closest >= d_safe - 1e-4),
            (f"obstacle limit needed: without it the min clearance is {free_closest * 1e3:.1f} mm < d_s",
             free_closest < d_safe),
        ]  # fmt: skip
    link = [n.replace("_capsule", "") for n in log.link_names]
    fi = feasible_intervals(robot, problem.poses[0])
    open_branches = [str(b) for b in fi.branch if fi[int(b)]]
    if problem.obstacles:
        ref_d = distances(robot.capsule_segments(ref.q), robot.capsule_radii, problem.obstacles).d.min(axis=1)
        what = f"soft minimum of the clearances capped at d_i + {MARGIN_WEIGHT:g} × joint-limit margin, clearance ≥ d_s"
        its = f"; its clearances (mm): {', '.join(f'{n} {d * 1e3:.0f}' for n, d in zip(link, ref_d))}"
    else:
        what, its = f"{MARGIN_WEIGHT:g} × joint-limit margin (no obstacles)", ""
    cert = f"certified to {ref.gap:.1e}" if ref.certified else f"not certified: {ref.message}"
    lines = [
        f"# {problem.name} (reach)",
        "",
        problem.description,
        "",
        f"{robot.name} from q_home to the target, {duration:g} s at dt = {dt:g} s;"
        f" d_s = {d_safe:g} m, d_i = {d_influence:g} m, ξ = {xi:g} m/s.",
        "",
        f"1. Closed form: the branches with ψ inside the joint limits (exact feasible intervals) are"
        f" {', '.join(open_branches) or 'none'}; q_home is on branch {runs.start_branch}.",
        f"2. NLP (qpik.solve_best over branch {runs.start_branch}, objective: {what}): branch {ref.branch},"
        f" ψ = {ref.param:.4f} rad, {ref.quantity.text(ref.objective)}, {ref.quantity.sense}, {cert},"
        f" {ref.time * 1e3:.1f} ms to solve;"
        f" q_ref = {np.array2string(ref.q, precision=3)}{its}.",
        f"3. QP controller from q_home toward the target with q_ref as its posture reference: final"
        f" configuration on branch {branch}, ψ = {psi:.4f} rad.",
        "",
        "| run | final position error (mm) | final orientation error (rad) | min clearance (mm) |"
        " min limit margin (rad) | QP median solve (µs) |",
        "|---|---|---|---|---|---|",
        *(
            f"| {lg.label} | {sm.final_pos_error * 1e3:.3g} | {sm.final_rot_error:.3g} |"
            f" {sm.min_clearance.min(initial=np.inf) * 1e3:.1f} | {sm.min_limit_margin:.3f} |"
            f" {sm.solve_time.get('median', np.nan) * 1e6:.0f} |"
            for lg, sm in ((log, summ), (free, free_s))
        ),
        "",
        "Min clearance per link with the obstacle limit (mm): "
        + ", ".join(f"{n} {d * 1e3:.1f}" for n, d in zip(link, summ.min_clearance)),
        "Min joint-limit margin per joint (rad): " + ", ".join(f"q{j + 1} {m:.3f}" for j, m in enumerate(margins)),
        "",
        *(f"- {_verdict(ok)}: {text}" for text, ok in checks),
        "",
        f"Overall: {_verdict(all(ok for _, ok in checks))}",
        "",
        f"Plots: {problem.name}_log.png, {problem.name}_free_log.png"
        + (f", {strip.name}" if strip is not None else " (no snapshot strip: it needs OpenGL)"),
    ]
    return "\n".join(lines)
