"""Seeded random closed-loop episodes of the QP controller, judged on MuJoCo's measurements.

One episode (:func:`make_episode`, a seed in, everything drawn from ``default_rng(seed)``):
an arm of the catalog, a solver (OSQP or DAQP), a start configuration, obstacles of every
shape (a sphere, a capsule, a box and a table, in that order, so that each arm compiles its
step function once), a target, dt and a number of steps, in one of six families:

- ``reach``: start inside the limits, obstacles 5–40 mm beyond d_s; the target a reachable
  pose, a pose up to 30 % past the limits, an unreachable one (2 m away) or a moving one;
- ``near_limits``: as ``reach``, with two joints within 0.02 rad of a limit;
- ``past_limits``: as ``reach``, with two joints 0.5–5° past a limit;
- ``inside``: one obstacle 10–90 % of d_s from a link (the start is inside the safety distance);
- ``past_limit_obstacle``: joints 0.5–5° past a limit and a sphere or a box 1–2.5 d_s from a link,
  in the direction in which the return from the limit moves that link; the target the pose of a
  configuration that moves the link 0.2 m further that way;
- ``slide``: a box face or a capsule parallel to a link axis 2–20 mm beyond d_s; the target the
  pose of a configuration that moves the link through it and along it, so that it slides.

:func:`run_episode` runs it with :func:`qpik.sim.simulate` on the MJCF twin, which measures
every link–obstacle clearance with ``mj_geomDistance`` at every step (MuJoCo's own distance
code, not qpik's), and returns the figures the tests judge.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

import qpik
from qpik.control import Controller, ControllerOptions
from qpik.geometry import Box, Capsule, HalfSpace, Sphere, distances
from qpik.sim import simulate

ARMS = ("nammoto7", "iiwa14", "zheng7", "panda")
SOLVERS = ("osqp", "daqp")
FAMILIES = ("reach", "near_limits", "past_limits", "inside", "past_limit_obstacle", "slide")
TARGETS = ("reachable", "past_limits", "unreachable", "moving")
D_SAFE = 0.02
D_INFLUENCE = 0.10
FAR = 0.5  # m: an obstacle parked out of the way (an episode that does not need all four shapes)


@dataclass
class Episode:
    """A drawn episode: what :func:`run_episode` runs (lengths in m, angles in rad, time in s)."""

    seed: int
    robot: qpik.Robot
    family: str
    solver: str
    q0: np.ndarray
    obstacles: tuple
    target_kind: str
    target: object
    dt: float
    steps: int


class MovingTarget:
    """A pose moving on a sinusoid around ``T0``: position ``T0.p + amp sin(w t)`` (m), twist its derivative."""

    def __init__(self, T0: np.ndarray, amp: np.ndarray, w: float, duration: float):
        self.T0, self.amp, self.w, self.duration = T0, amp, w, duration

    def pose(self, t: float) -> np.ndarray:
        T = self.T0.copy()
        T[:3, 3] += self.amp * np.sin(self.w * t)
        return T

    def twist(self, t: float) -> np.ndarray:
        return np.r_[self.amp * self.w * np.cos(self.w * t), 0.0, 0.0, 0.0]


def _unit(rng: np.random.Generator) -> np.ndarray:
    u = rng.normal(size=3)
    return u / np.linalg.norm(u)


def _rotation_with_z(n: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A rotation whose z axis is ``n`` and whose x axis is ``x`` made orthogonal to it."""
    x = x - (x @ n) * n
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(n, x), n])


def _point_on(seg: np.ndarray, c: int, rng: np.random.Generator) -> np.ndarray:
    return seg[c, 0] + rng.uniform(0.1, 0.9) * (seg[c, 1] - seg[c, 0])


@cache
def _moving_links(name: str) -> tuple[int, ...]:
    """Capsules (0-based) of links 3..n of arm ``name`` that have a length (obstacles beside them matter)."""
    seg = qpik.load_robot(name).capsule_segments(np.zeros(7))
    return tuple(c for c in range(2, len(seg)) if np.linalg.norm(seg[c, 1] - seg[c, 0]) > 0.05)


def _near(robot, seg, rng, kind: str, gap: float, c: int | None = None, u: np.ndarray | None = None):
    """A shape of ``kind`` whose nearest point is about ``gap`` (m) from link capsule ``c`` along ``u``."""
    c = int(rng.choice(_moving_links(robot.name))) if c is None else c
    p = _point_on(seg, c, rng)
    u = _unit(rng) if u is None else u
    surface = p + u * (robot.capsule_radii[c] + gap)
    if kind == "sphere":
        r = rng.uniform(0.03, 0.1)
        return Sphere(surface + u * r, r)
    if kind == "capsule":
        r = rng.uniform(0.02, 0.06)
        axis = np.cross(u, _unit(rng))
        axis *= rng.uniform(0.05, 0.2) / np.linalg.norm(axis)
        return Capsule(surface + u * r - axis, surface + u * r + axis, r)
    h = rng.uniform(0.03, 0.12, 3)
    return Box(surface + u * h[2], h, rotation=_rotation_with_z(-u, _unit(rng)))


def _table(robot, seg, rng, gap: float) -> HalfSpace:
    low = (np.minimum(seg[..., 0, 2], seg[..., 1, 2]) - robot.capsule_radii).min()
    return HalfSpace([0.0, 0.0, 1.0], low - gap)


def _parked(robot, seg, rng, kind: str):
    """A shape of ``kind`` out of the way (FAR beyond the arm's reach in a random horizontal direction)."""
    reach = np.abs(seg).max() + FAR + 1.0
    u = _unit(rng)
    u[2] = 0.0
    u /= np.linalg.norm(u)
    centre = u * reach
    if kind == "sphere":
        return Sphere(centre, 0.05)
    if kind == "capsule":
        return Capsule(centre, centre + np.array([0.0, 0.0, 0.1]), 0.05)
    return Box(centre, (0.05, 0.05, 0.05))


def _limits_start(robot, rng, past: bool) -> np.ndarray:
    """A start inside the limits with two joints near (0–0.02 rad inside) or past (0.5–5°) a limit."""
    q = rng.uniform(robot.q_min + 0.05, robot.q_max - 0.05)
    for j in rng.choice(robot.dof, 2, replace=False):
        off = np.radians(rng.uniform(0.5, 5.0)) if past else -rng.uniform(0.0, 0.02)
        q[j] = robot.q_max[j] + off if rng.uniform() < 0.5 else robot.q_min[j] - off
    return q


def _pushed(robot, q0: np.ndarray, c: int, direction: np.ndarray) -> np.ndarray:
    """A configuration that moves the middle of capsule ``c`` from q0 by ``direction`` (m), to first order.

    The point's Jacobian by central differences of ``capsule_segments`` (one batch); the least-squares joint step.
    """
    eps = 1e-6
    dq = eps * np.eye(robot.dof)
    mids = robot.capsule_segments(np.concatenate([q0 + dq, q0 - dq]))[:, c].mean(axis=1)  # (2n, 3)
    J = ((mids[: robot.dof] - mids[robot.dof :]) / (2 * eps)).T
    return q0 + np.linalg.lstsq(J, direction, rcond=1e-3)[0]


def _placed(robot, seg, make, low: float, high: float = np.inf, tries: int = 30):
    """``make()`` drawn until the shape's clearance to the arm (segments ``seg``) lies in (low, high); else None."""
    for _ in range(tries):
        shape = make()
        d = distances(seg, robot.capsule_radii, [shape]).d.min()
        if low < d < high:
            return shape
    return None


def _scene(robot, q0, rng, family: str) -> tuple[tuple, np.ndarray | None] | None:
    """The four obstacles (sphere, capsule, box, table) for ``family`` and, for the families that drive a
    link into its obstacle, a configuration beyond it (the target is its pose); None to draw again.

    Each obstacle is drawn until it is as far from the whole arm as the family asks (2 mm beyond d_s, or
    inside d_s for the ``inside`` family's one)."""
    seg = robot.capsule_segments(q0)
    shapes = ["sphere", "capsule", "box"]
    push = None
    clear = D_SAFE + 0.002
    if family == "past_limit_obstacle":
        past = np.flatnonzero((q0 > robot.q_max) | (q0 < robot.q_min))
        ret = np.zeros(robot.dof)
        ret[past] = np.where(q0[past] > robot.q_max[past], -1.0, 1.0) * robot.v_max[past]
        moved = robot.capsule_segments(q0 + 0.01 * ret) - seg  # where the return moves each capsule
        c = int(rng.choice(_moving_links(robot.name)))
        step = moved[c].mean(axis=0)
        if np.linalg.norm(step) < 1e-4:
            return None
        kind = str(rng.choice(["sphere", "box"]))
        u = step / np.linalg.norm(step)
        near = _placed(robot, seg, lambda: _near(robot, seg, rng, kind, rng.uniform(1.15, 2.5) * D_SAFE, c, u), clear)
        obstacles = [near if k == kind else _parked(robot, seg, rng, k) for k in shapes]
        push = _pushed(robot, q0, c, 0.2 * u + 0.1 * np.cross(u, _unit(rng)))
    elif family == "slide":
        c = int(rng.choice(_moving_links(robot.name)))
        a, b = seg[c]
        axis = (b - a) / np.linalg.norm(b - a)
        n = np.cross(axis, _unit(rng))
        n /= np.linalg.norm(n)
        kind = str(rng.choice(["box", "capsule"]))

        def make():
            gap = robot.capsule_radii[c] + D_SAFE + rng.uniform(0.002, 0.02)
            mid = a + rng.uniform(0.2, 0.8) * (b - a)
            if kind == "box":
                h = np.array([rng.uniform(0.1, 0.3), rng.uniform(0.05, 0.3), rng.uniform(0.02, 0.1)])
                centre = mid - n * (gap + h[2]) + axis * rng.uniform(-0.1, 0.1)
                return Box(centre, h, rotation=_rotation_with_z(n, axis))
            r = rng.uniform(0.02, 0.08)
            p0 = mid - n * (gap + r) - axis * rng.uniform(0.1, 0.3)
            return Capsule(p0, p0 + axis * rng.uniform(0.2, 0.5) + 0.02 * _unit(rng), r)

        near = _placed(robot, seg, make, D_SAFE + 0.001)
        obstacles = [near if k == kind else _parked(robot, seg, rng, k) for k in shapes]
        push = _pushed(robot, q0, c, -0.15 * n + rng.uniform(-0.3, 0.3) * axis + 0.1 * np.cross(n, axis))
    else:
        inside = int(rng.integers(3)) if family == "inside" else -1
        obstacles = [
            _placed(robot, seg, lambda k=k: _near(robot, seg, rng, k, rng.uniform(0.1, 0.9) * D_SAFE), 0.001, D_SAFE)
            if i == inside
            else _placed(robot, seg, lambda k=k: _near(robot, seg, rng, k, D_SAFE + rng.uniform(0.005, 0.04)), clear)
            for i, k in enumerate(shapes)
        ]
    obstacles.append(_table(robot, seg, rng, D_SAFE + rng.uniform(0.005, 0.05)))
    return None if any(o is None for o in obstacles) else (tuple(obstacles), push)


def make_episode(seed: int) -> Episode:
    """The episode of ``seed``: arm, solver and family cycle with the seed, the rest is drawn."""
    rng = np.random.default_rng(seed)
    robot = qpik.load_robot(ARMS[seed % len(ARMS)])
    solver = SOLVERS[(seed // len(ARMS)) % len(SOLVERS)]
    family = FAMILIES[(seed // (len(ARMS) * len(SOLVERS))) % len(FAMILIES)]
    while True:
        if family in ("near_limits", "past_limits", "past_limit_obstacle"):
            q0 = _limits_start(robot, rng, past=family != "near_limits")
        else:
            q0 = rng.uniform(robot.q_min + 0.05, robot.q_max - 0.05)
        drawn = _scene(robot, q0, rng, family)
        if drawn is not None:
            obstacles, push = drawn
            break
    dt = float(rng.choice([0.001, 0.002, 0.002, 0.005]))
    steps = int(rng.integers(200, 401))
    mid, half = (robot.q_max + robot.q_min) / 2, (robot.q_max - robot.q_min) / 2
    target_kind = "pushing" if push is not None else str(rng.choice(TARGETS))
    if target_kind == "pushing":  # a pose beyond the obstacle: the link is driven into it and along it
        target = robot.fk(push)
    elif target_kind == "reachable":
        target = robot.fk(rng.uniform(robot.q_min, robot.q_max))
    elif target_kind == "past_limits":
        target = robot.fk(rng.uniform(mid - 1.3 * half, mid + 1.3 * half))
    elif target_kind == "unreachable":
        target = robot.fk(q0)
        target[:3, 3] = 2.0 * _unit(rng)
    else:
        amp = rng.uniform(0.05, 0.4, 3) * rng.choice([-1.0, 1.0], 3)
        target = MovingTarget(robot.fk(q0), amp, rng.uniform(1.0, 6.0), steps * dt)
    return Episode(seed, robot, family, solver, q0, obstacles, target_kind, target, dt, steps)


@dataclass
class Outcome:
    """What an episode did, measured on the MuJoCo twin.

    Attributes:
        position: the largest step of a joint further past a limit than it has been yet (rad):
            ``max_k (e_k − min_{i<k} e_i)`` with ``e`` the excess past ``[q_min, q_max]`` (0 inside).
        velocity: the largest ``|v_j| − v_max_j`` (rad/s).
        drop: per (link, obstacle) pair that has been at or beyond d_s, how far it fell below d_s
            afterwards, the largest (m; ≤ 0 when it never did).
        decrease: per pair that started inside d_s, the largest one-step decrease of its clearance
            before it reached d_s (m; ≤ 0 when it never decreased).
        started_inside: a pair started inside d_s.
        closest: the smallest clearance of the episode (m).
        active: an obstacle came within the influence distance.
        statuses: the controller's status counts.
        finite: every logged q and v is finite.
    """

    position: float
    velocity: float
    drop: float
    decrease: float
    started_inside: bool
    closest: float
    active: bool
    statuses: dict
    finite: bool


def run_episode(ep: Episode) -> Outcome:
    """Run ``ep`` in MuJoCo (every step recorded) and measure it; see :class:`Outcome`."""
    robot = ep.robot
    # these episodes judge the obstacle rows; their starts are drawn without regard to the arm's own links (some
    # start inside a self pair), so self-collision is off here and judged in tests/safety_episodes.py
    ctrl = Controller.for_robot(
        robot,
        obstacles=ep.obstacles,
        dt=ep.dt,
        solver=ep.solver,
        d_safe=D_SAFE,
        options=ControllerOptions(d_influence=D_INFLUENCE, self_collision=False),
    )
    log = simulate(robot, ctrl, ep.q0, ep.steps * ep.dt, ep.dt, obstacles=ep.obstacles, target=ep.target)
    excess = np.maximum(np.maximum(log.q - robot.q_max, robot.q_min - log.q), 0.0)
    best = np.minimum.accumulate(excess, axis=0)
    position = float((excess[1:] - best[:-1]).max())
    velocity = float((np.abs(log.v) - robot.v_max).max())
    cl = log.clearance  # (K, L, O), mj_geomDistance
    reached = np.maximum.accumulate(cl >= D_SAFE, axis=0)
    drop = float(np.where(reached, D_SAFE - cl, -np.inf).max())
    steps = np.diff(cl, axis=0)
    decrease = float(np.where(~reached[1:], -steps, -np.inf).max())
    statuses = {str(s): int(n) for s, n in zip(*np.unique(log.status, return_counts=True))}
    return Outcome(
        position=position,
        velocity=velocity,
        drop=drop,
        decrease=decrease,
        started_inside=bool((cl[0] < D_SAFE).any()),
        closest=float(cl.min()),
        active=bool((cl < D_INFLUENCE).any()),
        statuses=statuses,
        finite=bool(np.isfinite(log.q).all() and np.isfinite(log.v).all()),
    )
