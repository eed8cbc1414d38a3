"""qpik view in a real headless browser: the page, the scene it holds, a moved target, a screenshot.

One viewer (iiwa14 with the ball and table of ``iiwa_obstacle_reach``) and one page in Debian's Chromium
(through Playwright) serve the whole module. The scene is read on the server (viser's handles) and
checked against MuJoCo's own kinematics of the model; the page is checked by its console, its DOM (the
feasible-set chart) and its pixels. Skips with one line where viser, Playwright or a browser is missing.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest

pytest.importorskip("viser", reason="viser is not installed (pip install 'qpik[view]')")
pytest.importorskip("playwright", reason="playwright is not installed (pip install 'qpik[view]')")

import qpik
from qpik.cli import main
from qpik.problems import find_problem, load
from qpik.viewer import ViewerError
from qpik.viewer.browser import browser, lower_priority, open_page, settle
from qpik.viewer.server import Viewer

# --dist loadgroup: one worker runs the whole module, so its module- and session-scoped fixtures are built once
pytestmark = pytest.mark.xdist_group("viewer_browser")

SIZE = (640, 400)


@pytest.fixture(scope="module")
def chromium():
    try:
        with browser() as b:
            yield b
    except ViewerError as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope="module")
def scene(chromium):
    problem = load(find_problem("iiwa_obstacle_reach"))
    viewer = Viewer(
        problem.robot, target=problem.poses[0], obstacles=problem.obstacles, options=qpik.ViewOptions(port=0)
    )
    viewer.wait()
    messages: list = []
    page = open_page(chromium, viewer, SIZE, messages)
    yield viewer, page, messages
    page.close()
    viewer.close()


def _body_poses(robot: qpik.Robot, q: np.ndarray) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """MuJoCo's kinematics of the robot's model at q, in a MjData of its own."""
    model = robot.mj_model()
    data = mujoco.MjData(model)
    for name, value in zip(robot.joint_names, q):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_kinematics(model, data)
    return model, data


def _check_arm(viewer: Viewer, root: str, q: np.ndarray) -> None:
    """Every body frame under ``root`` is where MuJoCo puts that body at q."""
    _, data = _body_poses(viewer.robot, q)
    for body in viewer.geometry.bodies:
        handle = viewer.server.scene.get_handle_by_name(f"{root}/b{body.body}")
        np.testing.assert_allclose(handle.position, data.xpos[body.body], atol=1e-9)
        w = data.xquat[body.body]
        assert np.allclose(handle.wxyz, w, atol=1e-9) or np.allclose(handle.wxyz, -w, atol=1e-9)


def _ghost_shown(viewer: Viewer, k: int) -> bool:
    """Whether branch k's ghost is drawn: its instance of every ghost mesh at scale 1 (hidden: 0)."""
    scales = {float(handle.batched_scales[k]) for _, handle in viewer.page.ghosts}
    assert len(scales) == 1 and scales <= {0.0, 1.0}, scales
    return scales == {1.0}


def _check_ghost(viewer: Viewer, k: int, q: np.ndarray) -> None:
    """Branch k's instance of every ghost mesh is where MuJoCo puts its body at q (to float32, as viser sends it)."""
    _, data = _body_poses(viewer.robot, q)
    for j, handle in viewer.page.ghosts:
        body = viewer.geometry.bodies[j].body
        np.testing.assert_allclose(handle.batched_positions[k], data.xpos[body], atol=1e-6)
        w, got = data.xquat[body], handle.batched_wxyzs[k]
        assert np.allclose(got, w, atol=1e-6) or np.allclose(got, -w, atol=1e-6)


def test_page_loads_without_console_errors(scene):
    _, page, messages = scene
    settle(page)
    errors = [m for m in messages if m[0] in ("error", "pageerror")]
    assert not errors, errors
    assert any("Connected" in text for _, text in messages)


def test_scene_holds_the_arm_the_ghosts_the_target_and_the_obstacles(scene):
    viewer, _, _ = scene
    get = viewer.server.scene.get_handle_by_name
    robot, state = viewer.robot, viewer.state
    _check_arm(viewer, "/arm", state.best.q)
    assert get("/target") is not None
    assert all(get(f"/obstacles/o{o}") is not None for o in range(len(viewer.obstacles)))
    assert all(get(f"/capsules/c{c}") is not None for c in range(len(robot.capsules)))
    ids = state.branches.branch.tolist()
    assert len(ids) == 8 and ids == viewer.page.branch_ids  # instance k of the ghost meshes: branch ids[k]
    for k in range(len(ids)):  # a ghost per branch that reaches the pose, except the solid arm's own
        same = np.abs(state.branches.q[k] - state.q).max() <= 1e-9
        assert _ghost_shown(viewer, k) == bool(state.branches.valid[k] and not same)
        if _ghost_shown(viewer, k):
            _check_ghost(viewer, k, state.branches.q[k])


def test_page_draws_the_feasible_sets(scene):
    """The chart in the page has one green bar per feasible interval of every branch."""
    viewer, page, _ = scene
    settle(page)
    count = sum(len(sets) for sets in viewer.state.intervals.intervals)
    assert count > 0
    assert page.locator("rect.feasible").count() == count


def test_moving_the_target_changes_the_branches(scene):
    viewer, page, _ = scene
    before = settle(page)
    old = viewer.state.branches.q.copy()
    pose = viewer.pose
    pose[:3, 3] += (-0.10, 0.05, 0.08)
    state = viewer.set_target(pose)
    assert not np.allclose(state.branches.q, old)
    valid = state.branches.valid
    assert valid.any()
    reached = viewer.robot.fk(state.branches.q[valid])
    np.testing.assert_allclose(reached, np.broadcast_to(pose, reached.shape), atol=1e-9)
    for k in range(len(state.branches.branch)):
        if _ghost_shown(viewer, k):
            _check_ghost(viewer, k, state.branches.q[k])
    after = settle(page)
    changed = np.any(np.abs(after.astype(int) - before.astype(int)) > 24, axis=2).mean()
    assert changed > 0.002, f"only {changed:.4%} of the page changed"


def test_cli_writes_a_screenshot_that_is_not_blank(chromium, tmp_path, capsys):
    out = tmp_path / "view.png"
    argv = ["view", "--problem", "iiwa_obstacle_reach", "--port", "0", "--screenshot", str(out), "--size", "640,400"]
    assert main(argv) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    from PIL import Image

    picture = np.asarray(Image.open(out).convert("RGB"))
    assert picture.shape == (SIZE[1], SIZE[0], 3)
    assert out.stat().st_size > 10_000
    assert picture.std() > 20
    assert len(np.unique(picture.reshape(-1, 3) // 16, axis=0)) > 50  # shaded meshes, not a flat page


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="lower_priority reads /proc (Linux)")
def test_lower_priority_lowers_the_processes_started_here_and_not_this_one():
    own = os.getpriority(os.PRIO_PROCESS, 0)
    # a child with a second thread that starts a grandchild: both are this process's descendants
    child = subprocess.Popen([sys.executable, "-c", "import subprocess, sys, threading, time; "
                              "threading.Thread(target=time.sleep, args=(30,), daemon=True).start(); "
                              "subprocess.run([sys.executable, '-c', 'import time; time.sleep(30)'])"])  # fmt: skip
    grandchildren: list[int] = []
    try:
        for _ in range(200):  # until the grandchild runs
            stat = [p for p in Path("/proc").iterdir() if p.name.isdigit()]
            grandchildren = [int(p.name) for p in stat if _parent(p) == child.pid]
            if grandchildren:
                break
            time.sleep(0.05)
        assert grandchildren, "the grandchild did not start"
        assert lower_priority(15) >= 2
        threads = [int(t.name) for pid in (child.pid, *grandchildren) for t in Path(f"/proc/{pid}/task").iterdir()]
        assert len(threads) >= 3  # the child's two threads, the grandchild's
        for tid in threads:
            assert os.getpriority(os.PRIO_PROCESS, tid) == max(15, own)
        assert os.getpriority(os.PRIO_PROCESS, 0) == own
    finally:
        for pid in grandchildren:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        child.kill()
        child.wait()


def _parent(entry: Path) -> int | None:
    try:
        return int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return None
