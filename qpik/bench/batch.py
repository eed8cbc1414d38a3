"""Bench: :func:`qpik.plan_many` on 200 short iiwa14 paths, in this process, in 2 and 4 local processes, and on a
Dask ``LocalCluster`` of 1, 2 and 4 worker processes (one thread each).

Each path is 6 waypoints, 0.15 rad of joint motion from a seeded random start near home, planned with 72 ψ values
per branch, the NLP and the capsule checks, without MuJoCo's check. A row's time is the batch's wall time divided
by the paths (seconds per plan; the note gives plans per second): with local processes it includes starting them
(``spawn``: each imports qpik and builds the robot's functions once), as every :func:`qpik.plan_many` call does; the
Dask cluster is started before the clock and each batch is its first on that cluster (each worker builds the
robot's functions once). Compiled code comes from the disk cache (one warm-up plan here first). With ``--repeat``
below 1,000: 20 paths, and 2 processes at most (a quick look).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from qpik.bench import Row
from qpik.planning.many import plan_many
from qpik.planning.options import PlanOptions
from qpik.planning.planner import plan_self_motion
from qpik.robots.loader import load_robot

TITLE = "Batches: qpik.plan_many, 200 iiwa14 paths of 6 waypoints (plans per second in the notes)"
PATHS = 200
OPTIONS = PlanOptions(resolution=72, mujoco=False)


def paths(count: int = PATHS) -> list[np.ndarray]:
    """The bench's paths: ``count`` of (6, 4, 4) waypoints, base frame, m."""
    robot = load_robot("iiwa14")
    rng = np.random.default_rng(0)
    steps = np.linspace(0.0, 0.15, 6)[:, None]
    return [robot.fk(robot.q_home + rng.uniform(-0.3, 0.3, robot.dof) + steps) for _ in range(count)]


def _row(label: str, seconds: float, count: int, ref: str | None, plans: list) -> Row:
    ok = sum(p.ok for p in plans)
    return Row(label, seconds / count, ref=ref, note=f"{count / seconds:.1f} plans/s; {ok}/{count} plans pass")


def run(args: argparse.Namespace) -> list[Row]:
    full = int(getattr(args, "repeat", 2000)) >= 1000
    count = PATHS if full else PATHS // 10
    sizes = (1, 2, 4) if full else (1, 2)
    robot, todo = load_robot("iiwa14"), paths(count)
    plan_self_motion(robot, todo[0], options=OPTIONS)  # compiles and caches
    here = "in this process"
    rows = []
    start = time.perf_counter()
    plans = plan_many(robot, todo, workers=1, progress=False, options=OPTIONS)
    rows.append(_row(here, time.perf_counter() - start, count, None, plans))
    for n in sizes[1:]:
        start = time.perf_counter()
        plans = plan_many(robot, todo, workers=n, progress=False, options=OPTIONS)
        rows.append(_row(f"{n} local processes", time.perf_counter() - start, count, here, plans))
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:  # the [cluster] extra
        return rows
    for n in sizes:
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        with cluster, Client(cluster) as client:
            start = time.perf_counter()
            plans = plan_many(robot, todo, client=client, progress=False, options=OPTIONS)
            rows.append(_row(f"Dask LocalCluster, {n} worker(s)", time.perf_counter() - start, count, here, plans))
    return rows
