"""Many planning jobs at once: in this process, in local worker processes, or on a Dask cluster.

:func:`run_batch` maps a function over items (for ``qpik plan``: problem files) and yields
``(item, result)`` as the jobs finish, with a progress bar (tqdm):

- ``workers=0``: one after the other in this process;
- ``workers=N`` (default: the number of CPUs): N local processes (``concurrent.futures``, started
  with ``spawn`` so that no thread or GL state of this process is copied into them);
- ``scheduler="tcp://host:8786"``: the same calls on a running Dask cluster
  (``dask.distributed.Client(scheduler)``, the ``[cluster]`` extra), whose workers need qpik installed.

The function and the items must pickle (a function defined at module level). Results are the
function's own; a job that raises gives its exception as the result (the batch goes on).
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

from qpik.errors import InputError

CONNECT = "10s"
"""How long to wait for a Dask scheduler."""


def run_batch(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | None = None,
    label: str = "plans",
) -> Iterator[tuple[Any, Any]]:
    """``(item, fn(item))`` for every item, in the order they finish (see the module docstring)."""
    items = list(items)
    if scheduler is not None:
        jobs = _dask(fn, items, scheduler)
    elif workers == 0:
        jobs = ((item, _call(fn, item)) for item in items)
    else:
        count = (os.cpu_count() or 1) if workers is None else int(workers)
        if count < 1:
            raise InputError(f"workers: must be >= 0, got {workers}")
        jobs = _processes(fn, items, min(count, max(len(items), 1)))
    bar = _bar(len(items), progress, label)
    for item, result in jobs:
        if bar is not None:
            bar.update(1)
        yield item, result
    if bar is not None:
        bar.close()


def _call(fn: Callable[[Any], Any], item: Any) -> Any:
    try:
        return fn(item)
    except Exception as exc:  # one failed job does not end the batch: its error is its result
        return exc


def _processes(fn, items, count: int):
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=count, mp_context=context) as pool:
        futures = {pool.submit(_call, fn, item): item for item in items}
        for done in as_completed(futures):
            yield futures[done], done.result()


def _dask(fn, items, scheduler: str):
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError:
        raise InputError("scheduler: a Dask cluster needs dask.distributed (pip install 'qpik[cluster]')") from None
    try:
        client = Client(scheduler, timeout=CONNECT)
    except (OSError, ValueError) as exc:  # no scheduler there, or not an address
        raise InputError(f"scheduler: cannot reach the Dask scheduler at {scheduler} ({exc})") from None
    try:
        futures = client.map(_call, [fn] * len(items), items, pure=False)
        where = {f.key: item for f, item in zip(futures, items)}
        for done in dask_completed(futures):
            yield where[done.key], done.result()
    finally:
        client.close()


def _bar(total: int, progress: bool | None, label: str):
    import sys

    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit="job")
