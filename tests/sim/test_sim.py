"""qpik.sim: closed-loop runs in MuJoCo, their logs and plots.

The log's clearances come from MuJoCo (``mj_geomDistance``) and are checked
against qpik.geometry's closed forms; poses against the DH forward kinematics;
integration against the exact answer of a constant velocity.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEEDS
from hypothesis import given, settings
from PIL import Image

import qpik
from qpik.algebra.lie import so3_log
from qpik.core.errors import InputError
from qpik.geometry import Box, Capsule, HalfSpace, Sphere, distances
from qpik.plots.runs import plot_comparison, plot_log
from qpik.sim import SimOptions, build_scene, simulate

IIWA = qpik.load_robot("iiwa14")
SCENE = (
    Sphere((0.5, 0.0, 0.6), 0.1, name="ball"),
    Box((0.6, 0.1, 0.2), (0.2, 0.3, 0.1), rotation=[[0.8, -0.6, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]]),
    HalfSpace((0.0, 0.3, 1.0), 0.05, name="slope"),
    Capsule((0.3, -0.4, 0.3), (0.3, 0.4, 0.8), 0.05),
)


def constant(v: np.ndarray):
    return lambda t, q: v


@settings(max_examples=6, deadline=None)
@given(seed=SEEDS)
def test_clearance_agrees_with_closed_form(seed):
    """MuJoCo's distances in the log equal qpik.geometry.distances at the logged q (both exact).

    They agree everywhere except on the depth of a capsule sunk into a box: there
    MuJoCo reports its contact depth and qpik.geometry the signed distance of the
    deepest axis point (neither is the translational penetration depth); both
    still report an overlap.
    """
    rng = np.random.default_rng(seed)
    q0 = rng.uniform(IIWA.q_min, IIWA.q_max) * 0.5
    v = rng.uniform(-0.6, 0.6, 7)
    log = simulate(IIWA, constant(v), q0, 2.0, 0.002, obstacles=SCENE, options=SimOptions(record_every=25))
    segs = IIWA.capsule_segments(log.q)  # (K, C, 2, 3)
    closed = np.stack([distances(s, IIWA.capsule_radii, SCENE).d for s in segs])
    assert log.clearance.shape == closed.shape == (len(log), 7, 4)
    exact = (closed >= 0.0) | np.array([not isinstance(o, Box) for o in SCENE])
    np.testing.assert_allclose(log.clearance[exact], closed[exact], atol=1e-6)
    assert np.all(log.clearance[~exact] < 0.0)
    assert log.link_names == tuple(f"link{k}_capsule" for k in range(1, 8))
    assert log.obstacle_names == ("ball", "obstacle1", "slope", "obstacle3")


def test_constant_velocity_integrates_exactly():
    v = np.array([0.1, -0.2, 0.3, 0.1, 0.0, 0.2, -0.1])
    T, dt = 1.3, 0.001
    log = simulate(IIWA, constant(v), IIWA.q_home, T, dt, options=SimOptions(record_every=7))
    np.testing.assert_allclose(log.q[-1], IIWA.q_home + v * T, rtol=0, atol=1e-12)
    assert log.t[0] == 0.0 and log.t[-1] == pytest.approx(T)
    assert len(log) == 1 + -(-1300 // 7)  # every 7th step and the last one
    np.testing.assert_allclose(log.q, IIWA.q_home + np.outer(log.t, v), atol=1e-12)
    np.testing.assert_array_equal(log.v, np.broadcast_to(v, log.v.shape))


def test_logged_pose_and_manipulability_match_dh():
    """The MuJoCo site pose equals the DH forward kinematics; manipulability the DH one."""
    rng = np.random.default_rng(3)
    v = rng.uniform(-0.5, 0.5, 7)
    log = simulate(IIWA, constant(v), IIWA.q_home, 1.0, 0.01)
    np.testing.assert_allclose(log.ee, IIWA.fk(log.q), atol=1e-12)
    np.testing.assert_allclose(log.manipulability, IIWA.manipulability(log.q), rtol=1e-9)


def test_any_mjcf_arm_with_joint_names():
    """The scene of an MJCF string with joint names and site runs the same as the twin."""
    v = np.array([0.2, 0.1, -0.1, 0.3, 0.2, -0.2, 0.1])
    scene = build_scene(IIWA.to_mjcf(), SCENE[:1], joint_names=[f"joint{k}" for k in range(1, 8)], site="ee")
    log = simulate(scene, constant(v), IIWA.q_home, 0.5, 0.01)
    twin = simulate(IIWA, constant(v), IIWA.q_home, 0.5, 0.01, obstacles=SCENE[:1])
    np.testing.assert_allclose(log.ee, twin.ee, atol=1e-12)
    np.testing.assert_allclose(log.clearance, twin.clearance, atol=1e-12)
    assert log.v_max is None and np.isnan(log.summary().max_velocity_ratio)


def test_tracking_error_of_a_path():
    """Errors against a moving target: position by the DH fk, orientation by the SO(3) log."""

    class Line:
        duration = 1.0

        def pose(self, t):
            T = IIWA.fk(IIWA.q_home)
            T[:3, 3] += (0.1 * t, 0.0, 0.0)
            return T

        def twist(self, t):
            return np.array([0.1, 0, 0, 0, 0, 0])

    v = np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.3, 0.0])
    log = simulate(IIWA, constant(v), IIWA.q_home, 1.0, 0.01, target=Line())
    e_pos, e_rot = log.errors
    T = IIWA.fk(log.q)
    goal = np.array([Line().pose(t) for t in log.t])
    np.testing.assert_allclose(e_pos, np.linalg.norm(goal[:, :3, 3] - T[:, :3, 3], axis=1), atol=1e-12)
    angles = [np.linalg.norm(so3_log(g[:3, :3] @ x[:3, :3].T)) for g, x in zip(goal, T)]
    np.testing.assert_allclose(e_rot, angles, atol=1e-9)
    s = log.summary(transient=0.5)
    assert s.max_pos_error == pytest.approx(e_pos[log.t >= 0.5].max())
    assert s.final_rot_error == pytest.approx(angles[-1])


def test_summary_limits_and_velocity():
    """A joint driven past its limit: the violation and the velocity ratio are reported."""
    v = np.zeros(7)
    v[3] = -1.0  # joint 4 from -1.2 toward its limit -120° = -2.094 rad
    log = simulate(IIWA, constant(v), IIWA.q_home, 1.2, 0.01)
    s = log.summary()
    expected = max(0.0, IIWA.q_min[3] - (IIWA.q_home[3] - 1.2))
    assert s.max_limit_violation == pytest.approx(expected, abs=1e-9)
    assert s.min_limit_margin == pytest.approx(-expected, abs=1e-9)
    assert s.max_velocity_ratio == pytest.approx(1.0 / IIWA.v_max[3])
    assert s.min_clearance.size == 0 and "clearance" not in str(s)


def test_bad_inputs():
    with pytest.raises(InputError, match="policy"):
        simulate(IIWA, lambda t, q: np.zeros(6), IIWA.q_home, 0.1, 0.01)
    with pytest.raises(InputError, match="q0"):
        simulate(IIWA, constant(np.zeros(7)), np.zeros(6), 0.1, 0.01)
    with pytest.raises(InputError, match="dt"):
        simulate(IIWA, constant(np.zeros(7)), IIWA.q_home, 0.1, 0.0)
    with pytest.raises(InputError, match="record_every"):
        simulate(IIWA, constant(np.zeros(7)), IIWA.q_home, 0.1, 0.01, options=SimOptions(record_every=0))


def test_scene_reuse():
    scene = build_scene(IIWA, SCENE)
    a = simulate(scene, constant(np.full(7, 0.1)), IIWA.q_home, 0.2, 0.01)
    b = simulate(scene, constant(np.full(7, 0.1)), IIWA.q_home, 0.2, 0.01)
    np.testing.assert_array_equal(a.clearance, b.clearance)


def _non_blank(path) -> bool:
    img = np.asarray(Image.open(path).convert("L"), dtype=float)
    return img.std() > 5.0


def test_plots_are_written(tmp_path):
    v = np.array([0.1, -0.2, 0.3, 0.1, 0.0, 0.2, -0.1])
    target = IIWA.fk(IIWA.q_home)
    a = simulate(
        IIWA,
        constant(v),
        IIWA.q_home,
        1.0,
        0.01,
        obstacles=SCENE,
        target=target,
        options=SimOptions(d_safe=0.03, label="a"),
    )
    b = simulate(IIWA, constant(-v), IIWA.q_home, 1.0, 0.01, target=target, options=SimOptions(label="b"))
    for path in (plot_log(a, tmp_path / "a.png"), plot_log(b, tmp_path / "b.png"),
                 plot_comparison([a, b], tmp_path / "ab.png", title="a vs b")):  # fmt: skip
        assert path.is_file() and _non_blank(path)


def test_render_strip(tmp_path):
    """Snapshots of a run with its obstacles, or a clean skip where no OpenGL context can be made."""
    from qpik.plots.runs import render_strip

    v = np.array([0.3, -0.2, 0.3, 0.4, 0.0, 0.2, -0.1])
    log = simulate(IIWA, constant(v), IIWA.q_home, 1.0, 0.02, obstacles=SCENE[:2], target=IIWA.fk(IIWA.q_home))
    path = render_strip(log, tmp_path / "strip.png", frames=4, size=(96, 80))
    if path is None:
        pytest.skip("offscreen rendering unavailable")
    img = Image.open(path)
    assert img.size == (3 * 96, 2 * 80)  # 4 snapshots in up to 3 columns
    assert _non_blank(path)


def test_bad_arms_and_obstacles_are_input_errors(tmp_path):
    """obstacles=[1] used to fail in dataclasses.replace with a TypeError; a robot's name was read as a file."""
    policy = constant(np.zeros(7))
    with pytest.raises(InputError, match=r"obstacles\[1\]"):
        simulate(IIWA, policy, IIWA.q_home, 0.01, 0.01, obstacles=[SCENE[0], 1])
    with pytest.raises(InputError, match="obstacles"):
        simulate(IIWA, policy, IIWA.q_home, 0.01, 0.01, obstacles=5)
    with pytest.raises(InputError, match=r"load_robot\('iiwa14'\)"):
        simulate("iiwa14", policy, IIWA.q_home, 0.01, 0.01)
    with pytest.raises(InputError, match=r"^arm"):
        simulate(None, policy, IIWA.q_home, 0.01, 0.01)
    with pytest.raises(InputError, match="rejected by MuJoCo"):
        simulate("<mujoco><worldbody><geom/></mujoco>", policy, IIWA.q_home, 0.01, 0.01)
    bad = tmp_path / "arm.xml"
    bad.write_text("not xml")
    with pytest.raises(InputError, match="rejected by MuJoCo"):
        simulate(bad, policy, IIWA.q_home, 0.01, 0.01)
