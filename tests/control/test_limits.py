"""Limits of the QP: damper rows vs finite differences of the geometry, and limits and clearances holding in
closed loop over seeded random episodes on the MuJoCo twin (:mod:`episodes`): 144 by default, 1,008 with
``QPIK_TESTS_LARGE=1``."""

from __future__ import annotations

import episodes
import numpy as np
import pytest
from conftest import LARGE, SEEDS, random_q
from hypothesis import given, settings

import qpik
from qpik.control import ConfigurationLimit, Controller, ObstacleLimit, State, VelocityLimit
from qpik.control.state import kinematics_of
from qpik.geometry.distance import distances
from qpik.geometry.shapes import Box, Capsule, HalfSpace, Sphere

D_SAFE = 0.02
D_INFL = 0.10
ROUND = len(episodes.ARMS) * len(episodes.SOLVERS) * len(episodes.FAMILIES)  # 48 seeds: each combination once
EPISODES = ROUND * (21 if LARGE else 3)  # 1,008 episodes in the large run, 144 by default


def clearance(robot: qpik.Robot, Q: np.ndarray, obstacles) -> np.ndarray:
    """(N, C, O) signed distances along a trajectory Q (N, 7), by the geometry module on FK segments."""
    seg = robot.capsule_segments(Q)  # (N, C, 2, 3)
    N, C = seg.shape[:2]
    d = distances(seg.reshape(N * C, 2, 3), np.tile(robot.capsule_radii, N), obstacles).d
    return d.reshape(N, C, -1)


def scene(robot: qpik.Robot, q0: np.ndarray, rng: np.random.Generator) -> list:
    """Two spheres close to the arm at q0 and a table below it, all at least D_SAFE + 5 mm away."""
    seg = robot.capsule_segments(q0)
    caps = robot.capsule_radii
    obstacles = []
    for _ in range(2):
        c = rng.integers(2, len(seg))  # not the base link
        p = seg[c, 0] + rng.uniform() * (seg[c, 1] - seg[c, 0])
        u = rng.normal(size=3)
        r = rng.uniform(0.03, 0.1)
        center = p + u / np.linalg.norm(u) * (caps[c] + r + D_SAFE + rng.uniform(0.01, 0.06))
        obstacles.append(Sphere(center, r))
    low = (np.minimum(seg[..., 0, 2], seg[..., 1, 2]) - caps).min()
    obstacles.append(HalfSpace([0.0, 0.0, 1.0], low - D_SAFE - rng.uniform(0.005, 0.05)))
    d = clearance(robot, q0[None], obstacles)[0]
    return obstacles if d.min() > D_SAFE + 0.005 else scene(robot, q0, rng)


@pytest.mark.parametrize("arm", episodes.ARMS)
def test_limits_and_clearance_hold_over_random_episodes(arm):
    """:data:`EPISODES` seeded closed-loop episodes (a quarter per arm, both solvers, six scene families:
    :mod:`episodes`; 1,008 with ``QPIK_TESTS_LARGE=1``), run on
    the MuJoCo twin, which measures every link–obstacle clearance at every step (mj_geomDistance, not qpik's
    distance code). Over every one: no joint further past a limit than it has been (1e-6 rad), no velocity above
    its limit (1e-6 rad/s), a clearance that has been at d_s never below d_s − 1e-4 m, one that starts inside d_s
    never decreasing (by more than 1e-6 m in a step) until it is out, no NaN, no exception, no failed step."""
    seeds = [s for s in range(EPISODES) if episodes.ARMS[s % len(episodes.ARMS)] == arm]
    worst = {"position": 0.0, "velocity": 0.0, "drop": -np.inf, "decrease": -np.inf}
    seen, close, inside = set(), 0, 0
    for seed in seeds:
        ep = episodes.make_episode(seed)
        out = episodes.run_episode(ep)
        for key in worst:
            worst[key] = max(worst[key], getattr(out, key))
        assert out.finite and "failed" not in out.statuses, (seed, out)
        seen.add((ep.solver, ep.family, ep.target_kind))
        close += out.closest < episodes.D_SAFE + 0.002
        inside += out.started_inside
    assert worst["position"] <= 1e-6 and worst["velocity"] <= 1e-6, worst
    assert worst["drop"] <= 1e-4 and worst["decrease"] <= 1e-6, worst
    assert {(s, f) for s, f, _ in seen} == {(s, f) for s in episodes.SOLVERS for f in episodes.FAMILIES}
    assert {t for _, _, t in seen} == {*episodes.TARGETS, "pushing"}
    assert close > len(seeds) // 4 and inside >= len(seeds) // 6  # the obstacles were close enough to matter


def scene_with_planes(robot: qpik.Robot, q0: np.ndarray, rng: np.random.Generator) -> list:
    """:func:`scene` plus a box and a capsule obstacle near the arm (the kinds with two rows per pair)."""
    seg = robot.capsule_segments(q0)
    extra = []
    for _ in range(2):
        c = rng.integers(2, len(seg))
        p = seg[c, 0] + rng.uniform() * (seg[c, 1] - seg[c, 0])
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        gap = robot.capsule_radii[c] + D_SAFE + rng.uniform(0.01, 0.05)
        extra.append(Box(p + u * (gap + 0.05), (0.05, 0.08, 0.05), rotation=_rotation(rng)))
        extra.append(Capsule(p - u * (gap + 0.03), p - u * (gap + 0.03) + 0.2 * rng.normal(size=3), 0.03))
    return scene(robot, q0, rng) + extra


def _rotation(rng: np.random.Generator) -> np.ndarray:
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q *= np.sign(np.diag(R))
    return Q * np.sign(np.linalg.det(Q))


def test_damper_rows_are_height_rates():
    """Each damper row is the rate of its height: the distance for a sphere's witness row, the height of an
    axis end above the step's separating plane (frozen) for the two rows of a box, capsule or half-space;
    the lower of the two heights is the distance itself (finite differences and the geometry module)."""
    rng = np.random.default_rng(5)
    checked = {-1: 0, 0: 0, 1: 0}
    for name in ("iiwa14", "panda", "nammoto7", "zheng7"):
        robot = qpik.load_robot(name)
        layout = kinematics_of(robot)
        for q in random_q(robot, 12, 8, margin=0.1):
            obstacles = scene_with_planes(robot, q, rng)
            lim = ObstacleLimit(obstacles, d_influence=10.0, d_safe=D_SAFE)  # every pair active
            state = State(robot, q, 0.001)
            A, lo, _ = lim.rows(state, -np.ones(7), np.ones(7))
            h = state.damper_heights(lim.obstacles)
            dist = distances(robot.capsule_segments(q), robot.capsule_radii, obstacles)
            v = rng.normal(size=7)
            eps = 1e-6
            seg_p, seg_m = robot.capsule_segments(q + eps * v), robot.capsule_segments(q - eps * v)
            d_p, d_m = (distances(sg, robot.capsule_radii, obstacles).d for sg in (seg_p, seg_m))
            rows = layout.damper_layout(lim.obstacles.kinds)
            assert len(rows) == len(A) == len(h) == lim.size(robot)
            for r, (c, o, end) in enumerate(rows):
                if not np.isfinite(lo[r]) or dist.d[c, o] <= 0.0:  # overlapping: the witness may be any deepest point
                    continue
                if end < 0:
                    rate = (d_p[c, o] - d_m[c, o]) / (2 * eps)
                    assert h[r] == pytest.approx(dist.d[c, o], abs=1e-12)
                else:
                    n, p_obs, r_c = dist.normal[c, o], dist.p_obs[c, o], robot.capsule_radii[c]
                    rate = (n @ (seg_p[c, end] - p_obs) - n @ (seg_m[c, end] - p_obs)) / (2 * eps)
                    assert h[r] == pytest.approx(n @ (robot.capsule_segments(q)[c, end] - p_obs) - r_c, abs=1e-12)
                    assert h[r] >= dist.d[c, o] - 1e-12  # the plane separates: the lower end is at the distance
                    other = r + 1 if end == 0 else r - 1
                    assert min(h[r], h[other]) == pytest.approx(dist.d[c, o], abs=1e-9)
                assert A[r] @ v == pytest.approx(rate, abs=2e-6)
                checked[end] += 1
    assert min(checked.values()) > 300, checked


def test_state_segments_match_robot():
    robot = qpik.load_robot("panda")
    for q in random_q(robot, 10, 1):
        np.testing.assert_allclose(State(robot, q, 0.001).segments, robot.capsule_segments(q), atol=1e-14)
        np.testing.assert_allclose(State(robot, q, 0.001).J, robot.jacobian(q), atol=1e-14)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_recovers_from_past_position_limit(seed):
    """Starting past a limit the box still admits a solution, which moves back at most at v_max."""
    rng = np.random.default_rng(seed)
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home.copy()
    j = rng.integers(7)
    q[j] = robot.q_max[j] + rng.uniform(0.001, 0.3) if rng.uniform() < 0.5 else robot.q_min[j] - rng.uniform(0.001, 0.3)
    ctrl = Controller.for_robot(robot, target=robot.fk(robot.q_home), dt=0.01)
    for _ in range(300):
        v = ctrl.step(q)
        assert ctrl.last.status in ("recovering", "ok")
        assert np.all(np.abs(v) <= robot.v_max + 1e-9)
        q_next = q + v * ctrl.dt
        dist_before = np.maximum(q - robot.q_max, robot.q_min - q).clip(0)
        dist_after = np.maximum(q_next - robot.q_max, robot.q_min - q_next).clip(0)
        assert np.all(dist_after <= dist_before + 1e-12)  # never further out
        q = q_next
    assert robot.within_limits(q, tol=1e-9)


@pytest.mark.parametrize("penetration", [0.01, -0.03])  # inside d_s, and overlapping (d < 0)
def test_recovers_from_inside_safety_distance(penetration):
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home.copy()
    seg = robot.capsule_segments(q)
    c = int(np.argmax(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)))  # the longest link
    p = 0.5 * (seg[c, 0] + seg[c, 1])
    u = np.cross(seg[c, 1] - seg[c, 0], [0.3, 0.5, 0.8])
    u /= np.linalg.norm(u)
    r = 0.05
    obstacles = [Sphere(p + u * (robot.capsule_radii[c] + r + penetration), r)]
    ctrl = Controller.for_robot(robot, target=robot.fk(q), obstacles=obstacles, dt=0.002, d_safe=D_SAFE)
    d0 = clearance(robot, q[None], obstacles).min()
    for _ in range(400):
        q = q + ctrl.step(q) * ctrl.dt
        if _ == 0:
            assert ctrl.last.status == ("penetrating" if penetration < 0 else "recovering")
        assert ctrl.last.status != "failed"
    d1 = clearance(robot, q[None], obstacles).min()
    assert d1 > d0 and d1 >= D_SAFE - 1e-4


def test_conflicting_limits_raise():
    robot = qpik.load_robot("iiwa14")
    tasks = Controller.for_robot(robot).tasks
    bad = robot.q_max.copy()
    bad[2] = robot.q_min[2] - 0.1
    with pytest.raises(qpik.InfeasibleError, match="joint"):
        Controller(robot, tasks, [ConfigurationLimit(q_max=bad)])
    with pytest.raises(qpik.InfeasibleError):
        Controller(robot, tasks, [ConfigurationLimit(margin=3.0)])
    with pytest.raises(qpik.InfeasibleError):
        Controller(robot, tasks, [VelocityLimit(-np.ones(7))])
    with pytest.raises(qpik.InfeasibleError):
        ObstacleLimit([Sphere([1, 0, 0], 0.1)], d_influence=0.02, d_safe=0.05)
    with pytest.raises(qpik.InfeasibleError):  # ξ dt larger than the damper band
        Controller(robot, tasks, [ObstacleLimit([Sphere([1, 0, 0], 0.1)], xi=100.0)], dt=0.01)


def _link_along_a_box(robot: qpik.Robot, seed: int):
    """A random start, a box face parallel to a random link's axis 1–20 mm beyond d_s, and a target 20 % past
    the limits: the link slides along the face at full speed while tilting about it."""
    rng = np.random.default_rng(seed)
    while True:
        q0 = rng.uniform(robot.q_min + 0.05, robot.q_max - 0.05)
        seg = robot.capsule_segments(q0)
        c = rng.integers(2, len(seg))
        a, b = seg[c]
        if np.linalg.norm(b - a) < 0.05:
            continue
        axis = (b - a) / np.linalg.norm(b - a)
        n = np.cross(axis, rng.normal(size=3))
        n /= np.linalg.norm(n)
        gap = robot.capsule_radii[c] + D_SAFE + rng.uniform(0.002, 0.02)
        mid = a + rng.uniform(0.2, 0.8) * (b - a)
        h = np.array([rng.uniform(0.05, 0.3), rng.uniform(0.05, 0.3), rng.uniform(0.02, 0.1)])
        centre = mid - n * (gap + h[2]) + axis * rng.uniform(-0.1, 0.1)
        box = Box(centre, h, rotation=episodes._rotation_with_z(n, axis))
        if clearance(robot, q0[None], [box]).min() >= D_SAFE + 0.001:
            break
    mid, half = (robot.q_max + robot.q_min) / 2, (robot.q_max - robot.q_min) / 2
    return q0, box, robot.fk(rng.uniform(mid - 1.2 * half, mid + 1.2 * half))


@pytest.mark.parametrize(("name", "seed"), [("iiwa14", 12), ("iiwa14", 14), ("panda", 16)])
def test_link_sliding_along_a_box_keeps_d_safe(name, seed):
    """A link sliding along a box face at full speed: as it tilts, the face's nearest point jumps from one part of
    the link to another, which one witness row per pair did not see: these three scenes (of 40 drawn) lost
    0.1–0.9 mm in single steps and went down to 17.6, 5.7 and 16.7 mm with d_s = 20 mm. MuJoCo's clearance stays
    above d_s − 1e-4 m."""
    from qpik.sim import simulate

    robot = qpik.load_robot(name)
    q0, box, target = _link_along_a_box(robot, seed)
    dt = 0.002
    ctrl = Controller.for_robot(robot, target=target, obstacles=[box], dt=dt, d_safe=D_SAFE)
    log = simulate(robot, ctrl, q0, 0.8, dt, obstacles=[box])
    assert log.clearance.min() >= D_SAFE - 1e-4
