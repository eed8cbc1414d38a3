r"""Three-way cross-validation of the closed form, the NLP and the QP controller on one pose.

For a pose and a smooth objective f (:mod:`qpik.objectives`):

(a) :func:`qpik.solve_best`: the best branch and δ/ψ — the global minimum of f over the
    self-motion of the closed form, inside the limits and clear of the obstacles (and, with the scene's
    self-collision, with its checked capsule pairs ≥ d_s apart);
(b) :func:`qpik.nlp.solve_full` started at (a)'s configuration: f minimised over the 7 joints
    with the pose as an equality constraint, by IPOPT;
(c) the QP controller (:class:`qpik.Controller`) at (a)'s configuration, with the same target (a
    :class:`~qpik.control.tasks.FrameTask` that dominates) and f as its secondary task
    (:class:`~qpik.control.tasks.ObjectiveTask`), the joint limits and the obstacles' velocity
    dampers at the same d_s (:class:`~qpik.control.limits.obstacle.ObstacleLimit` without its buffer), and with
    self-collision the dampers of the same capsule pairs (:class:`~qpik.control.self_collision.SelfCollisionLimit`).

All three state the same first-order optimality: at a minimum of f on the self-motion manifold
{q : fk(q) = pose}, ∇f is a combination of the pose constraints' gradients, the active joint
limits and the active clearance constraints. So (b) must stay at (a)'s q with the same f and a
vanishing KKT residual, and (c) must return a zero velocity: a nonzero self-motion component
would mean f can still decrease along the self-motion. The step of (c) is
:math:`v = -(2 J^T W J + 2\lambda I)^{-1} w \nabla f` when nothing is active, so the frame weight W
is large (:data:`FRAME_WEIGHT`) to make the part of ∇f in the row space of J (which W trades
against the target) negligible, and the damping λ small (:data:`DAMPING`), so that a self-motion
gradient :math:`N \nabla f` shows up amplified by w/λ.

Tolerances (issue): same q to 1e-6 rad, same f to 1e-8, KKT residual of (b) ≤ 1e-8, :math:`|v|` of (c)
≤ 1e-6 rad/s. A disagreement is reported in :attr:`CrossCheck.failures`, never hidden.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from qpik.control.controller import Controller
from qpik.control.limits import ConfigurationLimit, ObstacleLimit
from qpik.control.self_collision import SelfCollisionLimit
from qpik.control.tasks import DampingTask, FrameTask, ObjectiveTask
from qpik.core.errors import InputError
from qpik.core.validate import count, single_pose
from qpik.nlp.best import solve_best
from qpik.nlp.best_result import BestResult
from qpik.nlp.full import FullResult, solve_full
from qpik.nlp.options import BestOptions, FullOptions
from qpik.objectives import Objective
from qpik.robots.robot import Robot
from qpik.robots.self_pairs import candidate_pairs
from qpik.scene.scene import Scene, scene_of

FRAME_WEIGHT = 1e8
"""Weight of the QP's frame task, per m² (and rad²)."""
OBJECTIVE_WEIGHT = 1e-3
"""Weight w of the QP's objective task."""
DAMPING = 1e-6
"""λ of the QP's damping task."""
TOL_Q, TOL_F, TOL_KKT, TOL_V = 1e-6, 1e-8, 1e-8, 1e-6
"""The agreement required: rad, objective units, KKT residual, rad/s."""


@dataclass
class CrossCheck:
    r"""The three answers for one pose and how far apart they are.

    Attributes:
        best: (a), :class:`~qpik.nlp.best_result.BestResult`.
        full: (b), :class:`~qpik.nlp.full.FullResult` (None when not applicable).
        velocity: (c), the QP's step (n,), rad/s (None when not applicable).
        q_gap: :math:`\max |q_b - q_a|`, rad; f_gap: :math:`|f_b - f_a|`; kkt: (b)'s KKT residual;
            speed: :math:`\max |v|` of (c) (each +inf when not applicable).
        failures: the checks that failed, in words ([] when all agree).
        applicable: False when (a) has no answer (no feasible or no reachable configuration): then
            nothing was compared.
        random_rate: of :attr:`random_starts` IPOPT runs from random configurations alone, the
            fraction that reached the pose with f within :data:`TOL_F` of (a) (None if none were run).
    """

    best: BestResult
    full: FullResult | None
    velocity: np.ndarray | None
    q_gap: float
    f_gap: float
    kkt: float
    speed: float
    failures: list[str] = field(default_factory=list)
    applicable: bool = True
    random_starts: int = 0
    random_rate: float | None = None

    @property
    def passed(self) -> bool:
        """All three agree (False when not applicable)."""
        return self.applicable and not self.failures

    def report(self) -> str:
        """A few lines: the three answers and the verdict."""
        if not self.applicable:
            return f"(a) has no answer, nothing to compare: {self.best.summary()}"
        quantity = self.best.quantity
        f = quantity.minimised or quantity.name
        lines = [
            f"(a) solve_best: {self.best.summary()}",
            f"(b) full-joint NLP from (a): max |Δq| = {self.q_gap:.2e} rad, |Δf| = {self.f_gap:.2e} (f = {f},"
            f" minimised), KKT residual {self.kkt:.2e}",
            f"(c) QP controller at (a): max |v| = {self.speed:.2e} rad/s",
        ]
        if self.random_starts:
            lines.append(
                f"full-joint NLP from {self.random_starts} random starts alone:"
                f" {self.random_rate:.0%} reach the global optimum"
            )
        lines.append("agree: all three" if self.passed else "DISAGREE: " + "; ".join(self.failures))
        return "\n".join(lines)


def crosscheck(
    robot: Robot | Scene,
    pose: np.ndarray,
    objective: Objective | str | None = None,
    obstacles=None,
    q_ref: np.ndarray | None = None,
    *,
    d_safe: float | None = None,
    random_starts: int = 0,
    seed: int = 0,
) -> CrossCheck:
    """Solve (a), (b), (c) of the module docstring for ``pose`` and compare them.

    Args:
        robot: an arm with a closed form, or a :class:`~qpik.scene.Scene` of one (then ``objective``,
            ``obstacles``, ``q_ref`` and ``d_safe`` are the scene's).
        pose: (4, 4) end-effector pose, base frame.
        objective: a smooth objective (or its name); default: the smooth margin.
        obstacles: shapes (base frame), with the clearance constraint ≥ ``d_safe`` (m; default 0.02).
        q_ref: (n,) reference configuration, rad (a ``"distance"`` objective's).
        random_starts: also run the full-joint NLP from this many random configurations
            (seeded with ``seed``) and report how often it reaches (a)'s optimum.

    Raises:
        InputError: a non-smooth objective (the QP needs its gradient), bad input (naming the argument).
    """
    scene = scene_of(robot, obstacles, d_safe, objective, q_ref).with_objective("smooth-margin")
    robot, obj = scene.robot, scene.objective
    pose = single_pose(pose, "pose")
    random_starts, seed = count(random_starts, "random_starts"), count(seed, "seed")
    if not obj.smooth:
        raise InputError(
            f"objective: the cross-check needs a smooth objective (its gradient is the QP's task), got {obj.name}"
        )
    best = solve_best(scene, pose, options=BestOptions(certify=False))
    if best.status != "optimal":
        return CrossCheck(best, None, None, np.inf, np.inf, np.inf, np.inf, applicable=False)
    full = solve_full(scene, pose, options=FullOptions(q0=best.q, starts=1, max_starts=1))
    velocity, qp_status = _qp_step(scene, pose, best.q)
    q_gap = float(np.abs(full.q - best.q).max())
    f_gap = float(abs(full.objective - best.objective))
    speed = float(np.abs(velocity).max())
    failures = []
    if full.status != "optimal":
        failures.append(f"(b) did not converge: {full.message or full.status}")
    if not q_gap <= TOL_Q:
        failures.append(f"(b) moved {q_gap:.2e} rad from (a) (> {TOL_Q:g})")
    if not f_gap <= TOL_F:
        failures.append(f"(b)'s objective differs by {f_gap:.2e} (> {TOL_F:g})")
    if not full.kkt <= TOL_KKT:
        failures.append(f"(b)'s KKT residual is {full.kkt:.2e} (> {TOL_KKT:g})")
    if qp_status == "failed":  # its v = 0 would pass the next check: a failure is reported, never hidden
        failures.append("(c) the QP controller found no solution at (a)'s configuration")
    if not speed <= TOL_V:
        failures.append(f"(c) moves at {speed:.2e} rad/s (> {TOL_V:g})")
    out = CrossCheck(best, full, velocity, q_gap, f_gap, full.kkt, speed, failures)
    if random_starts:
        rng = np.random.default_rng(seed)
        hits = 0
        for _ in range(random_starts):
            q0 = rng.uniform(robot.q_min, robot.q_max)
            r = solve_full(scene, pose, options=FullOptions(q0=q0, starts=1, max_starts=1))
            hits += r.status == "optimal" and r.objective <= best.objective + TOL_F
        out.random_starts, out.random_rate = random_starts, hits / random_starts
    return out


def _qp_step(scene: Scene, pose: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, str]:
    """(c): one step of the QP controller at q (daqp, exact) with the target, f as a task, limits and dampers:
    its velocity (n,), rad/s, and the step's status (``"failed"``: no QP solution, v = 0)."""
    robot, obj, obs, q_ref, d_safe = scene.robot, scene.objective, scene.obstacles, scene.q_ref, scene.d_safe
    dt = 0.01
    tasks = [
        FrameTask(pose, 1.0 / dt, 1.0 / dt, FRAME_WEIGHT, FRAME_WEIGHT),
        ObjectiveTask(robot, obj, OBJECTIVE_WEIGHT, q_ref=q_ref, obstacles=obs),
        DampingTask(DAMPING),
    ]
    limits = [ConfigurationLimit()]
    if len(obs):
        limits.append(ObstacleLimit(obs, d_influence=d_safe + 0.1, d_safe=d_safe, xi=0.5, buffer=0.0))
    if scene.self_pairs:
        allowed = frozenset(candidate_pairs(robot)) - frozenset(scene.self_pairs)
        limits.append(SelfCollisionLimit(allowed, d_influence=d_safe + 0.1, d_safe=d_safe, xi=0.5, buffer=0.0))
    ctrl = Controller(robot, tasks, limits, solver="daqp", dt=dt)
    v = ctrl.step(q)
    return v, ctrl.last.status
