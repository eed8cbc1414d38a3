r"""The answer of :func:`qpik.plan_self_motion`: a :class:`Plan`, its checks, its files and its retiming.

The checks (:func:`check`) are measured on the plan's configurations, independently of how they
were found:

- forward kinematics reproduces every waypoint: position error ‖p(q_k) − p_k‖ (m) and rotation
  angle of :math:`R_k^T R(q_k)` (rad), both ≤ :data:`FK_TOL`;
- every joint inside its limits (violation 0);
- clearance ≥ d_s with the link capsules (:func:`qpik.geometry.distances`) and with MuJoCo's
  ``mj_geomDistance`` between the collision geoms of the arm's MuJoCo model and the obstacles
  (:func:`qpik.robots.mujoco_scene.build_scene`; the twin of a catalog arm, the model of a loaded one), within
  :data:`CLEARANCE_TOL`;
- every continuous transition moves each joint by at most its bound;
- with self-collision (:attr:`qpik.scene.Scene.self_pairs`), the capsules of every checked pair ≥ d_s apart
  (:func:`qpik.robots.self_pairs.pair_distances`).

Both clearances are over the pairs :mod:`qpik.geometry.contacts` checks: a pair whose distance no joint motion
changes (a base column standing on its table) is left out and reported in :attr:`Plan.facts`.
A plan whose check fails is ``"failed"`` (kind ``"check"``), whatever made it (:func:`measure`).
"""

from __future__ import annotations

import io
import itertools
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra.lie import tracking_errors
from qpik.core.errors import InputError
from qpik.core.validate import count, finite_array
from qpik.geometry.contacts import capsule_clearance, capsule_facts
from qpik.geometry.distance import ObstacleSet
from qpik.robots.robot import Robot

if TYPE_CHECKING:
    from qpik.planning.setup import Setup

FK_TOL = 1e-9
"""m and rad: FK of the plan must reach every waypoint to this."""
CLEARANCE_TOL = 1e-6
"""m: clearance measured by MuJoCo may fall short of d_s by this (its geoms are the capsules rounded to float)."""
STEP_TOL = 1e-9
"""rad: a joint step may exceed its bound by this."""


@dataclass
class Check:
    """One check of a plan: its name, whether it holds and the measured figure in words."""

    name: str
    ok: bool
    text: str
    waypoint: int = -1
    """The first waypoint where it fails (-1: it holds, or it is not a per-waypoint figure)."""


@dataclass
class Profile:
    """A plan's parameter profile on the DP grid, for the self-motion map.

    Attributes:
        values: (G,) the grid's parameter values, rad; ok: (N, B, G) feasible states.
        branches: (B,) public branch ids of the grid rows.
        dp_param: (K,) the DP's parameter (rad, wrapped) and dp_row: (K,) its grid row at the planned waypoints.
    """

    values: np.ndarray
    ok: np.ndarray
    branches: np.ndarray
    dp_param: np.ndarray
    dp_row: np.ndarray


@dataclass
class Trajectory:
    """A retimed plan (:meth:`Plan.retime`): samples of q(t) and its derivatives.

    Attributes:
        t: (M,) times, s; q: (M, n) rad; qd: (M, n) rad/s; qdd: (M, n) rad/s².
        duration: s. segment: (M,) which continuous segment of the plan each sample is on (the arm
            stops at every reconfiguration; the reconfiguration's own motion is not timed).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    duration: float
    segment: np.ndarray


@dataclass
class Plan:
    """A joint trajectory that follows an end-effector path.

    Attributes:
        robot: the arm; poses: (N, 4, 4) the waypoints (base frame); times: (N,) s, or None.
        progress: (N,) path progress in [0, 1] (or the times, s, when given).
        q: (K, n) the configuration at each planned waypoint, rad (K = N unless the plan failed before the
            last waypoint; a plan that fails a check keeps all its configurations).
        param: (K,) the redundancy parameter (δ or ψ, rad, wrapped) and branch: (K,) the public branch id
            of each configuration (both empty for an arm without a closed form).
        param_name: ``"delta"``, ``"psi"`` or ``""``.
        status: ``"optimal"`` (the NLP improved the DP's plan, or refined the QP controller's run of an arm
            without a closed form), ``"dp"`` (the DP's plan: the NLP did not improve it or was not run),
            ``"tracking"`` (the QP controller's run of an arm without a closed form) or ``"failed"`` (see
            :attr:`failure`). The same on every arm, and derived from the checks: a plan is not failed if and
            only if every waypoint is planned and every one of its :attr:`checks` holds (:func:`measure`).
        failure: the first waypoint that cannot be planned, or the check that fails and where, and why; or "".
        failure_kind: ``"infeasible"`` (proved: no configuration of the exact feasible set at that waypoint),
            ``"grid"`` (every waypoint has feasible configurations but the DP's grid, refined, found no
            continuous transition: a motion may still exist), ``"check"`` (the computed plan fails one of its
            own :attr:`checks`) or "" (not failed).
        facts: the capsule–obstacle pairs left out of the checks (:mod:`qpik.geometry.contacts`), in words.
        least_violating: at that waypoint, the best the arm can do (a :class:`qpik.BestResult`'s summary), or "".
        reconfigurations: the waypoints k whose transition to k + 1 is a reconfiguration.
        cost: the objective J of the plan (of its planned waypoints), minimised (the joint motion plus the weighted
            point objective, whatever that measures); dp_cost: J of the plan the NLP started from (the DP's; without a
            closed form the QP controller's run).
        margin: (K,) the smallest distance to a joint limit, rad; clearance: (K,) the smallest capsule–obstacle
            distance, m (inf without obstacles); clearance_mujoco: (K,) the same measured by MuJoCo (empty when
            not measured); self_clearance: (K,) the smallest distance of the scene's capsule pairs, m (inf without
            self-collision);
            manipulability: (K,) Yoshikawa's.
        step_bound: (N-1, n) the largest move of each joint allowed between waypoints, rad.
        d_safe: m. checks: the :class:`Check` list. profile: the DP's :class:`Profile` (closed form only).
        timings: seconds per stage (``"dp"``, ``"nlp"``, ``"tracking"``), each without building and compiling its
            functions (:class:`qpik.core.stopwatch.Stopwatch`).
        label: what made it (``"NLP"``, ``"DP"``, a baseline's name).
        dp_plan: the DP's own plan, when the NLP replaced it. setup: the checked inputs (waypoints, weights,
            bounds) the plan was made for.
    """

    robot: Robot
    poses: np.ndarray
    times: np.ndarray | None
    progress: np.ndarray
    q: np.ndarray
    param: np.ndarray
    branch: np.ndarray
    param_name: str
    status: str
    step_bound: np.ndarray
    d_safe: float
    obstacles: ObstacleSet
    cost: float = np.inf
    dp_cost: float = np.inf
    failure: str = ""
    failure_waypoint: int = -1
    failure_kind: str = ""
    facts: list[str] = field(default_factory=list)
    least_violating: str = ""
    reconfigurations: list[int] = field(default_factory=list)
    margin: np.ndarray = field(default_factory=lambda: np.zeros(0))
    clearance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    clearance_mujoco: np.ndarray = field(default_factory=lambda: np.zeros(0))
    self_clearance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    manipulability: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fk_error: tuple[float, float] = (0.0, 0.0)
    max_step_ratio: float = 0.0
    checks: list[Check] = field(default_factory=list)
    profile: Profile | None = None
    timings: dict[str, float] = field(default_factory=dict)
    label: str = ""
    dp_plan: Plan | None = None
    setup: Setup | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.q)

    @property
    def ok(self) -> bool:
        """Every waypoint planned and every check holds (then and only then the status is not ``"failed"``)."""
        return self.status != "failed" and all(c.ok for c in self.checks)

    @property
    def path_length(self) -> float:
        """Σ ‖q_{k+1} − q_k‖ over the continuous transitions, rad."""
        d = np.linalg.norm(np.diff(self.q, axis=0), axis=1)
        keep = np.ones(len(d), bool)
        keep[[k for k in self.reconfigurations if k < len(d)]] = False
        return float(d[keep].sum())

    def summary(self) -> str:
        """One line: status, waypoints, reconfigurations, the objective J (minimised); when failed, which check
        or which waypoint and why."""
        if self.status == "failed":
            return f"failed at waypoint {self.failure_waypoint} ({self.failure_kind}): {self.failure}"
        rec = f"{len(self.reconfigurations)} reconfiguration(s)" + (
            f" (after waypoints {', '.join(map(str, self.reconfigurations))})" if self.reconfigurations else ""
        )
        return f"{self.status}: {len(self.q)} waypoints, {rec}, objective J = {self.cost:.8g} (minimised)"

    def to_csv(self, path: str | os.PathLike | None = None) -> str:
        """The plan as CSV text (one row per planned waypoint; written to ``path`` if given): progress, q (rad),
        parameter, branch, limit margin (rad), clearance (m, capsules and MuJoCo), manipulability; a column
        the plan does not have (no closed form, MuJoCo not measured) is left blank."""
        n = self.robot.dof

        def cell(x: np.ndarray, k: int) -> str:
            return repr(float(x[k])) if len(x) else ""

        head = ["waypoint", "progress", *[f"q{j + 1}" for j in range(n)], self.param_name or "param", "branch",
                "margin_rad", "clearance_m", "clearance_mujoco_m", "manipulability"]  # fmt: skip
        buf = io.StringIO()
        buf.write(",".join(head) + "\n")
        for k in range(len(self.q)):
            vals = [str(k), repr(float(self.progress[k])), *(repr(float(v)) for v in self.q[k]),
                    cell(self.param, k), str(int(self.branch[k])) if len(self.branch) else "",
                    cell(self.margin, k), cell(self.clearance, k), cell(self.clearance_mujoco, k),
                    cell(self.manipulability, k)]  # fmt: skip
            buf.write(",".join(vals) + "\n")
        text = buf.getvalue()
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            Path(path).write_text(text)
        return text

    def to_npz(self, path: str | os.PathLike) -> Path:
        """Write the plan's arrays (q, poses, progress, times, param, branch, margin, clearances,
        manipulability, reconfigurations) to ``path`` (numpy ``.npz``)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, q=self.q, poses=self.poses, progress=self.progress,
                 times=np.zeros(0) if self.times is None else self.times, param=self.param, branch=self.branch,
                 margin=self.margin, clearance=self.clearance, clearance_mujoco=self.clearance_mujoco,
                 manipulability=self.manipulability, reconfigurations=np.array(self.reconfigurations, int),
                 step_bound=self.step_bound)  # fmt: skip
        return path

    def retime(
        self, v_max: np.ndarray | None = None, a_max: np.ndarray | None = None, samples: int = 200
    ) -> Trajectory:
        """Time-optimal timing of the plan under joint velocity and acceleration limits (toppra).

        Each continuous segment (between reconfigurations) is a cubic spline through its configurations
        (``toppra.SplineInterpolator`` over the path progress), timed from rest to rest by TOPP-RA with
        ``JointVelocityConstraint`` and ``JointAccelerationConstraint`` (interpolation discretization) and
        the constant-acceleration parametrizer (toppra's default one overshoots the acceleration limit by a
        few per cent). The segments follow each other; the arm stops at every reconfiguration.

        Args:
            v_max: (n,) joint speed limits, rad/s (default the robot's).
            a_max: (n,) joint acceleration limits, rad/s² (default 4 × v_max per second).
            samples: samples per segment of the returned :class:`Trajectory` (an integer >= 2).
        """
        import toppra
        from toppra import constraint

        samples = count(samples, "samples", 2)
        if self.status == "failed" or len(self.q) < 2:
            raise InputError("plan: only a plan of at least two planned waypoints can be retimed")
        n = self.robot.dof
        v = self.robot.v_max if v_max is None else finite_array(v_max, "v_max", (n,))
        a = 4.0 * v if a_max is None else finite_array(a_max, "a_max", (n,))
        if np.any(v <= 0) or np.any(a <= 0):
            raise InputError("v_max, a_max: must be > 0")
        cuts = [0, *[k + 1 for k in self.reconfigurations], len(self.q)]
        t_all, q_all, qd_all, qdd_all, seg_all, start = [], [], [], [], [], 0.0
        for s, (a0, b0) in enumerate(itertools.pairwise(cuts)):
            way = self.q[a0:b0]
            if len(way) < 2:
                continue
            arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(way, axis=0), axis=1))])
            if arc[-1] <= 0:
                continue
            path = toppra.SplineInterpolator(arc / arc[-1], way)
            pc_v = constraint.JointVelocityConstraint(np.stack([-v, v], axis=1))
            pc_a = constraint.JointAccelerationConstraint(
                np.stack([-a, a], axis=1), discretization_scheme=constraint.DiscretizationType.Interpolation
            )
            traj = toppra.algorithm.TOPPRA([pc_v, pc_a], path, parametrizer="ParametrizeConstAccel").compute_trajectory(
                0, 0
            )
            if traj is None:
                raise InputError(f"plan: toppra found no timing of segment {s} under these limits")
            ts = np.linspace(0.0, traj.duration, samples)
            t_all.append(start + ts), q_all.append(traj(ts)), qd_all.append(traj(ts, 1)), qdd_all.append(traj(ts, 2))
            seg_all.append(np.full(samples, s))
            start += traj.duration
        if not t_all:
            raise InputError("plan: the arm does not move; nothing to retime")
        return Trajectory(np.concatenate(t_all), np.concatenate(q_all), np.concatenate(qd_all),
                          np.concatenate(qdd_all), start, np.concatenate(seg_all))  # fmt: skip


def measure(plan: Plan, mujoco: bool = True) -> None:
    """Fill in the plan's per-waypoint figures and its :class:`Check` list (see the module docstring); a plan
    that is not failed and whose check fails becomes ``"failed"`` (kind ``"check"``) at that check's first
    failing waypoint: its status follows from its checks, whatever made it."""
    robot, q = plan.robot, plan.q
    K = len(q)
    plan.facts = [str(f) for f in capsule_facts(robot, plan.obstacles)]
    if not K:
        plan.checks = []
        return
    T = plan.poses[:K]
    F = robot.fk(q)
    pos, rot = tracking_errors(F, T)
    plan.fk_error = (float(pos.max()), float(rot.max()))
    plan.margin = np.minimum(q - robot.q_min, robot.q_max - q).min(axis=1)
    plan.manipulability = np.asarray(robot.manipulability(q), float)
    obs = plan.obstacles
    if len(obs):
        plan.clearance = capsule_clearance(robot, q, obs)  # the pairs qpik.geometry.contacts checks
        plan.clearance_mujoco = _mujoco_clearance(robot, obs, q) if mujoco else np.zeros(0)
    else:
        plan.clearance = plan.clearance_mujoco = np.full(K, np.inf)
    pairs = () if plan.setup is None else plan.setup.scene.self_pairs
    plan.self_clearance = np.full(K, np.inf) if plan.setup is None else plan.setup.scene.self_clearance(q)
    steps = np.abs(np.diff(q, axis=0)) / plan.step_bound[: K - 1]
    keep = np.ones(K - 1, bool)
    keep[[k for k in plan.reconfigurations if k < K - 1]] = False
    plan.max_step_ratio = float(steps[keep].max(initial=0.0))
    over = (np.abs(np.diff(q, axis=0)) - plan.step_bound[: K - 1]).max(axis=1)
    over[~keep] = -np.inf
    worst_step = float(over.max(initial=-np.inf))
    outside = np.maximum(np.maximum(robot.q_min - q, q - robot.q_max), 0.0).max(axis=1)
    viol = float(outside.max())
    fk_bad = (pos > FK_TOL) | (rot > FK_TOL) | ~np.isfinite(pos) | ~np.isfinite(rot)
    checks = [
        Check("fk", not fk_bad.any(),
              f"FK reproduces every waypoint: max error {plan.fk_error[0]:.2e} m, {plan.fk_error[1]:.2e} rad"
              f" (≤ {FK_TOL:g})", _first(fk_bad)),
        Check("limits", viol == 0.0, f"joint limits: max violation {viol:.3g} rad", _first(outside > 0)),
        Check("step", worst_step <= STEP_TOL,
              f"largest joint step {plan.max_step_ratio:.4g} × its bound (continuous transitions)",
              _first(over > STEP_TOL)),
    ]  # fmt: skip
    if len(obs):
        c = float(plan.clearance.min())
        text = f"clearance (capsules): min {c * 1e3:.3f} mm vs d_s = {plan.d_safe * 1e3:g} mm"
        close = plan.clearance < plan.d_safe - 1e-12
        checks.append(Check("clearance", not close.any(), text, _first(close)))
        if mujoco:
            cm = float(plan.clearance_mujoco.min())
            text = f"clearance (MuJoCo mj_geomDistance on the arm's model): min {cm * 1e3:.3f} mm"
            close = plan.clearance_mujoco < plan.d_safe - CLEARANCE_TOL
            checks.append(Check("clearance_mujoco", not close.any(), text, _first(close)))
    if pairs:
        close = plan.self_clearance < plan.d_safe - 1e-12
        text = f"self-clearance (capsule pairs): min {float(plan.self_clearance.min()) * 1e3:.3f} mm"
        checks.append(Check("self_clearance", not close.any(), text, _first(close)))
    plan.checks = checks
    bad = next((c for c in checks if not c.ok), None)
    if bad is not None and plan.status != "failed":
        plan.status, plan.failure_kind, plan.failure_waypoint = "failed", "check", bad.waypoint
        plan.failure = f"check {bad.name!r} fails (first at waypoint {bad.waypoint}): {bad.text}"


def _first(bad: np.ndarray) -> int:
    """The first index where ``bad`` holds, or -1."""
    hit = np.flatnonzero(bad)
    return int(hit[0]) if len(hit) else -1


def _mujoco_clearance(robot: Robot, obstacles: ObstacleSet, q: np.ndarray) -> np.ndarray:
    """(K,) the smallest distance between the collision geoms of the arm's MuJoCo model and the obstacles, m."""
    from qpik.robots.mujoco_scene import build_scene

    scene = build_scene(robot, obstacles.shapes)
    checked = scene.checked  # the pairs qpik.geometry.contacts checks
    out = np.empty((len(scene.link_geoms), len(scene.obstacle_geoms)))
    res = np.empty(len(q))
    for k, qk in enumerate(q):
        scene.kin.update(qk)
        res[k] = np.where(checked, scene.clearances(out), np.inf).min(initial=np.inf)
    return res


def make_plan(setup: Setup, q: np.ndarray, status: str, **kw) -> Plan:
    """A :class:`Plan` of configurations q (K, n) on the waypoints of ``setup``, measured."""
    return Plan(setup.robot, setup.poses, setup.times, setup.progress, q, kw.pop("param", np.zeros(0)),
                kw.pop("branch", np.zeros(0, int)), kw.pop("param_name", ""), status, setup.tr.step,
                setup.d_safe, setup.obstacles, setup=setup, **kw)  # fmt: skip
