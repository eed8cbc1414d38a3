"""Batches of jobs (qpik.planning.batch): every job gives its result or its failure, in this process and in local
processes, also when a process dies; the context reaches every job."""

from __future__ import annotations

import gc
import os
from pathlib import Path

import pytest

from qpik.core.errors import InputError
from qpik.planning.batch import ALLOWED_FAILURES, JobFailure, run_batch


def _square(x):
    if x == 3:
        raise ValueError(f"job {x}\nfails")
    return x * x


def _scaled(context, x):
    return context["scale"] * x


def _dies_once(marker_and_x):
    """Ends its process (as a kill would) the first time it runs for x = 2, then gives x."""
    marker, x = marker_and_x
    if x == 2 and not Path(marker).exists():
        Path(marker).write_text("died")
        os._exit(1)
    return x


def _always_dies(x):
    if x == 0:
        os._exit(1)
    return x


def test_a_failing_job_is_its_failure_and_the_batch_goes_on():
    out = dict(run_batch(_square, [1, 2, 3, 4], workers=0))
    assert out[0] == 1 and out[1] == 4 and out[3] == 16
    assert out[2] == JobFailure(2, "ValueError: job 3 fails")


def test_local_processes_give_the_same_results_and_the_context():
    assert dict(run_batch(_square, [1, 2, 3, 4], workers=2)) == dict(run_batch(_square, [1, 2, 3, 4], workers=0))
    assert dict(run_batch(_scaled, [1, 2], context={"scale": 3.0}, workers=2)) == {0: 3.0, 1: 6.0}


def test_a_process_that_dies_loses_no_other_result(tmp_path):
    items = [(str(tmp_path / "marker"), x) for x in range(4)]
    assert dict(run_batch(_dies_once, items, workers=2)) == {0: 0, 1: 1, 2: 2, 3: 3}
    assert (tmp_path / "marker").read_text() == "died"


def test_a_job_that_kills_its_process_every_time_fails_after_the_allowed_failures():
    out = dict(run_batch(_always_dies, [0, 1, 2], workers=2))
    assert out[1] == 1 and out[2] == 2
    assert isinstance(out[0], JobFailure) and "BrokenProcessPool" in out[0].error
    assert ALLOWED_FAILURES == 3


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"workers": -1}, "workers: expected an integer >= 0"),
        ({"workers": 1.5}, "workers: expected an integer >= 0"),
        ({"retries": -1}, "retries: expected an integer >= 0"),
        ({"scheduler": 3}, "scheduler: expected a distributed.Client or an address"),
        ({"scheduler": "no-such-address"}, "scheduler: cannot reach the Dask scheduler"),
    ],
)
def test_bad_arguments_are_named(kwargs, message):
    with pytest.raises(InputError, match=message):
        list(run_batch(_square, [1], **kwargs))


def test_an_unreachable_scheduler_leaves_no_half_made_client_to_the_garbage_collector():
    """A client that could not connect is closed before the error is raised: left to the garbage collector, its
    finaliser would run at some later allocation, possibly inside another client's start, and wait there for the lock
    that start holds (a deadlock seen in this suite). With automatic collection off, no unclosed client is left."""
    from dask.distributed import Client

    gc.collect()
    gc.disable()
    try:
        with pytest.raises(InputError, match="scheduler: cannot reach the Dask scheduler"):
            list(run_batch(_square, [1], scheduler="no-such-address"))
        left = [o for o in gc.get_objects() if isinstance(o, Client) and o.status not in ("closed", "newly-created")]
    finally:
        gc.enable()
    assert not left
