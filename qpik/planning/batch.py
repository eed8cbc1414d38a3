"""Many jobs at once: in this process, in local worker processes, or on a Dask cluster.

:func:`run_batch` maps a function over items (for ``qpik plan``: :class:`~qpik.problems.plan.PlanJob` s; for
:func:`qpik.planning.many.plan_many`: paths) and yields ``(index, result)`` as the jobs finish, with a progress bar
(tqdm, on stderr):

- ``workers`` 0 or 1: one after the other in this process;
- ``workers=N`` (default: the number of CPUs): N local processes (``concurrent.futures``, started with ``spawn`` so
  that no thread or GL state of this process is copied into them);
- ``scheduler``: a Dask cluster (a ``distributed.Client``, or its scheduler's address ``"tcp://host:8786"``; the
  ``[cluster]`` extra), whose workers need qpik installed and share no folder with this process.

The function, the items and the results must pickle (a function defined at module level). ``context`` (e.g. the
robot) is sent once per worker, not once per job: the function is called ``fn(context, item)`` (``fn(item)``
without one). A job that raises, or whose worker dies, gives a :class:`JobFailure` as its result; the batch goes on.
A local process that dies breaks its pool: its unfinished jobs run again, each alone in a new process, at
most :data:`ALLOWED_FAILURES` times, as Dask's scheduler reruns the jobs of a worker that dies (its
``allowed-failures``). ``retries`` is Dask's: a job that raises runs again that many times (for failures that may
pass, e.g. a node's disk or memory; qpik's own errors are deterministic, hence the default 0).
"""

from __future__ import annotations

import gc
import multiprocessing
import os
import sys
import uuid
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

from qpik.core.errors import InputError

CONNECT = "10s"
"""How long to wait for a Dask scheduler."""
ALLOWED_FAILURES = 3
"""Times a local job whose process died runs again (Dask's default ``distributed.scheduler.allowed-failures``)."""


@dataclass(frozen=True)
class JobFailure:
    """A job that raised or whose worker died.

    Attributes:
        index: its item's place in the batch. error: the exception's type and message, on one line.
    """

    index: int
    error: str

    @classmethod
    def of(cls, index: int, exc: BaseException) -> JobFailure:
        return cls(index, f"{type(exc).__name__}: {' '.join(str(exc).split())}")


def run_batch(
    fn: Callable[..., Any],
    items: Sequence[Any],
    *,
    context: Any = None,
    workers: int | None = None,
    scheduler: Any = None,
    retries: int = 0,
    progress: bool | None = None,
    label: str = "plans",
) -> Iterator[tuple[int, Any]]:
    """``(i, fn(items[i]))`` (or ``fn(context, items[i])``) for every item, in the order they finish; a
    :class:`JobFailure` for a job that fails (see the module docstring). ``progress``: a bar on stderr (default:
    when stderr is a terminal).

    Raises:
        InputError: ``workers`` < 0, ``retries`` not an integer ≥ 0, no Dask or no scheduler at that address.
    """
    items = list(items)
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise InputError(f"retries: expected an integer >= 0, got {retries!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise InputError(f"workers: expected an integer >= 0, got {workers!r}")
    args = () if context is None else (context,)
    if scheduler is not None:
        jobs = _dask(fn, args, items, scheduler, retries)
    else:
        count = (os.cpu_count() or 1) if workers is None else workers
        count = min(count, len(items))
        jobs = _here(fn, args, items) if count <= 1 else _processes(fn, args, items, count)
    bar = _bar(len(items), progress, label)
    try:
        for index, result in jobs:
            if bar is not None:
                bar.update(1)
            yield index, result
    finally:
        if bar is not None:
            bar.close()


def _call(fn: Callable[..., Any], args: tuple, index: int, item: Any) -> Any:
    try:
        return fn(*args, item)
    except Exception as exc:  # one failed job does not end the batch: its failure is its result
        return JobFailure.of(index, exc)


def _here(fn, args: tuple, items: list) -> Iterator[tuple[int, Any]]:
    for i, item in enumerate(items):
        yield i, _call(fn, args, i, item)


_CONTEXT: tuple = ()
"""A local worker process's context (set once by :func:`_install`)."""


def _install(args: tuple) -> None:
    global _CONTEXT
    _CONTEXT = args


def _local(fn, index: int, item: Any) -> Any:
    return _call(fn, _CONTEXT, index, item)


def _processes(fn, args: tuple, items: list, count: int) -> Iterator[tuple[int, Any]]:
    lost: list[int] = []
    yield from _pool(fn, args, items, range(len(items)), count, lost)
    for i in lost:  # each alone now, so that a job that kills its process takes no other job with it
        for attempt in range(ALLOWED_FAILURES):
            again: list[int] = []
            yield from _pool(fn, args, items, [i], 1, again, final=attempt == ALLOWED_FAILURES - 1)
            if not again:
                break


def _pool(fn, args: tuple, items: list, which, count: int, lost: list[int], final: bool = False):
    """The jobs ``which`` in a new pool of ``count`` processes; those whose process died go to ``lost`` (or, when
    ``final``, give their failure)."""
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(count, spawn, initializer=_install, initargs=(args,)) as pool:
        futures = {pool.submit(_local, fn, i, items[i]): i for i in which}
        for done in as_completed(futures):
            i = futures[done]
            try:
                yield i, done.result()
            except BrokenProcessPool as exc:  # its process died (killed, out of memory, a crash)
                if final:
                    yield i, JobFailure.of(i, exc)
                else:
                    lost.append(i)


def connect(scheduler: Any):
    """``(client, owned)``: ``scheduler`` itself if it is a ``distributed.Client``, else a new client of the scheduler
    at that address (``owned``: close it after use).

    Raises:
        InputError: no ``dask.distributed``, not an address, or no scheduler answers there within :data:`CONNECT`.
    """
    try:
        from dask.distributed import Client
    except ImportError:
        raise InputError("scheduler: a Dask cluster needs dask.distributed (pip install 'qpik[cluster]')") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    if not isinstance(scheduler, str):
        raise InputError(f"scheduler: expected a distributed.Client or an address, got {type(scheduler).__name__}")
    try:
        return Client(scheduler, timeout=CONNECT), True
    except (OSError, ValueError, TypeError) as exc:  # no scheduler there, or not an address
        reason = str(exc)
    # The half-made client is in reference cycles: collected later, inside another client's start, its finaliser
    # would wait for the lock that start holds (distributed's LoopRunner), a deadlock. Collected now, it closes.
    gc.collect()
    raise InputError(f"scheduler: cannot reach the Dask scheduler at {scheduler} ({reason})")


def _dask(fn, args: tuple, items: list, scheduler: Any, retries: int) -> Iterator[tuple[int, Any]]:
    from dask.distributed import as_completed as dask_completed

    client, owned = connect(scheduler)
    try:
        shared = client.scatter(list(args), broadcast=True, hash=False) if args else []  # once per worker
        batch = uuid.uuid4().hex
        futures = [
            client.submit(_call, fn, tuple(shared), i, item, pure=False, retries=retries, key=f"qpik-{batch}-{i}")
            for i, item in enumerate(items)
        ]
        where = {f.key: i for i, f in enumerate(futures)}
        for done in dask_completed(futures):
            i = where[done.key]
            try:
                result = done.result()
            except Exception as exc:  # the worker died (KilledWorker after its allowed failures), or the job raised
                result = JobFailure.of(i, exc)
            done.release()
            yield i, result
    finally:
        if owned:
            client.close()


def _bar(total: int, progress: bool | None, label: str):
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit="job", file=sys.stderr)
