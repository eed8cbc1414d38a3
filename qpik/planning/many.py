"""Many paths of one arm planned at once: :func:`plan_many`, in this process, in local processes or on a Dask cluster.

The client sends the workers data only: the robot as a :class:`~qpik.robots.bundle.RobotBundle` (once per worker:
a scattered Dask future, or a local process's initialiser), the objective, the obstacles, the options and each
path's waypoints. A worker keeps the robot per process (by the bundle's content hash), so that its CasADi functions,
compiled code and closed-form solver are built once per worker process, not once per path. Each plan comes back
without its robot (:func:`detach`) and gets the caller's robot object again (:func:`attach`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from qpik.core.errors import InputError, QpikError
from qpik.core.validate import flag, number
from qpik.planning.batch import JobFailure, run_batch
from qpik.planning.options import PlanOptions
from qpik.planning.plan import Plan
from qpik.planning.planner import plan_self_motion
from qpik.robots.bundle import RobotBundle
from qpik.robots.robot import Robot
from qpik.scene.scene import Scene

if TYPE_CHECKING:
    from distributed import Client


class PlanningError(QpikError):
    """Some paths of :func:`plan_many` could not be planned (their jobs raised or their workers died).

    Attributes:
        failures: the :class:`~qpik.planning.batch.JobFailure` of each, ``index`` the path's place in ``paths``.
    """

    def __init__(self, failures: Sequence[JobFailure]):
        self.failures = list(failures)
        lines = "; ".join(f"path {f.index}: {f.error}" for f in self.failures[:5])
        more = f"; and {len(self.failures) - 5} more" if len(self.failures) > 5 else ""
        super().__init__(f"{len(self.failures)} path(s) could not be planned: {lines}{more}")


def detach(plan: Plan) -> Plan:
    """``plan`` (and its DP plan and setup) without the robot: what a worker sends back (modified in place)."""
    plan.robot = None  # type: ignore[assignment]
    if plan.setup is not None:
        plan.setup.robot = None
    if plan.dp_plan is not None:
        detach(plan.dp_plan)
    return plan


def attach(plan: Plan, robot: Robot) -> Plan:
    """``plan`` (and its DP plan and setup) with ``robot`` again (modified in place)."""
    plan.robot = robot
    if plan.setup is not None:
        plan.setup.robot = robot
    if plan.dp_plan is not None:
        attach(plan.dp_plan, robot)
    return plan


def plan_many(
    robot: Robot | Scene,
    paths: Sequence[Any],
    options: PlanOptions | None = None,
    *,
    client: Client | str | None = None,
    workers: int | None = None,
    errors: str = "raise",
    retries: int = 0,
    progress: bool = True,
) -> list[Plan | JobFailure]:
    """:func:`qpik.plan_self_motion` of ``robot`` along every path of ``paths``: one :class:`~qpik.planning.plan.Plan`
    per path, in their order (the same plans as a loop, computed in parallel).

    Args:
        robot: the arm (a catalog arm, a loaded model: its files are read here and sent to the workers, or a chain),
            or a :class:`~qpik.scene.Scene` of it: the objective, obstacles, d_safe, q_ref and capsule pairs kept apart
            of every path.
        paths: waypoints (N, 4, 4) each (end-effector poses, base frame, m), or timed paths
            (:class:`qpik.geometry.paths.TimedPath`, sampled here at ``options.waypoints`` even times).
        options: :func:`qpik.plan_self_motion`'s (:class:`~qpik.planning.options.PlanOptions`), the same for every
            path.
        client: None (this machine), a ``distributed.Client``, or a Dask scheduler's address (``"tcp://host:8786"``).
        workers: without a client, local processes (default: one per CPU; 1: in this process).
        errors: ``"raise"``: :class:`PlanningError` listing every path that could not be planned (after the others
            ran); ``"keep"``: its :class:`~qpik.planning.batch.JobFailure` (``index``, ``error``) in its place.
        retries: Dask's: a job that raises runs again this many times (a worker that dies is handled by Dask).
        progress: a progress bar on stderr.

    Raises:
        InputError: bad arguments (naming them). PlanningError: see ``errors``.
    """
    scene = robot if isinstance(robot, Scene) else Scene.of(robot)
    robot = scene.robot
    options = PlanOptions() if options is None else options
    if not isinstance(options, PlanOptions):
        raise InputError(f"options: expected PlanOptions, got {type(options).__name__}")
    if not isinstance(errors, str) or errors not in ("raise", "keep"):
        raise InputError(f"errors: expected 'raise' or 'keep', got {errors!r}")
    progress = flag(progress, "progress")
    if isinstance(paths, np.ndarray) and paths.ndim == 3:
        raise InputError("paths: expected a sequence of paths, got one path (N, 4, 4); use [path]")
    try:
        paths = list(paths)
    except TypeError:
        raise InputError(f"paths: expected a sequence of paths, got {type(paths).__name__}") from None
    items = [_sampled(p, options.waypoints, f"paths[{i}]") for i, p in enumerate(paths)]
    pieces = {"objective": scene.objective, "obstacles": scene.obstacles.shapes, "d_safe": scene.d_safe,
              "q_ref": scene.q_ref, "self_collision": scene.self_pairs}  # fmt: skip
    context = (RobotBundle.of(robot), pieces, options)
    if client is None and workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                                   or workers < 1):  # fmt: skip
        raise InputError(f"workers: expected an integer >= 1, got {workers!r}")
    out: list[Plan | JobFailure | None] = [None] * len(items)
    local = 0 if workers == 1 else workers
    for i, result in run_batch(_plan_one, items, context=context, workers=local, scheduler=client, retries=retries,
                               progress=progress, label="paths"):  # fmt: skip
        out[i] = result if isinstance(result, JobFailure) else attach(result, robot)
    failures = [r for r in out if isinstance(r, JobFailure)]
    if failures and errors == "raise":
        raise PlanningError(failures)
    return out  # type: ignore[return-value]


def _sampled(path: Any, count: Any, name: str) -> tuple[Any, np.ndarray | None]:
    """``(waypoints, times)`` of one path: a timed path is sampled here at ``count`` even times (its functions need
    not pickle); waypoints have no times."""
    if isinstance(path, np.ndarray | list | tuple):
        return np.asarray(path, float) if isinstance(path, list | tuple) else path, None
    if not hasattr(path, "pose") or not hasattr(path, "duration"):
        raise InputError(f"{name}: expected (N, 4, 4) waypoints or a timed path, got {type(path).__name__}")
    duration = number(path.duration, f"{name}.duration")
    times = np.linspace(0.0, duration, int(number(count, "waypoints", 2)))
    return np.asarray(path.pose(times), float), times


def _plan_one(context: tuple, item: tuple) -> Plan:
    bundle, pieces, options = context
    poses, times = item
    return detach(plan_self_motion(Scene.of(bundle.robot(), **pieces), poses, times=times, options=options))
