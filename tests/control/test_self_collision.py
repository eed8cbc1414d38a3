"""Self-collision rows, the allowed pairs (default list, SRDF), MuJoCo's self-distances, and the motion limits."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import qpik
from qpik.algebra import symbolic as sy
from qpik.control import State
from qpik.control.limits_motion import AccelerationLimit, BrakingLimit, JerkLimit
from qpik.control.self_collision import SelfCollisionLimit, checked_pairs, row_layout
from qpik.core.errors import InputError
from qpik.geometry.distance import pair_expr
from qpik.robots.self_pairs import always_in_collision, candidate_pairs, default_allowed, pair_distances
from qpik.robots.srdf import disabled_links, link_names, read_disabled
from qpik.sim.self_distance import SelfDistances


@pytest.fixture(scope="module")
def panda() -> qpik.Robot:
    return qpik.load_robot("panda")


def _heights(robot, q: np.ndarray, pairs, q_plane: np.ndarray) -> np.ndarray:
    """Per row of :func:`row_layout`: the height (m) at q of the capsule's end over the separating plane found at
    ``q_plane``, carried rigidly with the plane's link to q (numpy, from the witness of ``pair_expr``)."""
    seg0, seg = robot.capsule_segments(q_plane), robot.capsule_segments(q)
    T0, T = robot.frames(q_plane), robot.frames(q)
    radii, caps = robot.capsule_radii, robot.capsules
    out = []
    for k, end, swapped in row_layout(robot, pairs):
        first, second = pairs[k][::-1] if swapped else pairs[k]
        (a, b), (qa, qb) = seg0[first], seg0[second]
        _, _, p, n, _ = pair_expr(
            tuple(a), tuple(b), radii[first], "capsule", (*qa, *(qb - qa), radii[second]), sy.NUMPY
        )
        move = T[caps[second].link] @ np.linalg.inv(T0[caps[second].link])  # the plane rides on link l
        p, n = move[:3, :3] @ np.array(p) + move[:3, 3], move[:3, :3] @ np.array(n)
        out.append(n @ (seg[first][end] - p) - radii[first])
    return np.array(out)


def test_rows_are_the_rate_of_the_heights(panda) -> None:
    """Row · v = d/dt of the row's height over its separating plane moving with the other link (central
    differences), for every checked pair; at q the heights are ≥ the pair's distance, the smaller one equal to it
    within the witness' position along the axis."""
    lim = SelfCollisionLimit(allowed=frozenset(), d_influence=10.0)  # every candidate pair, every row on
    rng = np.random.default_rng(3)
    pairs = checked_pairs(panda, frozenset())
    layout = row_layout(panda, pairs)
    assert len(layout) == 2 * len(pairs)  # the panda's capsules are segments: two rows per pair
    for _ in range(5):
        q = panda.q_min + (panda.q_max - panda.q_min) * (0.2 + 0.6 * rng.random(7))
        v = rng.normal(size=7)
        state = State(panda, q, 1e-3)
        A, _, _ = lim.rows(state, -np.full(7, 10.0), np.full(7, 10.0))
        h, rates = lim.heights(panda, q)
        np.testing.assert_allclose(rates, A)
        np.testing.assert_allclose(h, _heights(panda, q, pairs, q), atol=1e-12)
        eps = 1e-6
        fd = (_heights(panda, q + eps * v, pairs, q) - _heights(panda, q - eps * v, pairs, q)) / (2 * eps)
        np.testing.assert_allclose(A @ v, fd, atol=1e-5)
        d = pair_distances(panda, q, pairs)[0]
        by_pair = np.array([min(h[r] for r, (k, _, _) in enumerate(layout) if k == j) for j in range(len(pairs))])
        assert np.all(by_pair >= d - 1e-12)


def test_heights_bound_the_distance_after_a_motion(panda) -> None:
    """The separating-plane argument: after a random motion the pair's distance is ≥ the smaller height of its
    rows over the plane of the start (carried with the other link), dense sampling of motions."""
    rng = np.random.default_rng(8)
    pairs = checked_pairs(panda, frozenset())
    layout = row_layout(panda, pairs)
    for _ in range(20):
        q = panda.q_min + (panda.q_max - panda.q_min) * (0.2 + 0.6 * rng.random(7))
        for _ in range(10):
            q1 = q + rng.normal(scale=0.3, size=7)
            h = _heights(panda, q1, pairs, q)
            d = pair_distances(panda, q1, pairs)[0]
            for j in range(len(pairs)):
                assert d[j] >= min(h[r] for r, (k, _, _) in enumerate(layout) if k == j) - 1e-9


def test_damper_bound_at_the_safety_distance(panda) -> None:
    lim = SelfCollisionLimit(allowed=frozenset(), d_influence=10.0, d_safe=0.01, xi=0.5, buffer=0.0)
    q = panda.q_home
    state = State(panda, q, 1e-3)
    A, lower, upper = lim.rows(state, -panda.v_max, panda.v_max)
    h = lim.heights(panda, q)[0]
    moved = np.abs(A).sum(axis=1) > 1e-12  # a row no joint moves is left out (-inf)
    assert moved.sum() >= 8 and np.all(np.isneginf(lower[~moved]))
    want = -0.5 * (h - 0.01) / (10.0 - 0.01)
    separating = want > 0  # capped at what the box allows: at most the demand
    np.testing.assert_allclose(lower[moved & ~separating], want[moved & ~separating], atol=1e-12)
    assert np.all(lower[moved & separating] <= want[moved & separating] + 1e-12)
    assert np.all(np.isinf(upper))


def test_default_allowed_pairs_are_always_or_never_in_collision(panda) -> None:
    allowed = default_allowed(panda)
    assert default_allowed(panda) is allowed  # cached on the robot
    pairs = candidate_pairs(panda)
    rng = np.random.default_rng(11)  # other samples than the list's
    lo, hi = panda.q_min, panda.q_max
    d = pair_distances(panda, lo + (hi - lo) * rng.random((2000, 7)), pairs)
    for k, p in enumerate(pairs):
        if p in allowed:
            assert np.all(d[:, k] < 0.0) or np.all(d[:, k] > 0.0), p
    kept = [k for k, p in enumerate(pairs) if p not in allowed]
    assert kept and any(np.any(d[:, k] < 0.05) for k in kept)  # the checked pairs do come close


def test_always_in_collision_pairs_overlap_everywhere() -> None:
    """iiwa14: the pairs of links k and k + 2 overlap at every sample (other samples than the list's); the other
    candidates do not; both lists' pairs are in the default allowed list."""
    iiwa = qpik.load_robot("iiwa14")
    always = always_in_collision(iiwa)
    assert always <= default_allowed(iiwa) and len(always) == 3
    pairs = candidate_pairs(iiwa)
    lo, hi = np.maximum(iiwa.q_min, -np.pi), np.minimum(iiwa.q_max, np.pi)
    d = pair_distances(iiwa, lo + (hi - lo) * np.random.default_rng(5).random((2000, 7)), pairs)
    for k, p in enumerate(pairs):
        assert np.all(d[:, k] < 0.0) == (p in always), p


SRDF = """<robot name="panda">
  <disable_collisions link1="link1" link2="link3" reason="Never"/>
  <disable_collisions link1="link7" link2="link1" reason="Never"/>
  <disable_collisions link1="hand" link2="link1" reason="Never"/>
</robot>"""


def test_srdf_pairs_are_left_out(panda) -> None:
    assert link_names(panda) == tuple(f"link{k}" for k in range(1, 8))
    assert frozenset(("link1", "link3")) in read_disabled(SRDF)
    assert disabled_links(panda, SRDF) == {(1, 3), (1, 7)}
    pairs = checked_pairs(panda, srdf=SRDF)
    links = {(panda.capsules[c].link, panda.capsules[e].link) for c, e in pairs}
    assert (1, 3) not in links and (1, 7) not in links and (1, 5) in links
    with pytest.raises(InputError, match="srdf"):
        read_disabled("<robot><disable_collisions link1='a'/></robot>")


def test_mujoco_self_distances_agree_with_the_capsules(panda) -> None:
    """On the twin (geoms = qpik's capsules) MuJoCo's mj_geomDistance gives qpik's capsule distances."""
    import mujoco

    model = panda.mj_model()
    data = mujoco.MjData(model)
    measured = SelfDistances(model, panda.joint_names)
    assert len(measured.pairs) == len(candidate_pairs(panda))
    rng = np.random.default_rng(5)
    for _ in range(5):
        q = panda.q_min + (panda.q_max - panda.q_min) * rng.random(7)
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        got = measured.measure(data)
        caps = {(panda.capsules[c].link, panda.capsules[e].link): (c, e) for c, e in candidate_pairs(panda)}
        want = pair_distances(panda, q, [caps[tuple(k)] for k in measured.links])[0]
        np.testing.assert_allclose(got, want, atol=1e-6)


def test_motion_limits_bound_acceleration_jerk_and_braking(panda) -> None:
    dt = 0.002
    acc, jerk, brake = AccelerationLimit(), JerkLimit(), BrakingLimit(j_max=np.full(7, 1e12))
    q = panda.q_home.copy()
    for lim in (acc, jerk, brake):
        lim.check(panda, dt)
    v1, v2 = np.full(7, 0.5), np.full(7, 0.4)
    acc.reset(v1)
    jerk.reset(v1, v2)
    state = State(panda, q, dt)
    lo, hi = acc.bounds(state)
    np.testing.assert_allclose(hi - v1, panda.a_max * dt)
    np.testing.assert_allclose(v1 - lo, panda.a_max * dt)
    lo, hi = jerk.bounds(state)
    assert np.all(hi <= 2 * v1 - v2 + panda.j_max * dt * dt + 1e-12)
    assert np.all(lo >= 2 * v1 - v2 - panda.j_max * dt * dt - 1e-12)
    # braking: at the bound, one step then full deceleration ends at the limit (dense check, joint 1)
    _, hi = brake.bounds(state)
    a, pos, vel = panda.a_max[0], q[0] + hi[0] * dt, hi[0]
    while vel > 0:
        vel = max(vel - a * dt, 0.0)
        pos += vel * dt
    assert pos <= panda.q_max[0] + 1e-9
    assert pos > panda.q_max[0] - 0.05  # and the bound is not far from tight
    acc.observe(np.zeros(7))
    lo, hi = acc.bounds(state)
    np.testing.assert_allclose(hi, panda.a_max * dt)


def test_braked_damper_is_followed_at_the_braking_deceleration() -> None:
    """With ``brake`` α, an approach riding the damper's bound from beyond d_i down to d_s never has to slow
    faster than α (one dimension, dense steps); ξ = 0.5 m/s alone would need ξ²/(d_i − d_s) ≈ 5 m/s²."""
    import casadi as ca

    from qpik.control.limits import damper_lower

    h = ca.SX.sym("h")
    wide = ca.SX(np.array([100.0]))
    d_i, d_s, xi, alpha, dt = 0.06, 0.011, 0.5, 1.0, 1e-4
    gains = SimpleNamespace(d_influence=d_i, d_safe=d_s, xi=xi)
    bound = ca.Function("l", [h], [damper_lower(ca.SX(1.0), h, gains, -wide, wide, brake=alpha)])
    height, rates = d_i + 0.1, []
    while height > d_s + 1e-4:
        rate = float(bound(height))  # the fastest approach allowed (ḣ = l < 0)
        rates.append(rate)
        height += rate * dt
    decel = np.diff(rates) / dt  # ḣ rises toward 0: the deceleration
    assert decel.max() <= alpha * 1.01 and decel.max() >= 0.5 * alpha
    assert rates[0] < -2 * np.sqrt(alpha * (d_i - d_s))  # beyond d_i the braking profile allows more than ξ_α
