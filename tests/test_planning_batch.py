"""Batches of planning problems (qpik.planning.batch): a Dask LocalCluster gives the same plans as one process."""

from __future__ import annotations

import numpy as np
import pytest

from qpik.planning.batch import run_batch
from qpik.problems import find_problem
from qpik.problems.plan import plan_file

FILES = ("nammoto2012_joint_limits_plan", "nammoto2012_obstacle_plan", "zheng7_plan")


def _boom(x):
    raise ValueError(f"job {x} fails")


def test_a_dask_local_cluster_gives_the_same_plans_as_one_process():
    distributed = pytest.importorskip("dask.distributed")
    jobs = [(str(find_problem(name)), None) for name in FILES]
    here = {job[0]: result for job, result in run_batch(plan_file, jobs, workers=0)}
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        there = {job[0]: result for job, result in run_batch(plan_file, jobs, scheduler=cluster.scheduler_address)}
    assert set(here) == set(there) == {job[0] for job in jobs}
    for key, a in here.items():
        b = there[key]
        assert not isinstance(b, Exception), b
        assert a["ok"] and b["ok"] and a["summary"] == b["summary"]
        assert np.array_equal(a["q"], b["q"]) and a["cost"] == b["cost"]


def test_a_failing_job_is_its_result_and_the_batch_goes_on():
    out = dict(run_batch(_boom, [1, 2], workers=0))
    assert set(out) == {1, 2} and all(isinstance(e, ValueError) for e in out.values())
    assert str(out[2]) == "job 2 fails"
