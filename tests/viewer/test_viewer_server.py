"""qpik.viewer.server without a browser: a drag event, playback of a simulation log, live mode, the port check, a
websocket client (qpik.viewer.listener).

The scene is read from viser's server-side handles and checked against MuJoCo's kinematics of the model
and qpik's forward kinematics; quaternions of the drag events are made by scipy.
"""

from __future__ import annotations

import socket
import time
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from conftest import random_q
from scipy.spatial.transform import Rotation

pytest.importorskip("viser", reason="viser is not installed (pip install 'qpik[view]')")

import qpik
from qpik.sim import SimOptions, simulate
from qpik.viewer import ViewerError
from qpik.viewer.server import Viewer, port_free


def _arm_at(viewer: Viewer, q: np.ndarray) -> None:
    """The solid arm's body frames are where MuJoCo puts the bodies at q."""
    model = viewer.robot.mj_model()
    data = mujoco.MjData(model)
    for name, value in zip(viewer.robot.joint_names, q):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_kinematics(model, data)
    for body in viewer.geometry.bodies:
        handle = viewer.server.scene.get_handle_by_name(f"/arm/b{body.body}")
        np.testing.assert_allclose(handle.position, data.xpos[body.body], atol=1e-9)


@pytest.fixture(scope="module")
def iiwa():
    with Viewer(qpik.load_robot("iiwa14"), options=qpik.ViewOptions(port=0)) as viewer:
        viewer.wait()
        yield viewer


def test_drag_event_moves_the_target_and_the_answers(iiwa):
    robot = iiwa.robot
    pose = robot.fk(random_q(robot, 1, 4)[0])
    x, y, z, w = Rotation.from_matrix(pose[:3, :3]).as_quat()
    before = iiwa.updates
    iiwa._on_drag(SimpleNamespace(phase="update", target=SimpleNamespace(position=pose[:3, 3], wxyz=(w, x, y, z))))
    assert iiwa.updates == before + 1 and len(iiwa.latencies) >= 1 and len(iiwa.cpu_times) == len(iiwa.latencies)
    assert 0.0 < iiwa.cpu_times[-1] <= iiwa.latencies[-1]  # the drawing thread's CPU time within the span
    np.testing.assert_allclose(iiwa.pose, pose, atol=1e-12)
    assert not iiwa.state.certify  # during a drag: the certificate follows at its end
    np.testing.assert_allclose(robot.fk(iiwa.state.q), pose, atol=1e-9)
    _arm_at(iiwa, iiwa.state.q)
    iiwa._on_drag(SimpleNamespace(phase="end", target=SimpleNamespace(position=pose[:3, 3], wxyz=(w, x, y, z))))
    assert iiwa.state.certify and iiwa.state.best.certified


def test_slider_puts_the_ghosts_at_the_parameter(iiwa):
    iiwa.set_param(-2.0)
    sol = iiwa.state.branches
    assert sol.param == pytest.approx(-2.0)
    psi, _ = qpik.redundancy_parameter(iiwa.robot, sol.q[sol.valid])
    np.testing.assert_allclose(psi, -2.0, atol=1e-9)


def test_live_mode_drives_the_arm_to_the_target(iiwa):
    robot = iiwa.robot
    target = robot.fk(robot.q_home)
    target[:3, 3] += (0.05, -0.05, 0.05)
    iiwa.set_target(target, certify=False)
    iiwa.live = True
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            q = iiwa._override
            if q is not None and np.linalg.norm(robot.fk(q)[:3, 3] - target[:3, 3]) < 1e-4:
                break
            time.sleep(0.1)
        q = iiwa._override.copy()
    finally:
        iiwa.live = False
    assert np.linalg.norm(robot.fk(q)[:3, 3] - target[:3, 3]) < 1e-4
    assert robot.within_limits(q)
    assert iiwa._override is None  # off again: the solid arm is the best answer


def test_playback_of_a_simulation_log_shows_its_configurations():
    robot = qpik.load_robot("iiwa14")
    target = robot.fk(robot.q_home)
    target[:3, 3] += (0.0, 0.1, 0.0)
    log = simulate(
        robot,
        qpik.Controller.for_robot(robot, target=target, dt=0.01),
        robot.q_home,
        0.3,
        dt=0.01,
        target=target,
        options=SimOptions(progress=False),
    )
    with Viewer(robot, play=log, options=qpik.ViewOptions(port=0)) as viewer:
        for k in (0, len(log) // 2, len(log) - 1):
            viewer.seek(k)
            _arm_at(viewer, log.q[k])
            np.testing.assert_allclose(viewer.server.scene.get_handle_by_name("/target").position, target[:3, 3],
                                       atol=1e-12)  # fmt: skip


def test_a_taken_port_is_named():
    with socket.socket() as other:
        other.bind(("127.0.0.1", 0))
        other.listen()
        port = other.getsockname()[1]
        assert not port_free("127.0.0.1", port)
        with pytest.raises(ViewerError, match=f"port {port} is taken"):
            Viewer(qpik.load_robot("panda"), options=qpik.ViewOptions(port=port))


def test_panel_shows_the_margin_as_itself(iiwa):
    """The maximised margin is shown as the margin (≥ 0 for an answer inside the limits), not as the −margin that
    solve_best minimises; checked against the joint limits directly."""
    best = iiwa.state.best
    assert best.status == "optimal"
    robot, q = iiwa.robot, best.q
    half = 0.5 * (robot.q_max - robot.q_min)
    margin = float(np.min(np.minimum(q - robot.q_min, robot.q_max - q) / half))
    text = iiwa.page.best_md.content
    assert f"margin {margin:.6g}" in text and "maximised" in text, text
    assert margin > 0 and "-" not in text.split("margin", 1)[1].split("(", 1)[0]


def test_the_panel_names_the_locked_joint_the_solver_takes():
    """The Jaco file is of the locked-joint family read from the flange: its slider is q1, the solver's parameter
    (checked against the solver's own name, and that q1 of the configuration is what redundancy_parameter gives)."""
    import contextlib
    import io

    import viser
    from conftest import model_robot

    from qpik.analytic.api import closed_form_for
    from qpik.geometry.distance import ObstacleSet
    from qpik.viewer.page import Page

    robot = model_robot("robosuite_jaco")
    assert closed_form_for(robot).param_name == "q1"
    q = random_q(robot, 1, 3)[0]
    q1 = qpik.redundancy_parameter(robot, q)[0]  # wrapped: the Jaco's joint 1 turns past ±π
    assert abs((q1 - q[0] + np.pi) % (2 * np.pi) - np.pi) < 1e-9
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(port=0, verbose=False)
    try:
        page = Page(server, robot, ObstacleSet(()), 0.02, robot.fk(robot.q_home), None, "margin")
        assert page.symbol == "q1" and page.slider.label == "q1 [rad]"
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def test_websocket_client_receives_the_scene_and_every_update(iiwa):
    """A Listener (viser's websocket from another process) is counted by the server as a client and receives the
    page's scene, counted from the arm's model: a mesh per part of the solid arm, of the gold best answer and per
    capsule, a batched mesh per ghost part, one target control; then, for a drag update, before its mark, a new
    orientation of every moving body of the solid arm and the ghosts' new poses. Closed, it is no client."""
    from collections import Counter

    from qpik.viewer.listener import Listener

    robot, bodies = iiwa.robot, iiwa.geometry.bodies
    parts = sum(len(body.parts) for body in bodies)
    before = len(iiwa.server.get_clients())
    with Listener(iiwa) as client:
        assert len(iiwa.server.get_clients()) == before + 1
        client.sync()
        scene = Counter()
        for frame in client.frames:
            scene.update(frame.types)
        assert scene["MeshMessage"] == 2 * parts + len(robot.capsules)
        assert scene["BatchedMeshesMessage"] == parts
        assert scene["TransformControlsMessage"] == 1
        seen = len(client.frames)
        received = time.perf_counter()
        iiwa.receive(robot.fk(random_q(robot, 1, 5)[0]), received)
        assert client.sync() > received
        update = Counter()
        for frame in client.frames[seen:]:
            update.update(frame.types)
        assert update["SetOrientationMessage"] >= sum(body.moving for body in bodies)
        assert update["SceneNodeUpdateMessage"] >= parts  # per ghost part, its instances' poses
        assert client.frames[-1].mark == 2
    deadline = time.monotonic() + 10.0  # the server drops the client once its process has ended
    while len(iiwa.server.get_clients()) > before and time.monotonic() < deadline:
        time.sleep(0.05)
    assert len(iiwa.server.get_clients()) == before


def test_the_slider_moves_a_searched_arm_along_its_self_motion():
    """robosuite's Sawyer (qpik.ik by the 1-D search, q1): the slider is q1 and the page has a ghost per slot (16);
    moving the slider puts the solid arm, drawn where MuJoCo puts its bodies, on the branch inside the limits
    nearest the last configuration at the new q1, reaching the target by MuJoCo's FK of the file, and its panel says
    which branch; the ghosts are qpik.ik's branches there."""
    from conftest import model_robot, mujoco_poses

    robot = model_robot("robosuite_sawyer")
    q = random_q(robot, 1, 9)[0]
    T = mujoco_poses(robot, q[None])[0]
    with Viewer(robot, T, options=qpik.ViewOptions(port=0)) as viewer:
        assert viewer.page.slider.label == "q1 [rad]" and len(viewer.page.branch_ids) == 16
        last = viewer.state.q
        for value in (q[0], q[0] + 0.05, q[0] + 0.1):
            viewer.set_param(value)
            st = viewer.state
            assert st.slot is not None and abs(st.q[0] - value) < 1e-9
            sols = qpik.ik(robot, T, value)
            np.testing.assert_array_equal(st.branches.q, sols.q)
            inside = np.flatnonzero(sols.within_limits)
            apart = [np.abs((sols.q[k] - last + np.pi) % (2 * np.pi) - np.pi).max() for k in inside]
            assert st.slot == inside[int(np.argmin(apart))]
            np.testing.assert_allclose(mujoco_poses(robot, st.q[None])[0], T, atol=1e-9)
            _arm_at(viewer, st.q)
            assert f"branch **{int(sols.branch[st.slot])}**" in viewer.page.best_md.content
            last = st.q
