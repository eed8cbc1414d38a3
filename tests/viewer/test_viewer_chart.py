"""qpik.viewer.chart, state and playback: the drawn feasible sets against dense sampling of the closed form; the
answers of one pose against forward kinematics; the plan files the viewer plays."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from conftest import SEEDS, model_robot, random_q
from hypothesis import given, settings

import qpik
from qpik.core.errors import InputError
from qpik.geometry import Sphere
from qpik.viewer.chart import feasible_chart
from qpik.viewer.playback import as_track
from qpik.viewer.state import solve_view

SVG = "{http://www.w3.org/2000/svg}"


def _drawn_sets(svg: str) -> tuple[list[int], list[list[tuple[float, float]]], float]:
    """From the picture alone: the branch ids of the rows, each row's green bars converted back to parameter
    values through the positions of the −π and π tick labels, and the cursor's value."""
    root = ET.fromstring(svg)
    texts = [(t.text, float(t.get("x")), float(t.get("y"))) for t in root.iter(f"{SVG}text")]
    x_lo = next(x for s, x, _ in texts if s == "−π")
    x_hi = next(x for s, x, _ in texts if s == "π")
    value = lambda x: -math.pi + (x - x_lo) / (x_hi - x_lo) * 2 * math.pi  # noqa: E731
    rows = [(int(s[1:]), y) for s, _, y in texts if s.startswith("b")]
    bars: list[list[tuple[float, float]]] = [[] for _ in rows]
    for rect in root.iter(f"{SVG}rect"):
        if rect.get("class") != "feasible":
            continue
        y = float(rect.get("y"))
        r = min(range(len(rows)), key=lambda i: abs(rows[i][1] - (y + 7)))
        x, w = float(rect.get("x")), float(rect.get("width"))
        bars[r].append((value(x), value(x + w)))
    cursor = next(line for line in root.iter(f"{SVG}line") if line.get("class") == "cursor")
    return [b for b, _ in rows], bars, value(float(cursor.get("x1")))


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7"])
@settings(max_examples=4, deadline=None)
@given(seed=SEEDS)
def test_drawn_feasible_sets_match_the_closed_form_on_a_dense_grid(name, seed):
    """A ψ/δ lies under a green bar of a branch's row iff qpik.ik puts that branch inside the limits there (720
    values; values within one pixel of a bar's end are not judged)."""
    robot = qpik.load_robot(name)
    pose = robot.fk(random_q(robot, 1, seed)[0])
    svg = feasible_chart(qpik.feasible_intervals(robot, pose), 0.5)
    branches, bars, cursor = _drawn_sets(svg)
    assert cursor == pytest.approx(0.5, abs=0.02)
    grid = np.linspace(-math.pi, math.pi, 720, endpoint=False) + 1e-4
    inside = qpik.ik(robot, np.repeat(pose[None], len(grid), 0), grid).within_limits  # (720, B)
    sol_ids = qpik.ik(robot, pose, 0.0).branch.tolist()
    pixel = 2 * math.pi / 250
    for r, b in enumerate(branches):
        col = inside[:, sol_ids.index(b)]
        drawn = np.array([any(lo <= v <= hi for lo, hi in bars[r]) for v in grid])
        near_end = np.array([any(min(abs(v - lo), abs(v - hi)) < pixel for lo, hi in bars[r]) for v in grid])
        near_end |= np.r_[False, col[1:] != col[:-1]] | np.r_[col[1:] != col[:-1], False]
        assert np.array_equal(drawn[~near_end], col[~near_end]), f"branch {b}"


def test_view_state_of_a_pose_reaches_it():
    """Every valid branch and the solid configuration reach the pose by the DH forward kinematics, the best answer
    is its own closed form's, and the clearances are those of qpik.geometry at the solid configuration."""
    robot = qpik.load_robot("iiwa14")
    pose = robot.fk(robot.q_home)
    ball = Sphere((0.45, 0.25, 0.6), 0.08)
    from qpik.geometry import ObstacleSet, distances

    st = solve_view(robot, pose, 0.7, obstacles=ObstacleSet([ball]), certify=False)
    assert st.branches.valid.any()
    valid = st.branches.q[st.branches.valid]
    np.testing.assert_allclose(robot.fk(valid), np.broadcast_to(pose, (len(valid), 4, 4)), atol=1e-9)
    np.testing.assert_allclose(robot.fk(st.q), pose, atol=1e-9)
    assert st.best.status == "optimal" and np.allclose(st.q, st.best.q)
    want = distances(robot.capsule_segments(st.q), robot.capsule_radii, [ball]).d
    np.testing.assert_allclose(st.clearance.d, want, atol=1e-12)


def test_view_state_of_an_arm_without_closed_form_is_the_numerical_ik():
    robot = qpik.load_robot("zheng7")  # the offset wrist of Zheng et al. 2019: no family of qpik.ik
    assert robot.closed_form is None
    q = random_q(robot, 1, 5)[0]
    st = solve_view(robot, robot.fk(q), 0.0, q_seed=q + 0.05)
    assert st.branches is None and st.intervals is None and st.best is None and st.slot is None
    assert st.numerical.status == "ok"
    np.testing.assert_allclose(robot.fk(st.q), robot.fk(q), atol=1e-8)


@pytest.mark.parametrize("key", ["robosuite_sawyer", "xarm7_offset", "erd_tiago_pro"])
def test_view_state_of_a_searched_arm_is_the_branch_nearest_the_last_configuration(key):
    """An arm whose branches are found per pose (the 1-D search: robosuite's Sawyer, q1; the xArm7 with axis 3 moved 1
    mm, q7; the general 6-R: example-robot-data's TIAGo Pro arm, q7): the ghosts are qpik.ik's branches at the
    parameter, each valid one reaching the pose by MuJoCo's FK of the file; the solid configuration is, among those
    inside the limits, the one nearest the seed (brute force over the slots), here the configuration the pose came from;
    no feasible sets, no best answer."""
    from conftest import mujoco_poses

    robot = model_robot(key)
    j = 0 if key == "robosuite_sawyer" else 6
    for q in random_q(robot, 3, 8):
        T = mujoco_poses(robot, q[None])[0]
        st = solve_view(robot, T, q[j], q_seed=q + 0.02)
        assert st.intervals is None and st.best is None and st.numerical is None
        sols = qpik.ik(robot, T, q[j])
        np.testing.assert_array_equal(st.branches.q, sols.q)
        valid = sols.q[sols.valid]
        np.testing.assert_allclose(mujoco_poses(robot, valid), np.broadcast_to(T, (len(valid), 4, 4)), atol=1e-9)
        inside = np.flatnonzero(sols.within_limits)
        apart = [np.abs((sols.q[k] - q - 0.02 + np.pi) % (2 * np.pi) - np.pi).max() for k in inside]
        assert st.slot == inside[int(np.argmin(apart))]
        np.testing.assert_allclose((st.q - q + np.pi) % (2 * np.pi) - np.pi, 0.0, atol=1e-9)


def test_plan_file_is_played_as_written(tmp_path):
    robot = qpik.load_robot("iiwa14")
    q = random_q(robot, 6, 2)
    path = tmp_path / "x_plan.npz"
    np.savez(path, q=q, poses=robot.fk(q), times=np.linspace(0, 1, 6), param=np.zeros(6), branch=np.arange(6))
    track = as_track(path, robot)
    np.testing.assert_array_equal(track.q, q)
    np.testing.assert_array_equal(track.t, np.linspace(0, 1, 6))
    np.testing.assert_array_equal(track.branch, np.arange(6))


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "expected the .npz plan file"),
        ({"q": np.zeros((3, 7))}, "no array poses"),
        ({"q": np.zeros((3, 6)), "poses": np.zeros((3, 4, 4))}, "expected configurations (K, 7)"),
    ],
)
def test_bad_plan_files_are_named(tmp_path, content, message):
    robot = qpik.load_robot("iiwa14")
    path = tmp_path / ("plan.csv" if content is None else "plan.npz")
    if content is None:
        path.write_text("q1\n0\n")
    else:
        np.savez(path, **content)
    with pytest.raises(InputError, match=re.escape(message)):
        as_track(path, robot)
