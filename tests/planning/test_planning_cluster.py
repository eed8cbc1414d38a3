"""``qpik plan DIR --scheduler`` on a real Dask cluster (``dask scheduler``, two ``dask worker`` processes in their own
folders, seeing none of the client's): the client reads, the workers compute, the client writes. Every file comes
back to the client's output folder as a local run writes it, nothing is written in the workers' folders, and a job
that raises or a worker killed during the batch loses no other result."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
from dask_cluster import PACKAGE, dask_cluster, listing

from qpik.cli import main
from qpik.problems import find_problem
from qpik.robots.packaged import packaged_model

pytest.importorskip("dask.distributed")

# --dist loadgroup: one worker runs the whole module, so its module- and session-scoped fixtures are built once
pytestmark = pytest.mark.xdist_group("planning_cluster")

SMALL = find_problem("nammoto2012_joint_limits_plan").read_text().replace("num = 61", "num = 11")
Q = np.array([0.3, 0.5, 0.1, -1.2, 0.2, 0.8, 0.1])
MODEL = f"""name = "iiwa_model_plan"
kind = "plan"
[robot]
model = "iiwa/model.urdf"
[target]
q = {json.dumps((Q + np.linspace(0.0, 0.2, 6)[:, None]).tolist())}
[[obstacles]]
type = "sphere"
center = [0.5, -0.5, 0.3]
radius = 0.05
[solver]
resolution = 144
"""


def _named(name: str) -> str:
    return SMALL.replace('name = "nammoto2012_joint_limits_plan"', f'name = "{name}"')


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    with dask_cluster(tmp_path_factory.mktemp("cluster")) as c:
        yield c


@pytest.fixture
def client_folder(tmp_path, monkeypatch):
    """The client's working folder with ``files/``: two catalog arms, a loaded URDF with meshes (copied here only)."""
    files = tmp_path / "files"
    files.mkdir()
    (files / "small.toml").write_text(_named("small"))
    shutil.copy(find_problem("zheng7_plan"), files)
    urdf = packaged_model("pybullet/iiwa")
    (files / "iiwa").mkdir()
    shutil.copy(urdf, files / "iiwa" / "model.urdf")
    shutil.copytree(urdf.parent / "meshes", files / "iiwa" / "meshes")
    (files / "model.toml").write_text(MODEL)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _without_times(report: str) -> str:
    return re.sub(r"^Time \(the solves.*$", "", report, flags=re.M)


def test_a_folder_on_the_cluster_comes_back_as_a_local_run_writes_it(cluster, client_folder, capsys):
    before = [listing(f) for f in cluster.folders]
    assert main(["plan", "files", "-o", "local", "--workers", "0"]) == 0
    assert main(["plan", "files", "-o", "remote", "--scheduler", cluster.address]) == 0
    out = capsys.readouterr().out
    assert "3 file(s) planned, 0 FAIL" in out
    local, remote = client_folder / "local", client_folder / "remote"
    assert listing(local) == listing(remote)
    assert {p.name for p in remote.iterdir()} == {"small", "zheng7_plan", "iiwa_model_plan"}
    for folder in local.iterdir():
        name = folder.name
        a, b = (np.load(root / name / f"{name}_plan.npz")["q"] for root in (local, remote))
        assert a.shape == b.shape and np.abs(a - b).max() <= 1e-12
        ra, rb = ((root / name / "report.md").read_text() for root in (local, remote))
        assert _without_times(ra) == _without_times(rb) and "Overall: PASS" in rb
        for f in folder.iterdir():
            assert (remote / name / f.name).stat().st_size > 0
    assert "clearance" in (remote / "iiwa_model_plan" / "report.md").read_text()
    assert [listing(f) for f in cluster.folders] == before == [[], [], []]  # the workers wrote nothing there


def test_plan_many_on_the_cluster_equals_a_loop(cluster):
    import qpik

    robot = qpik.load_robot("iiwa14")
    rng = np.random.default_rng(1)
    paths = [robot.fk(robot.q_home + rng.uniform(-0.3, 0.3, 7) + np.linspace(0, 0.15, 5)[:, None]) for _ in range(12)]
    options = qpik.PlanOptions(resolution=72, mujoco=False)
    plans = qpik.plan_many(robot, paths, options, client=cluster.address, progress=False)
    for path, plan in zip(paths, plans, strict=True):
        alone = qpik.plan_self_motion(robot, path, options=options)
        assert plan.robot is robot and plan.status == alone.status and plan.cost == pytest.approx(alone.cost, 1e-12)
        assert np.abs(plan.q - alone.q).max() <= 1e-12


def test_a_raising_job_and_a_killed_worker_lose_no_other_result(cluster, client_folder):
    files = client_folder / "files"
    for k in range(4):
        (files / f"more{k}.toml").write_text(_named(f"more{k}"))
    (files / "raises.toml").write_text(_named("raises").replace("[solver]\n", "[solver]\nresolution = 9\n"))
    code = "import sys; from qpik.cli import main; sys.exit(main(sys.argv[1:]))"
    env = {**{k: v for k, v in os.environ.items() if k.startswith("QPIK_")}, "PYTHONPATH": str(PACKAGE)}
    argv = [sys.executable, "-c", code, "plan", "files", "-o", "out", "--scheduler", cluster.address]
    run = subprocess.Popen(argv, cwd=client_folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out = client_folder / "out"
    deadline = time.monotonic() + 600  # kill a worker once the first result is back: the others are still running
    while not (out.is_dir() and any(out.iterdir())) and run.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert out.is_dir() and any(out.iterdir()), f"no result within 600 s: {run.poll()=}"
    assert run.poll() is None and len(list(out.iterdir())) < 7  # the batch is still running
    cluster.kill_worker(0)
    stdout, stderr = run.communicate(timeout=600)
    assert run.returncode == 1, stderr
    assert "raises: error: InputError: resolution: expected an even integer in [8, " in stdout
    assert "files/raises.toml: InputError: resolution" in stderr and "1 file(s) not planned" in stderr
    names = {"small", "zheng7_plan", "iiwa_model_plan", *(f"more{k}" for k in range(4))}
    assert {p.name for p in out.iterdir()} == names
    for name in names:
        assert "Overall: PASS" in (out / name / "report.md").read_text()
