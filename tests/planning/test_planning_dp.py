"""The planner's DP (qpik.planning.dp) on real grids: the fewest reconfigurations equal the minimum found by
enumerating every sequence of grid states (brute force), the compiled kernel equals its numpy twin, and the
grid holds exactly the grid values inside the exact feasible intervals."""

from __future__ import annotations

import numpy as np
import pytest

import qpik
from qpik.geometry import Sphere
from qpik.geometry.distance import distances
from qpik.objectives import JointLimitMargin
from qpik.planning import dp
from qpik.planning import grid as grid_module
from qpik.planning.grid import Grid
from qpik.scene import Scene

IIWA = qpik.load_robot("iiwa14")


def _turning(angles) -> np.ndarray:
    """q_home's pose turned about the tool axis by each angle (rad): (N, 4, 4)."""
    T0 = IIWA.fk(IIWA.q_home)
    out = np.repeat(T0[None], len(angles), 0)
    for k, a in enumerate(angles):
        c, s = np.cos(a), np.sin(a)
        out[k, :3, :3] = T0[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    return out


def _brute_force(q: np.ndarray, ok: np.ndarray, lim: float, motion: np.ndarray) -> tuple[int, float]:
    """Fewest transitions moving some joint by more than ``lim`` over every sequence of feasible states, then the
    least Σ motion_k ‖Δq‖² over the others: q (N, S, n), ok (N, S), by enumerating all S^N sequences."""
    N, S, _ = q.shape
    jumps, cost = np.zeros([S] * N, np.int16), np.zeros([S] * N)
    valid = np.ones([S] * N, bool)
    for k in range(N):
        shape = [1] * N
        shape[k] = S
        valid &= ok[k].reshape(shape)
    for k in range(N - 1):
        D = q[k + 1][None] - q[k][:, None]
        bad = (np.abs(D) > lim).any(axis=-1)
        shape = [1] * N
        shape[k] = shape[k + 1] = S
        jumps += bad.reshape(shape)
        cost += np.where(bad, 0.0, motion[k] * (D * D).sum(axis=-1)).reshape(shape)
    J = np.where(valid, jumps, np.iinfo(np.int16).max)
    least = int(J.min())
    return least, float(cost[least == J].min())


@pytest.mark.parametrize("angles, least", [((0.0, 0.5, 2.0, 2.5), 1), ((0.0, 0.9, 1.8, 2.7), 0)])
def test_fewest_reconfigurations_equal_the_brute_force_minimum(angles, least):
    N = len(angles)
    grid = Grid(Scene.of(IIWA), _turning(angles), 6)
    layers = grid.layers(0, N)
    tr = dp.Transitions(np.full((N - 1, 7), 1.0), np.ones(N - 1), np.ones(N))
    res = dp.solve(grid, tr, grid.G // 2, fewest=True)
    S = grid.rows * grid.G
    best, cost = _brute_force(layers.q.reshape(N, S, -1), layers.ok.reshape(N, S), 1.0, tr.motion)
    assert best == least  # the instance is what it is meant to be
    assert len(res.reconfigurations) == best and res.cost == pytest.approx(cost, abs=1e-12)
    # the plan's own transitions: the reconfigurations are exactly the ones over the bound
    over = (np.abs(np.diff(res.q, axis=0)) > 1.0 + 1e-12).any(axis=1)
    assert np.flatnonzero(over).tolist() == res.reconfigurations
    forbid = dp.solve(grid, tr, grid.G // 2, fewest=False)
    assert (forbid.failure is None) == (least == 0)
    if least:
        assert forbid.failure.waypoint >= 1 and "joint" in forbid.failure.reason


def test_compiled_kernel_equals_its_numpy_twin(monkeypatch):
    rng = np.random.default_rng(3)
    T = IIWA.fk(IIWA.q_home + np.linspace(0, 0.4, 12)[:, None] * rng.uniform(-1, 1, 7))
    grid = Grid(Scene.of(IIWA, [Sphere((0.5, 0.3, 0.6), 0.1)], d_safe=0.02, objective=JointLimitMargin()), T, 60)
    dt = np.full(11, 0.1)
    tr = dp.Transitions(np.minimum(0.3, IIWA.v_max * 0.1)[None].repeat(11, 0), 1 / dt, np.full(12, 0.1), dt,
                        np.full(7, 20.0))  # fmt: skip
    for fewest in (False, True):
        native = dp.solve(grid, tr, 4, fewest)
        monkeypatch.setattr(dp, "_library", lambda: None)
        twin = dp.solve(grid, tr, 4, fewest)
        monkeypatch.undo()
        assert np.array_equal(native.rows, twin.rows) and np.array_equal(native.index, twin.index)
        assert native.cost == pytest.approx(twin.cost, rel=1e-12)


def test_grid_states_in_c_equal_their_numpy_twin(monkeypatch):
    rng = np.random.default_rng(5)
    T = IIWA.fk(IIWA.q_home + np.linspace(0, 0.5, 7)[:, None] * rng.uniform(-1, 1, 7))
    args = (Scene.of(IIWA, [Sphere((0.45, 0.1, 0.7), 0.12)], d_safe=0.02, objective=JointLimitMargin()), T, 90)
    native = Grid(*args).layers(1, 7)
    monkeypatch.setattr(grid_module, "_library", lambda: None)
    twin = Grid(*args).layers(1, 7)
    assert np.array_equal(native.ok, twin.ok) and 0 < native.ok.sum() < native.ok.size
    assert np.array_equal(native.f, twin.f) and np.array_equal(native.q[native.ok], twin.q[twin.ok])


def test_grid_states_are_the_grid_values_inside_the_exact_intervals_and_clear():
    T = IIWA.fk(IIWA.q_home + np.linspace(0, 0.3, 3)[:, None])
    ball = Sphere((0.4, 0.2, 0.7), 0.12)
    grid = Grid(Scene.of(IIWA, [ball], d_safe=0.03), T, 90)
    layers = grid.layers(0, 3)
    for k in range(3):
        sols = qpik.ik(IIWA, np.repeat(T[k][None], grid.G, 0), grid.values)
        inside = np.array([[grid.intervals[k].contains(int(b), v) for v in grid.values] for b in sols.branch])
        assert np.array_equal(grid.inside[k], inside)
        assert np.abs(layers.q[k][inside] - sols.q.transpose(1, 0, 2)[inside]).max() < 1e-12
        d = distances(IIWA.capsule_segments(sols.q.reshape(-1, 7)), IIWA.capsule_radii, [ball]).d
        clear = d.reshape(grid.G, grid.rows, -1).min(axis=2).T >= 0.03
        assert np.array_equal(layers.ok[k], inside & sols.within_limits.T & clear)
