"""A real Dask cluster for the tests, started as a user would: ``dask scheduler`` and two ``dask worker`` processes.

Each process runs in a temporary working folder of its own, with an environment that sees qpik's package
folder only (``PYTHONPATH``), never the client's working folder.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import qpik

PACKAGE = Path(qpik.__file__).resolve().parents[1]
DASK = [sys.executable, "-m", "distributed.cli.dask_scheduler"], [sys.executable, "-m", "distributed.cli.dask_worker"]


@dataclass
class Cluster:
    address: str
    folders: list[Path]  # the scheduler's and the workers' working folders
    workers: list[subprocess.Popen]

    def kill_worker(self, k: int) -> None:
        os.kill(self.workers[k].pid, signal.SIGKILL)
        self.workers[k].wait()


def _env() -> dict[str, str]:
    keep = (
        "PATH",
        "HOME",
        "QPIK_CACHE",
        "QPIK_NATIVE",
        "QPIK_OPTIMISE",
        "MUJOCO_GL",
        "PYOPENGL_PLATFORM",
        "LANG",
        "TMPDIR",
    )
    env = {k: os.environ[k] for k in keep if k in os.environ}
    env["PYTHONPATH"] = str(PACKAGE)
    env["DASK_DISTRIBUTED__WORKER__DAEMON"] = "False"
    return env


@contextmanager
def dask_cluster(root: Path, workers: int = 2):
    """A scheduler and ``workers`` workers (one thread each, no nanny: killing one kills its process)."""
    folders = [root / "scheduler", *(root / f"worker{k}" for k in range(workers))]
    for f in folders:
        f.mkdir(parents=True)
    info = root / "scheduler.json"  # beside the folders, not in them
    procs = []
    try:
        procs.append(
            subprocess.Popen(
                [*DASK[0], "--scheduler-file", str(info), "--port", "0", "--no-dashboard"],
                cwd=folders[0],
                env=_env(),
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
        for k in range(workers):
            procs.append(subprocess.Popen([*DASK[1], "--scheduler-file", str(info), "--nthreads", "1", "--no-nanny",
                                           "--no-dashboard", "--name", f"w{k}"], cwd=folders[k + 1], env=_env(),
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))  # fmt: skip
        for _ in range(600):
            if info.is_file() and info.read_text().strip():
                break
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        from dask.distributed import Client

        with Client(address, timeout="60s") as client:
            client.wait_for_workers(workers, timeout=120)
        yield Cluster(address, folders, procs[1:])
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()


def listing(folder: Path) -> list[str]:
    """Every file and folder under ``folder``, relative."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))
