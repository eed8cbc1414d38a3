r"""``qpik.plan_self_motion``: the joint trajectory that follows an end-effector path exactly and uses the
redundancy as well as possible.

Closed-form arms (``nammoto7`` in δ, ``iiwa14`` in ψ, and loaded arms of those forms):

1. the exact feasible intervals of every branch at every waypoint (:func:`qpik.feasible_intervals`) and
   a grid of ``resolution`` parameter values on every branch, evaluated only inside them
   (:mod:`qpik.planning.grid`);
2. dynamic programming over the grid (:mod:`qpik.planning.dp`): the sequence of states with the least
   :math:`J = \sum \lVert \Delta q \rVert^2/\Delta + \sum w_k f(q_k)` whose transitions keep every
   joint step within its bound (L∞: ``max_joint_step``, and with ``times`` the velocity limits
   :math:`v_{max}\Delta t` and ``a_max``), with the fewest reconfigurations when ``reconfigure="fewest"``;
3. the sparse NLP over the parameter at every waypoint (:mod:`qpik.planning.refine`), started from the
   DP's plan; its answer is kept when it is better and passes every check.

Every configuration is the closed form at its waypoint, so the path is followed exactly.

Arms whose branches :func:`qpik.ik` finds per pose (the 1-D search: the Sawyer, Baxter; the general 6-R: the YuMi, TIAGo
Pro; no expressions of the parameter, no feasible sets): the same DP over the branches the search finds inside the
limits at every grid value of the locked joint (:class:`~qpik.planning.search_grid.SearchGrid`; ``"infeasible"`` is then
never proved), refined by the NLP over the joints.

Arms of no family (``zheng7``): the QP controller tracks the path
(:func:`qpik.planning.track.track`, also the online baseline), and the same NLP over the joints, with the pose as
an equality at every waypoint, refines its configurations at the waypoints.

Where the grid finds no continuous plan but no waypoint's exact feasible set is empty, the DP is run
again on grids :data:`REFINE` times finer in turn (near the shoulder and wrist singular positions the
branch maps turn fast, and a continuous motion may pass between two grid values) before the plan is
reported failed, of kind ``"grid"``; ``"infeasible"`` only when a waypoint's exact feasible set is empty.

Every plan is measured (:func:`qpik.planning.plan.measure`): FK, joint limits, clearance with the
capsules and with MuJoCo, joint steps; a plan whose check fails is ``"failed"`` (kind ``"check"``).

How it plans (joint-step bounds, grid, NLP, checks) is one :class:`~qpik.planning.options.PlanOptions`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from qpik.analytic import feasible_intervals
from qpik.core.errors import InputError, UnreachableError
from qpik.core.stopwatch import Stopwatch
from qpik.core.validate import finite_array, flag, number
from qpik.geometry.paths import TimedPath
from qpik.objectives import Objective
from qpik.planning import dp
from qpik.planning.grid import Grid
from qpik.planning.options import PlanOptions, default_resolution
from qpik.planning.plan import Plan, Profile, make_plan, measure
from qpik.planning.refine import PathNLP
from qpik.planning.search_grid import SearchGrid
from qpik.planning.setup import Setup
from qpik.planning.track import track
from qpik.robots.robot import Robot
from qpik.scene.scene import Scene, scene_of

RECONFIGURE = ("forbid", "fewest")
MAX_RESOLUTION = 16_384
"""The largest ``resolution``."""
MAX_STATES = 4_000_000
"""The most grid values per branch over the whole path, waypoints × resolution (memory)."""
REFINE = (4,)
"""Factors of ``resolution`` at which the DP runs again when the grid alone failed (capped by the limits above)."""
NEAR_MISS = 2.0
"""A reconfiguration whose closest grid states need at most this many joint-step bounds is tried on finer grids."""
IMPROVED = 1e-12
"""The NLP's answer replaces the DP's when its objective is lower by more than this (relative)."""


def plan_self_motion(
    robot: Robot | Scene,
    path: np.ndarray | TimedPath,
    objective: Objective | str | None = None,
    obstacles: Sequence | None = None,
    *,
    times: np.ndarray | None = None,
    d_safe: float | None = None,
    q_ref: np.ndarray | None = None,
    options: PlanOptions | None = None,
) -> Plan:
    r"""Plan the joint motion along an end-effector path (see the module docstring).

    Args:
        robot: the arm, or a :class:`~qpik.scene.Scene` of it (then ``objective``, ``obstacles``, ``d_safe`` and
            ``q_ref`` are the scene's).
        path: waypoints (N, 4, 4) (end-effector poses, base frame) or a timed path
            (:class:`qpik.geometry.paths.TimedPath`, sampled at ``times`` or at ``waypoints`` even times).
        objective: the point objective (:mod:`qpik.objectives`: an Objective or a name), integrated along
            the path; None: joint motion only.
        obstacles: shapes (world frame): every link capsule stays ≥ ``d_safe`` from each.
        times: (N,) strictly increasing times, s: the motion term becomes ∫‖q̇‖² dt, the joint steps are
            also bounded by the velocity limits (and ``options.a_max``).
        d_safe: m (≥ 0; default 0.02).
        q_ref: (n,) the reference of the ``"distance"`` objective, rad.
        options: joint-step bounds, reconfigurations, the DP's grid, the NLP and the checks
            (:class:`~qpik.planning.options.PlanOptions`; default its defaults).

    Returns:
        A :class:`~qpik.planning.plan.Plan` (``status == "failed"`` with the waypoint and the reason when
        the path cannot be planned; then ``q`` holds the planned prefix).

    Raises:
        InputError: bad arguments (naming them).
    """
    if objective is not None and not isinstance(objective, Objective | str):
        raise InputError(f"objective: expected None, an Objective or a name, got {type(objective).__name__}")
    options = PlanOptions() if options is None else options
    if not isinstance(options, PlanOptions):
        raise InputError(f"options: expected PlanOptions, got {type(options).__name__}")
    scene = scene_of(robot, obstacles, d_safe, objective, q_ref)
    setup = Setup(scene, path, times, options)
    reconfigure, resolution, window = options.reconfigure, options.resolution, options.window
    if not isinstance(reconfigure, str) or reconfigure not in RECONFIGURE:
        raise InputError(f"reconfigure: expected one of {RECONFIGURE}, got {reconfigure!r}")
    refine, mujoco = flag(options.refine, "refine"), flag(options.mujoco, "mujoco")
    if setup.robot.closed_form is None:
        return _plan_joints(setup, refine, mujoco)
    if resolution is None:
        resolution = default_resolution(setup.robot)
    res = int(number(resolution, "resolution", 8))
    if res % 2 or res != resolution or res > MAX_RESOLUTION:
        raise InputError(f"resolution: expected an even integer in [8, {MAX_RESOLUTION}], got {resolution!r}")
    if res * len(setup.poses) > MAX_STATES:
        raise InputError(f"resolution: {res} values × {len(setup.poses)} waypoints exceeds {MAX_STATES:g}; use fewer")
    w = 3.0 * float(setup.tr.step.max()) if window is None else number(window, "window")
    return _plan_closed_form(setup, res, w, options.branches, reconfigure == "fewest", refine, mujoco)


def _plan_closed_form(setup: Setup, resolution: int, window: float, branches, fewest: bool, refine: bool,
                      mujoco: bool) -> Plan:  # fmt: skip
    watch = Stopwatch()  # the DP's time: its functions are built with the clock paused
    if setup.robot.branch_functions:
        with watch.paused():
            feasible_intervals(setup.robot, setup.poses[0])  # the exact sets' functions, built on their first call
    grid = _grid(setup, resolution, branches)
    with watch.paused():
        dp.build(grid)
    result = dp.solve(grid, setup.tr, int(np.ceil(window / grid.spacing)), fewest)
    for factor in REFINE:  # only the grid failed: finer grids before giving up
        finer = resolution * factor
        too_big = finer > MAX_RESOLUTION or finer * len(setup.poses) > MAX_STATES
        if too_big or not _grid_failed(grid, setup.tr, result, fewest):
            break
        with watch.paused():
            fine = _grid(setup, finer, branches)
            dp.build(fine)
        again = dp.solve(fine, setup.tr, int(np.ceil(window / fine.spacing)), fewest)
        if _better(again, result):
            grid, result = fine, again
    t_dp = watch.stop()
    sym = grid.param_name
    if result.failure is not None:
        k = result.failure.waypoint
        continuous = np.ones(max(k - 1, 0), bool)
        continuous[[j for j in result.reconfigurations if j < k - 1]] = False
        cost = setup.cost(result.q[:k], continuous) if k else 0.0
        plan = make_plan(setup, result.q[:k], "failed", param_name=sym, failure=result.failure.reason,
                         failure_waypoint=k, failure_kind=result.failure.kind,
                         least_violating=_least_violating(setup, k), timings={"dp": t_dp}, cost=cost,
                         dp_cost=cost, reconfigurations=[j for j in result.reconfigurations if j < k - 1])  # fmt: skip
        plan.branch, plan.param = _public(grid, result.rows[:k], result.index[:k])
        plan.profile = _profile(grid, result)
        measure(plan, mujoco)
        return plan
    continuous = np.ones(len(setup.poses) - 1, bool)
    continuous[result.reconfigurations] = False
    branch, param = _public(grid, result.rows, result.index)
    plan = make_plan(setup, result.q, "dp", param=param, branch=branch, param_name=sym, cost=result.cost,
                     dp_cost=result.cost, reconfigurations=result.reconfigurations, timings={"dp": t_dp},
                     profile=_profile(grid, result), label="DP")  # fmt: skip
    measure(plan, mujoco)
    if not refine:
        return plan
    if grid.intervals is None:  # no expressions of the parameter: the NLP over the joints, from the DP's plan
        return _refine_joints(setup, plan, result, continuous, mujoco)
    nlp = PathNLP(setup.scene, setup.poses, setup.tr, continuous, grid, result.rows)
    out = nlp.solve(grid.values[result.index])
    plan.timings["nlp"] = out.time
    if _lower(out.cost, result.cost):
        branch, param = grid.public(result.rows, out.param)
        better = _refined(setup, plan, result, out.q, out.cost, "NLP", mujoco, param=param, branch=branch,
                          timings=plan.timings)  # fmt: skip
        if better.ok:
            return better
    return plan


def _refine_joints(setup: Setup, plan: Plan, result: dp.DPResult, continuous: np.ndarray, mujoco: bool) -> Plan:
    """The DP's ``plan`` of an arm of the 1-D search refined by the NLP over the joints (the pose an equality at
    every waypoint), kept when better and passing every check; without reconfigurations, the same NLP from the QP
    controller's run (:func:`_plan_joints`) is a second start, kept instead where its plan passes every check at a
    lower J (the DP's grid of the locked joint is coarse: 64 values by default)."""
    nlp = PathNLP(setup.scene, setup.poses, setup.tr, continuous)
    out = nlp.solve(result.q)
    plan.timings["nlp"] = out.time
    best = plan
    if _lower(out.cost, result.cost):
        better = _refined(setup, plan, result, out.q, out.cost, "NLP", mujoco, **_slots(setup, out.q),
                          timings=plan.timings)  # fmt: skip
        best = better if better.ok else plan
    if result.reconfigurations:
        return best
    other = _plan_joints(setup, True, mujoco)
    if not other.ok or not _lower(other.cost, best.cost):
        return best
    timings = {**plan.timings, **{f"second start: {k}": v for k, v in other.timings.items()}}
    second = _refined(setup, plan, result, other.q, other.cost, "NLP from the QP controller's run", mujoco,
                      **_slots(setup, other.q), timings=timings)  # fmt: skip
    return second if second.ok else best


def _lower(cost: float, than: float) -> bool:
    """Whether ``cost`` is below ``than`` by more than :data:`IMPROVED` (relative)."""
    return cost < than - IMPROVED * max(1.0, abs(than))


def _refined(setup: Setup, dp_plan: Plan, result: dp.DPResult, q: np.ndarray, cost: float, label: str, mujoco: bool,
             **kw) -> Plan:  # fmt: skip
    """A refinement of the DP's plan ``dp_plan`` (of ``result``): the ``"optimal"`` plan of configurations q (K, n)
    at the objective ``cost``, measured; ``kw``: its ``param``, ``branch`` and ``timings``."""
    out = make_plan(setup, q, "optimal", param_name=dp_plan.param_name, cost=cost, dp_cost=result.cost,
                    reconfigurations=result.reconfigurations, profile=dp_plan.profile, label=label, dp_plan=dp_plan,
                    **kw)  # fmt: skip
    measure(out, mujoco)
    return out


def _slots(setup: Setup, q: np.ndarray) -> dict[str, np.ndarray]:
    """``param``, the locked joint (rad), and ``branch``, the slot, of configurations q (N, n) of an arm of the 1-D
    search (:func:`qpik.redundancy_parameter`: one search per configuration)."""
    from qpik.analytic import redundancy_parameter

    param, branch = redundancy_parameter(setup.robot, q)
    return {"param": param, "branch": branch}


def _grid(setup: Setup, resolution: int, branches) -> Grid:
    """The DP's grid of ``resolution`` values per branch, restricted to ``branches`` (public ids, or None): a
    :class:`~qpik.planning.search_grid.SearchGrid` for an arm whose branches the 1-D search finds."""
    kind = Grid if setup.robot.branch_functions else SearchGrid
    grid = kind(setup.scene, setup.poses, resolution)
    if branches is not None:
        ids = [int(b) for b in np.atleast_1d(finite_array(branches, "branches"))]
        known = list(grid.solver.branch_ids)
        bad = [b for b in ids if b not in known]
        if bad:
            raise InputError(f"branches: unknown branch id(s) {bad}; the branches are {known}")
        keep = np.zeros(grid.rows, bool)
        keep[[known.index(b) % grid.rows for b in ids]] = True
        grid.inside &= keep[None, :, None]
    return grid


def _grid_failed(grid: Grid, tr: dp.Transitions, result: dp.DPResult, fewest: bool) -> bool:
    """Whether a finer grid may do better: a transition the grid alone failed (no proof), or with ``fewest`` a
    reconfiguration, between two waypoints whose closest feasible states are within :data:`NEAR_MISS` times the
    joint-step bound (a finer grid may make it a continuous transition; far apart, none can)."""
    if result.failure is not None:
        k = result.failure.waypoint
        return result.failure.kind == "grid" and k > 0 and _closest_ratio(grid, tr, k - 1) <= NEAR_MISS
    return fewest and any(_closest_ratio(grid, tr, k) <= NEAR_MISS for k in result.reconfigurations)


def _closest_ratio(grid: Grid, tr: dp.Transitions, k: int) -> float:
    """min over feasible state pairs of waypoints k and k + 1 of max_j |Δq_j| / bound_j (k-d tree, L∞); inf when
    above :data:`NEAR_MISS`."""
    from scipy.spatial import cKDTree

    layers = grid.layers(k, k + 2)
    n = layers.q.shape[-1]
    a, b = (layers.q[i][layers.ok[i]].reshape(-1, n) / tr.step[k] for i in (0, 1))
    if not len(a) or not len(b):
        return np.inf
    return float(cKDTree(b).query(a, k=1, p=np.inf, distance_upper_bound=NEAR_MISS * (1 + 1e-9))[0].min())


def _better(new: dp.DPResult, old: dp.DPResult) -> bool:
    """Later failure, then fewer reconfigurations."""
    a, b = (len(r.rows) if r.failure is None else r.failure.waypoint for r in (new, old))
    if a != b:
        return a > b
    return len(new.reconfigurations) < len(old.reconfigurations)


def _public(grid: Grid, rows: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return grid.public(rows, grid.values[index])


def _profile(grid: Grid, result: dp.DPResult) -> Profile:
    live = result.index >= 0
    return Profile(grid.values, result.ok, grid.branch_of(np.arange(grid.rows)),
                   grid.values[result.index[live]], result.rows[live])  # fmt: skip


def _least_violating(setup: Setup, k: int) -> str:
    """What :func:`qpik.solve_best` says about waypoint k: unreachable, or the least-violating branch, each proved, or
    that it found no feasible point without a proof that none exists (nothing for an arm of the 1-D search, whose
    branches are not expressions of the locked joint)."""
    if not setup.robot.branch_functions:
        return ""
    from qpik.nlp import solve_best

    return solve_best(setup.scene.replace(objective="margin"), setup.poses[k]).summary()


def _plan_joints(setup: Setup, refine: bool, mujoco: bool) -> Plan:
    """An arm without a closed form: the QP controller's tracking run, refined by the NLP over the joints."""
    from qpik.nlp import solve_ik

    try:
        q0 = solve_ik(setup.robot, setup.poses[0], setup.robot.q_home)
    except UnreachableError as exc:  # no proof without a closed form: the plan fails its FK check at waypoint 0
        plan = make_plan(
            setup,
            np.zeros((0, setup.robot.dof)),
            "failed",
            failure=f"check 'fk' fails at waypoint 0: {exc}",
            failure_waypoint=0,
            failure_kind="check",
            label="QP controller (online)",
        )
        measure(plan, mujoco)
        return plan
    watch = Stopwatch()
    q_track = track(setup, q0, watch)
    timings = {"tracking": watch.stop()}
    continuous = np.ones(len(setup.poses) - 1, bool)
    plan = make_plan(
        setup,
        q_track,
        "tracking",
        cost=setup.cost(q_track, continuous),
        timings=timings,
        label="QP controller (online)",
    )
    measure(plan, mujoco)
    if not refine:
        return plan
    nlp = PathNLP(setup.scene, setup.poses, setup.tr, continuous)
    out = nlp.solve(q_track)
    timings["nlp"] = out.time
    refined = make_plan(setup, out.q, "optimal", cost=out.cost, timings=timings, label="NLP", dp_plan=plan)
    measure(refined, mujoco)
    return refined if refined.ok or not plan.ok else plan
