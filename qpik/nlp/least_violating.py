r"""The answer of :func:`~qpik.nlp.best.solve_best` for a pose without a feasible point: :func:`least_violating`.

Every branch's closed form is evaluated at :data:`VIOLATION_SAMPLES` parameters over [−π, π). The
answer is the configuration nearest to a solution: the smallest pose error
:math:`\sqrt{|\Delta p|^2 + \theta^2}` (m and rad; θ the angle of :math:`R^* R^\top`) when no branch
reaches the pose, else the largest clearance (m) inside the limits, else the smallest excursion
outside the limits (rad). Its objective is +inf.
"""

from __future__ import annotations

import numpy as np

from qpik.analytic.intervals import wrap
from qpik.analytic.solver import AnalyticSolver
from qpik.nlp.best_result import BestResult, BranchRows
from qpik.nlp.run import BestRun
from qpik.objectives import clearance
from qpik.robots.robot import Robot

VIOLATION_SAMPLES = 720
"""Parameter samples per branch when looking for the least-violating branch."""


def least_violating(
    scene: BestRun, i: int, rows: BranchRows | None, status: str | None = None, message: str = ""
) -> BestResult:
    """The answer for pose i when the search has none: unreachable, or the least-violating configuration.

    Every branch's closed form (compiled, :meth:`~qpik.analytic.solver.AnalyticSolver.solve_many`) at
    :data:`VIOLATION_SAMPLES` parameters. If no branch reaches the pose, the status is
    ``"unreachable"`` and q is the configuration (the closed form clamps what it cannot reach) whose
    pose error (:func:`qpik.algebra.lie.pose_error`) has the smallest norm, its norm the violation. Otherwise
    ``"no feasible branch"``: inside the limits but never clear of the obstacles, the configuration
    with the largest clearance (violation d_s minus it, m); else the one least outside the limits
    (rad). ``status`` replaces the status (a solver failure keeps this configuration as its q).
    The objective is +inf.
    """
    robot, sm = scene.robot, scene.selfmotion
    name = sm.solver.param_name
    psi = np.linspace(-np.pi, np.pi, VIOLATION_SAMPLES, endpoint=False)
    T = scene.poses[i]
    sol = sm.solver.solve_many(T, psi)
    if not sol.valid.any():
        k, b, err = _closest(robot, T, sol.q)
        why = message or "no branch reaches the pose at any parameter"
        return BestResult(status or "unreachable", -1, float(psi[k]), sol.q[k, b].copy(), np.inf, violation=err,
                          rows=rows, param_name=name, message=why)  # fmt: skip
    beyond = np.maximum(robot.q_min - sol.q, sol.q - robot.q_max).max(axis=2)  # (M, B) rad outside the limits
    within = sol.within_limits
    if within.any() and (len(scene.obstacles) or scene.self_pairs):
        # inside the limits but never clear: the configuration with the largest clearance
        k, b = np.nonzero(within)
        Q = sol.q[k, b]
        clear = clearance(robot, Q, scene.obstacles)  # the pairs of fixed capsules constrain nothing
        clear = np.minimum(clear, scene.problem.self_clearance(Q))
        j = int(np.argmax(clear))
        violation = max(float(scene.d_safe - clear[j]), 0.0)
        at, br, q = psi[k[j]], b[j], Q[j]
    else:
        score = np.where(sol.valid, np.maximum(beyond, 0.0), np.inf)
        k, br = np.unravel_index(int(np.argmin(score)), score.shape)
        violation, at, q = float(score[k, br]), psi[k], sol.q[k, br]
    why = "no branch keeps the joints in their limits" + (" and clear of the obstacles" if len(scene.obstacles) else "")
    why += " and its capsules apart" if scene.self_pairs else ""
    return BestResult(status or "no feasible branch", int(sm.branch_ids[br]), float(wrap(at)), q.copy(), np.inf,
                      violation=violation, rows=rows, param_name=name, message=message or why)  # fmt: skip


def build_sweep(solver: AnalyticSolver, pose: np.ndarray) -> None:
    """Compile now the sweep :func:`least_violating` evaluates with ``solver`` (any pose (4, 4) will do), else the first
    pose without a feasible point compiles it inside its solve."""
    solver.solve_many(pose, np.zeros(VIOLATION_SAMPLES))


def _closest(robot: Robot, target: np.ndarray, Q: np.ndarray, stride: int = 8) -> tuple[int, int, float]:
    """The sample k and branch b of configurations Q (M, B, n) whose pose is closest to ``target`` (4, 4), and its
    error (:func:`_pose_error_norm`): every ``stride``-th sample of every branch first, then every sample within
    ``stride`` of the closest one on its branch."""
    M, B, n = Q.shape
    coarse = np.ascontiguousarray(Q[::stride]).reshape(-1, n)
    k, b = divmod(int(np.argmin(_pose_error_norm(target, robot.fk(coarse)))), B)
    near = (k * stride + np.arange(-stride, stride + 1)) % M
    err = _pose_error_norm(target, robot.fk(np.ascontiguousarray(Q[near, b])))
    j = int(np.argmin(err))
    return int(near[j]), b, float(err[j])


def _pose_error_norm(target: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(M,): ‖[p* − p; log(R* Rᵀ)]‖ of poses (M, 4, 4) toward ``target`` (4, 4): √(|Δp|² + θ²), θ the angle of R* Rᵀ."""
    dp = poses[:, :3, 3] - target[:3, 3]
    cos = 0.5 * (np.einsum("ij,mij->m", target[:3, :3], poses[:, :3, :3]) - 1.0)
    return np.sqrt((dp * dp).sum(axis=1) + np.arccos(np.clip(cos, -1.0, 1.0)) ** 2)
