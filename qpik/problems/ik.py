"""The ``ik`` runner of ``qpik run``, and the branch table with FK residuals of ``qpik ik``.

A problem of kind ``ik`` gives N target poses and M parameter values (δ or ψ,
rad). The runner solves all N·M cases in one batched :func:`qpik.ik` call and
reports, as Markdown text:

- against ``[expected] q`` (a paper's table, one pose and one parameter): the
  paper's row and qpik's answer per branch, the per-joint difference after
  wrapping to (-π, π], the largest difference and PASS/FAIL against
  ``[expected] tolerance``; the FK position error of the paper's rounded rows
  against ``[expected] fk_tolerance``;
- for targets made from joint angles (``[target] q`` or ``random``): whether
  one branch at the parameter of each target gives it back (``tolerance``);
- for sweeps (several parameters or several poses): a compact table of the
  chosen branch (``[solver] branch``, default the first branch or the target's)
  per step, and figures: the self-motion map and the overlaid stick figures
  (one pose, several parameters) or the joint angles against the swept position
  coordinate (several poses; one panel per parameter value);
- for one pose and one parameter: the branch poses picture.

Every solution (all branches, all cases) goes to ``<name>_solutions.csv`` with
full precision and its FK residual (position m, rotation rad).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.api import IKSolutions, ik, redundancy_parameter, symbol
from qpik.analytic.intervals import apart, wrap
from qpik.core.errors import ProblemFileError
from qpik.problems.runners import runner
from qpik.robots.robot import Robot

if TYPE_CHECKING:
    from qpik.problems.schema import Problem

FK_TOL = 1e-9  # m and rad: qpik's own solutions must reach the pose to this
MAX_ROWS = 19  # rows of a compact sweep table (all rows are in the CSV)
OVERLAY_MAX = 9  # configurations overlaid in one stick figure


def fk_residual(robot: Robot, q: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """FK error of ``q`` (..., n) against poses ``T`` (broadcast to (..., 4, 4)).

    Returns the position error ``‖p(q) − p‖`` (m) and the rotation angle
    ``2 asin(‖R(q) − R‖_F / 2√2)`` (rad) between the two orientations, each of shape (...).
    """
    q = np.asarray(q, dtype=float)
    F = robot.fk(q.reshape(-1, q.shape[-1])).reshape(*q.shape[:-1], 4, 4)
    T = np.broadcast_to(T, F.shape)
    pos = np.linalg.norm(F[..., :3, 3] - T[..., :3, 3], axis=-1)
    chord = np.linalg.norm(F[..., :3, :3] - T[..., :3, :3], axis=(-2, -1)) / (2.0 * np.sqrt(2.0))
    return pos, 2.0 * np.arcsin(np.minimum(chord, 1.0))


def branch_table(robot: Robot, sols: IKSolutions, T: np.ndarray) -> str:
    """``sols.table()`` of one pose with the FK residual of each valid branch (m, rad) appended."""
    pos, rot = fk_residual(robot, sols.q, T)
    lines = sols.table().splitlines()
    out = [lines[0] + f"  {'fk pos [m]':>10} {'fk rot [rad]':>12}"]
    for i, line in enumerate(lines[1:]):
        res = f"{pos[i]:10.1e} {rot[i]:12.1e}" if sols.valid[i] else f"{'-':>10} {'-':>12}"
        out.append(f"{line}  {res}")
    return "\n".join(out)


@runner("ik")
def run_ik(problem: Problem, out: Path) -> str:
    """Solve an ``ik`` problem; write the CSV and figures under ``out``; return the Markdown report."""
    robot, poses = problem.robot, problem.poses
    if problem.params is None and problem.q_targets is None:
        raise ProblemFileError(f"{problem.file}: an ik problem needs [parameter] unless its target is given as q")
    N = poses.shape[0]
    grid = _solve_grid(robot, poses, problem.params, problem.q_targets)
    sym = symbol(grid.param_name)
    lines = [f"# {problem.name} ({robot.name}, closed form in {sym})", ""]
    lines += [x for x in (problem.description, f"Source: {problem.source}" if problem.source else "") if x]
    lines.append("")
    csv = out / f"{problem.name}_solutions.csv"
    _write_csv(csv, grid)
    pos, rot = grid.pos, grid.rot
    ok_fk = bool(np.all((pos[grid.valid] <= FK_TOL) & (rot[grid.valid] <= FK_TOL)))
    checks: list[tuple[str, bool]] = [(f"FK of every valid branch reaches its pose within {FK_TOL:g}", ok_fk)]
    lines.append(
        f"{N} pose(s) x {grid.q.shape[1]} {sym} value(s) x {grid.q.shape[2]} branches; "
        f"valid: {int(grid.valid.sum())}, within limits: {int(grid.within.sum())}; "
        f"largest FK residual {_max(pos[grid.valid]):.1e} m, {_max(rot[grid.valid]):.1e} rad"
    )
    lines.append("")
    if "q" in problem.expected:
        text, passed = _compare_expected(problem, grid, poses)
        lines += text
        checks += passed
    if problem.q_targets is not None:
        text, passed = _recovery(problem, poses)
        lines += text
        checks.append(passed)
    figures = _sweep_section(problem, grid, poses, out, lines)
    lines += ["## Checks", ""]
    lines += [f"- {'PASS' if ok else 'FAIL'}: {what}" for what, ok in checks]
    verdict = "PASS" if all(ok for _, ok in checks) else "FAIL"
    lines += ["", f"**{verdict}**", "", "Files:", f"- {csv.name}: every branch of every case (full precision)"]
    lines += [f"- {name}: {what}" for name, what in figures]
    notes = problem.expected.get("notes")
    if notes:
        lines += ["", "Notes from the problem file:", "", str(notes).strip()]
    return "\n".join(lines) + "\n"


class _Grid:
    """Solutions of N poses x M parameters: q (N, M, B, n), valid/within (N, M, B), params (N, M).

    ``pos``, ``rot`` (N, M, B): FK residuals (m, rad) of every row, valid or not.
    """

    def __init__(self, sols: IKSolutions, N: int, M: int, robot: Robot, poses: np.ndarray):
        B, n = sols.q.shape[-2:]
        self.q = sols.q.reshape(N, M, B, n)
        self.valid = sols.valid.reshape(N, M, B)
        self.within = sols.within_limits.reshape(N, M, B)
        self.singular = sols.singular.reshape(N, M, B)
        self.params = np.asarray(sols.param).reshape(N, M)
        self.branch = sols.branch
        self.param_name = sols.param_name
        self.pos, self.rot = fk_residual(robot, self.q, poses[:, None, None])

    def single(self, i: int, k: int) -> IKSolutions:
        return IKSolutions(
            self.q[i, k],
            self.valid[i, k],
            self.within[i, k],
            self.singular[i, k],
            self.branch,
            float(self.params[i, k]),
            self.param_name,
        )


def _solve_grid(robot: Robot, poses: np.ndarray, params: np.ndarray | None, q_targets: np.ndarray | None) -> _Grid:
    """All N x M cases in one batched call; without params, each pose at its target's own parameter."""
    N = poses.shape[0]
    P = np.asarray(redundancy_parameter(robot, q_targets)[0])[:, None] if params is None else np.tile(params, (N, 1))
    M = P.shape[1]
    sols = ik(robot, np.repeat(poses, M, axis=0), P.ravel())
    return _Grid(sols, N, M, robot, poses)


def _compare_expected(problem: Problem, grid: _Grid, poses: np.ndarray) -> tuple[list[str], list[tuple[str, bool]]]:
    """The paper's rows beside qpik's per branch; wrapped differences; PASS/FAIL."""
    robot, exp = problem.robot, problem.expected
    if grid.q.shape[:2] != (1, 1):
        raise ProblemFileError(f"{problem.file}: expected.q needs one pose and one parameter value")
    q_exp = np.atleast_2d(exp["q"])
    ids = np.asarray(exp.get("branches", grid.branch[: len(q_exp)]))
    tol = problem.expected_number("tolerance", 0.05)
    sym = symbol(grid.param_name)
    idx = [int(np.flatnonzero(grid.branch == b)[0]) for b in ids]
    q = grid.q[0, 0, idx]
    valid = grid.valid[0, 0, idx]
    diff = np.abs(wrap(q - q_exp))
    diff[~valid] = np.inf
    heads = " ".join(f"{'θ' + str(j + 1):>6}" for j in range(robot.dof))
    lines = [
        f"## Expected rows ({sym} = {grid.params[0, 0]:.4f} rad)",
        "",
        "Per branch: the file's row, qpik's answer, |difference| wrapped to (-π, π] (rad).",
        "",
        "```",
        f"{'branch':>6} {'':5} {heads}  {'max':>6} {'limits':>6}",
    ]
    for r, b in enumerate(ids):
        fmt = lambda v: " ".join(f"{x:6.2f}" for x in v)  # noqa: E731
        lim = "in" if grid.within[0, 0, idx[r]] else ("out" if valid[r] else "none")
        lines += [
            f"{b:>6} {'file':5} {fmt(q_exp[r])}",
            f"{'':>6} {'qpik':5} {fmt(q[r])}" if valid[r] else f"{'':>6} qpik  (branch not valid)",
            f"{'':>6} {'|Δ|':5} {' '.join(f'{x:6.3f}' for x in diff[r])}  {diff[r].max():6.3f} {lim:>6}",
        ]
    lines.append("```")
    worst = float(diff.max())
    lines += ["", f"Max difference: {worst:.4f} rad (tolerance {tol:g} rad)", ""]
    checks = [(f"every expected row within {tol:g} rad of qpik's branch (max {worst:.4f} rad)", worst <= tol)]
    if "fk_tolerance" in exp:
        ftol = problem.expected_number("fk_tolerance")
        p_err, _ = fk_residual(robot, q_exp, poses[0])
        lines += [f"FK of the file's rounded rows: position error up to {p_err.max() * 1e3:.1f} mm", ""]
        checks.append((f"the file's rows reach p within {ftol:g} m (max {p_err.max():.4f} m)", p_err.max() <= ftol))
    return lines, checks


def _recovery(problem: Problem, poses: np.ndarray) -> tuple[list[str], tuple[str, bool]]:
    """For targets made from q: one branch at the parameter of q gives q back."""
    robot, qt = problem.robot, problem.q_targets
    tol = problem.expected_number("tolerance", 1e-9)
    par, br = redundancy_parameter(robot, qt)
    sols = ik(robot, poses, np.asarray(par))
    err = apart(sols.q, qt[:, None, :])
    err[~sols.valid] = np.inf
    best = err.min(axis=1)
    hit = sols.branch[err.argmin(axis=1)]
    sym = symbol(sols.param_name)
    lines = ["## Target configurations", ""]
    if len(qt) == 1:
        lines.append(
            f"Target q = {np.array2string(qt[0], precision=4)}: {sym} = {float(par[0]):.6f} rad, "
            f"branch {int(br[0])}; at that {sym}, branch {int(hit[0])} returns q within {best[0]:.1e} rad"
        )
    else:
        lines.append(
            f"{len(qt)} targets: at each target's own {sym}, the closest branch returns q within {best.max():.1e} rad"
        )
    lines.append("")
    same = bool(np.all(hit == br))
    what = f"one branch at the {sym} of each target q returns it within {tol:g} rad (max {best.max():.1e})"
    return lines, (
        what + ("" if same else "; branch ids differ from redundancy_parameter's"),
        bool(best.max() <= tol and same),
    )


def _sweep_section(
    problem: Problem, grid: _Grid, poses: np.ndarray, out: Path, lines: list[str]
) -> list[tuple[str, str]]:
    """Compact table(s) and figures; returns (file name, what it shows)."""
    from qpik.plots import save  # Matplotlib: not for qpik ik's branch_table
    from qpik.plots.closed_form import branch_pictures, selfmotion_map, stick_overlay, sweep_figure

    robot, name = problem.robot, problem.name
    N, M = grid.q.shape[:2]
    sym = symbol(grid.param_name)
    b = _chosen_branch(problem, grid)
    j = int(np.flatnonzero(grid.branch == b)[0])
    figures: list[tuple[str, str]] = []
    if N == 1 and M == 1:
        f = f"{name}_branches.png"
        how = branch_pictures(robot, grid.single(0, 0), out / f)
        figures.append((f, f"every valid branch at {sym} = {grid.params[0, 0]:.2f} rad ({how})"))
    if N == 1:
        f = f"{name}_selfmotion.png"
        save(selfmotion_map(robot, poses[0], shade_branch=b), out / f)
        figures.append((f, f"self-motion map: each joint against {sym}, all branches; grey = branch {b} out of limits"))
    if N == 1 and M > 1:
        lines += _table(f"{sym} [rad]", grid.params[0], grid, (0, slice(None), j), b)
        ok = grid.valid[0, :, j].copy()
        ok &= np.isin(np.arange(len(ok)), _thin(len(ok), OVERLAY_MAX))
        if ok.any():
            f = f"{name}_overlay.png"
            labels = [f"{sym} = {p:+.2f}" for p in grid.params[0, ok]]
            p0, p1 = grid.params[0, 0], grid.params[0, -1]
            title = (
                f"{robot.name}, branch {b}: one end-effector pose, {sym} = {p0:+.2f} … {p1:+.2f} rad (where it reaches)"
            )
            save(stick_overlay(robot, grid.q[0, ok, j], labels, title), out / f)
            figures.append((f, f"branch {b} at each {sym}, overlaid in 3-D and on the x-y plane"))
    if N > 1:
        x, axis = _swept(poses)
        if axis is None:
            return figures
        curves = []
        for k in range(M):
            lines += [f"### {sym} = {grid.params[0, k]:.2f} rad", ""]
            lines += _table(f"p_{axis} [m]", x, grid, (slice(None), k, j), b)
            curves.append((f"{sym} = {grid.params[0, k]:.2f} rad, branch {b}", grid.q[:, k, j], grid.valid[:, k, j]))
        f = f"{name}_sweep.png"
        title = f"{robot.name}: joint angles of branch {b} against p_{axis}"
        save(sweep_figure(robot, x, curves, f"p_{axis} [m]", title), out / f)
        figures.append((f, f"joint angles of branch {b} against p_{axis}, one panel per {sym}"))
    return figures


def _chosen_branch(problem: Problem, grid: _Grid) -> int:
    """``[solver] branch``, else the branch of the (first) target q, else the first branch."""
    if problem.solver["branch"] is not None:
        b = problem.solver["branch"]
        if b not in grid.branch:
            raise ProblemFileError(f"{problem.file}: solver.branch {b} is not one of {grid.branch.tolist()}")
        return b
    if problem.q_targets is not None:
        return int(redundancy_parameter(problem.robot, problem.q_targets[0])[1])
    return int(grid.branch[0])


def _swept(poses: np.ndarray) -> tuple[np.ndarray, str | None]:
    """The position coordinate that varies along a sweep of poses with one rotation, else (index, None)."""
    same_rot = np.allclose(poses[:, :3, :3], poses[0, :3, :3])
    spread = np.ptp(poses[:, :3, 3], axis=0)
    if not same_rot or np.count_nonzero(spread > 1e-12) != 1:
        return np.arange(len(poses), dtype=float), None
    a = int(np.argmax(spread))
    return poses[:, a, 3], "xyz"[a]


def _table(xlabel: str, x: np.ndarray, grid: _Grid, at: tuple, b: int) -> list[str]:
    """Compact rows (at most MAX_ROWS, evenly spread, last one kept) of branch ``b`` along a sweep.

    ``at`` indexes ``grid.q[..., :]`` down to one sweep of that branch (S, n).
    """
    q, valid, within, miss = grid.q[at], grid.valid[at], grid.within[at], grid.pos[at]
    rows = _thin(len(x), MAX_ROWS)
    step = rows[1] - rows[0] if len(rows) > 1 else 1
    heads = " ".join(f"{'θ' + str(j + 1):>7}" for j in range(q.shape[1]))
    lines = [f"Branch {b}" + (f" (one step in {step}; all in the CSV)" if step > 1 else ""), "", "```"]
    lines.append(f"{xlabel:>11} {heads}  valid limits")
    for r in rows:
        vals = " ".join(f"{v:7.3f}" for v in q[r]) if valid[r] else " ".join(f"{'-':>7}" for _ in q[r])
        lines.append(f"{x[r]:11.3f} {vals}  {'yes' if valid[r] else 'no':>5} {'in' if within[r] else 'out':>6}")
    lines += ["```", ""]
    span = np.where(valid[:, None], q, np.nan)
    if valid.any():
        lo, hi = np.nanmin(span, axis=0), np.nanmax(span, axis=0)
        lines += [
            "Range over the sweep: " + ", ".join(f"θ{j + 1} [{lo[j]:.2f}, {hi[j]:.2f}]" for j in range(len(lo))),
            "",
        ]
    if not valid.all():
        where = ", ".join(f"{v:.3f}" for v in x[~valid])
        lines += [
            f"Branch {b} does not reach the pose at {xlabel.split()[0]} = {where}: the closed form flags these "
            f"steps invalid (its boundary answer misses the position by up to {miss[~valid].max() * 1e3:.2f} mm).",
            "",
        ]
    return lines


def _thin(n: int, most: int) -> list[int]:
    """About ``most`` indices of ``range(n)``, evenly spread, first and last kept."""
    step = -(-n // most)
    return sorted(set(range(0, n, step)) | {n - 1})


def _write_csv(path: Path, grid: _Grid) -> None:
    N, M, B, n = grid.q.shape
    pos, rot = grid.pos, grid.rot
    head = ["pose", grid.param_name, "branch", *[f"q{j + 1}" for j in range(n)], "valid", "within_limits", "singular"]
    rows = [",".join([*head, "fk_pos_m", "fk_rot_rad"])]
    for i in range(N):
        for k in range(M):
            for c in range(B):
                vals = [str(i), repr(float(grid.params[i, k])), str(int(grid.branch[c]))]
                vals += [repr(float(v)) for v in grid.q[i, k, c]]
                vals += [
                    str(int(grid.valid[i, k, c])),
                    str(int(grid.within[i, k, c])),
                    str(int(grid.singular[i, k, c])),
                ]
                vals += [f"{pos[i, k, c]:.3e}", f"{rot[i, k, c]:.3e}"]
                rows.append(",".join(vals))
    path.write_text("\n".join(rows) + "\n")


def _max(x: np.ndarray) -> float:
    return float(x.max()) if x.size else 0.0
