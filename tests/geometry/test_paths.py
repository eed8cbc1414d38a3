"""qpik.geometry.paths: WaypointPath passes through its waypoints and its twist is the derivative of its pose (finite
differences); the path protocol is importable without the simulator or the problem files."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import qpik
import qpik.problems
import qpik.sim
from qpik.geometry.paths import TargetPath, TimedPath, WaypointPath


def _poses(seed: int, N: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = np.zeros((N, 4, 4))
    T[:, :3, :3] = Rotation.random(N, random_state=rng).as_matrix()
    T[:, :3, 3] = rng.uniform(-1, 1, (N, 3))
    T[:, 3, 3] = 1.0
    return T


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**16), N=st.integers(2, 6))
def test_waypoint_path_passes_its_waypoints_and_its_twist_is_its_derivative(seed, N):
    T = _poses(seed, N)
    times = np.cumsum(np.random.default_rng(seed).uniform(0.5, 2.0, N)) - 0.3
    path = WaypointPath(T, times)
    assert isinstance(path, TimedPath) and np.isclose(path.duration, times[-1] - times[0])
    assert np.abs(path.pose(times - times[0]) - T).max() < 1e-12
    # inside each segment: [v; ω] against central differences of the pose (ω from Ṙ Rᵀ)
    t = (times[:-1] + times[1:]) / 2 - times[0]
    h = 1e-6
    P0, P1 = path.pose(t - h), path.pose(t + h)
    v = (P1[:, :3, 3] - P0[:, :3, 3]) / (2 * h)
    W = (P1[:, :3, :3] - P0[:, :3, :3]) / (2 * h) @ np.swapaxes(path.pose(t)[:, :3, :3], 1, 2)
    w = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)
    tw = path.twist(t)
    assert np.abs(tw[:, :3] - v).max() < 1e-6 and np.abs(tw[:, 3:] - w).max() < 1e-5


def test_waypoint_path_bad_input_names_the_argument():
    T = _poses(0, 3)
    with pytest.raises(qpik.InputError, match="times"):
        WaypointPath(T, [0.0, 2.0, 1.0])
    with pytest.raises(qpik.InputError, match="poses"):
        WaypointPath(T[0])


def test_path_protocol_imports_neither_the_simulator_nor_the_problem_files():
    tree = ast.parse(Path(qpik.geometry.paths.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not {m for m in imported if m.startswith(("qpik.sim", "qpik.problems", "qpik.control", "qpik.planning"))}
    assert qpik.problems.TargetPath is TargetPath and qpik.sim.TimedPath is TimedPath
