"""Seeded closed-loop episodes of the controller with self-collision, a moving sphere and motion limits,
judged on MuJoCo's measurements (``mj_geomDistance`` between the model's own geoms, not qpik's code).

One episode (:func:`make_episode`, everything drawn from ``default_rng(seed)``): an arm (the catalog's four,
or a loaded arm), one of three families, and a controller with every limit (:func:`limits`), of which the
caller may turn one off (``off``):

- ``fold``: the target is the pose of a point on the arm's own base column, shoulder or forearm capsule
  (the hand is pulled into the arm);
- ``sphere``: a sphere (radius 5 cm) starts 0–5 cm beyond d_i from a point of a moving link and moves
  toward it at 0.1–0.5 m/s until it would be 5 cm inside the link, then stops (the target: hold the start
  pose); a sphere the arm could not escape within its limits (:func:`escape`: one joint velocity that
  moves every link the sphere comes within d_i of away from it at 1.5 times its approach speed, reached in
  time at the acceleration limits) is drawn again, since no controller could hold it;
- ``limit``: the arm starts at full speed (its velocity limit) toward a joint limit, at the braking
  distance plus 0–20 % from it (the target: hold the start pose).

:func:`run_episode` integrates ``q ← q + v dt`` and measures, at every step, the self-distances of the
non-adjacent collision geoms that the controller does not leave out (:class:`qpik.sim.self_distance.SelfDistances`)
and the link–sphere clearances, and counts position, velocity, acceleration and jerk violations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

import qpik
from qpik.control import (
    ConfigurationLimit,
    Controller,
    DampingTask,
    FrameTask,
    ObstacleLimit,
    PostureTask,
    VelocityLimit,
)
from qpik.control.limits_motion import AccelerationLimit, BrakingLimit, JerkLimit
from qpik.control.self_collision import SelfCollisionLimit
from qpik.geometry import Sphere
from qpik.geometry.distance import distances
from qpik.robots.self_pairs import candidate_pairs
from qpik.sim import build_scene
from qpik.sim.self_distance import SelfDistances, allowed_links

FAMILIES = ("fold", "sphere", "limit")
DT = 0.002
STEPS = 500
D_SAFE_SELF, D_SAFE_OBS, D_INFLUENCE_OBS = 0.01, 0.02, 0.10
TOL = 1e-4  # m, distances
REL = 1e-6  # relative, limits
LOADED_A_MAX, LOADED_J_MAX = 10.0, 5000.0  # rad/s², rad/s³ given for loaded arms (their files have none)
PARK = np.array([3.0, 3.0, 3.0])  # m: the sphere out of the way
SPHERE_RADIUS = 0.05
BRAKE = 1.0  # m/s², the dampers' braking profile beyond d_i
ESCAPE_MARGIN = 1.5  # the premise's margin M on the retreat speed and on the time to reach it (escape_factor)
ESCAPE_SAMPLES = 41  # points of the sphere's path at which the threatened capsules are taken


@dataclass
class Episode:
    seed: int
    robot: qpik.Robot
    family: str
    q0: np.ndarray
    v0: np.ndarray
    target: np.ndarray
    start: np.ndarray  # sphere centre at t = 0 (m)
    velocity: np.ndarray  # m/s
    moving_for: float  # s


@dataclass
class Outcome:
    self_violation: float = 0.0  # m below d_s - TOL of a pair once above d_s
    obstacle_violation: float = 0.0
    position: int = 0
    velocity: int = 0
    acceleration: int = 0
    jerk: int = 0
    nan: int = 0
    min_self: float = np.inf  # m, smallest measured self-distance of a checked pair
    min_obstacle: float = np.inf  # m, smallest link–sphere clearance
    statuses: set = field(default_factory=set)


def a_max(robot: qpik.Robot) -> np.ndarray:
    return robot.a_max if robot.a_max is not None else np.full(robot.dof, LOADED_A_MAX)


def j_max(robot: qpik.Robot) -> np.ndarray:
    return robot.j_max if robot.j_max is not None else np.full(robot.dof, LOADED_J_MAX)


def _clear(robot: qpik.Robot, sc: SelfCollisionLimit, q: np.ndarray, v: np.ndarray) -> bool:
    """Whether the start (q, v) is one the controller can hold: every row of the self pairs at least 2 d_s high
    after braking any approach at BRAKE (its height less rate² / (2 BRAKE)); or, for a pair some arms keep
    within 2 d_s at every configuration (pybullet's panda: hand and link 5, 1 mm), not penetrating and not
    approaching."""
    h, A = sc.heights(robot, q)
    rate = np.minimum(A @ v, 0.0)
    clear = h - rate * rate / (2.0 * BRAKE) >= 2.0 * D_SAFE_SELF
    close = (h >= 0.0) & (rate == 0.0) & (h < 2.0 * D_SAFE_SELF)
    return bool(np.all(clear | close))


def _point_jacobians(robot: qpik.Robot, q: np.ndarray) -> np.ndarray:
    """(C, 2, 3, n): the derivatives of every capsule's end points (m/rad) by central differences of the
    model's forward kinematics (step 1e-6 rad)."""
    h = 1e-6
    steps = h * np.eye(robot.dof)
    cols = [(robot.capsule_segments(q + e) - robot.capsule_segments(q - e)) / (2 * h) for e in steps]
    return np.stack(cols, axis=-1)


def escape(robot: qpik.Robot, q0: np.ndarray, start: np.ndarray, velocity: np.ndarray, moving_for: float,
           margin: float = ESCAPE_MARGIN) -> tuple[float, np.ndarray]:  # fmt: skip
    r"""The premise of a sphere episode, from the arm's limits and kinematics alone (not the controller's rows):
    ``(t, v)``: the largest :math:`t` (at most 100; inf if the sphere threatens no capsule) such that one joint
    velocity ``v`` (n,), rad/s, moves every threatened point of the arm away from the
    sphere at :math:`t` times the sphere's speed toward it, a linear program (``scipy.optimize.linprog``) at
    ``q0`` (n,), rad, with the sphere (radius :data:`SPHERE_RADIUS`) moving from ``start`` (3,), m, at
    ``velocity`` (3,), m/s, for ``moving_for`` s. The episode is within the premise when :math:`t \ge M`
    (``margin``, :data:`ESCAPE_MARGIN`).

    - Threatened points: at :data:`ESCAPE_SAMPLES` points of the sphere's path (the arm held at ``q0``), the
      point of every capsule nearest the sphere where the capsule is within d_i of it and the sphere moves toward
      it at :math:`s_k = n_k^T \dot c > 0` (:math:`n_k` the unit normal from the sphere's centre to the point);
      the row is :math:`n_k^T J_k v \ge t\, s_k`, :math:`J_k` its point Jacobian. Every capsule counts, those of
      the base column too (no joint moves them: a sphere that comes within d_i of one cannot be escaped).
    - Velocity: :math:`|v_j| \le \bar v_j`, and room to keep ``v`` while the sphere moves:
      :math:`q_{min} \le q_0 + v\,T_{move} \le q_{max}`.
    - Acceleration: ``v`` is reached from rest at the acceleration limits (after the jerk ramp
      :math:`\tau_j = \bar a_j/\bar j_j`) within :math:`T = 2 (g_0 - d_s)/(M s)`, with :math:`g_0` the start gap
      and ``s`` the sphere's speed: :math:`|v_j| \le \bar a_j (T - \tau_j)`. A retreat speed that ramps up
      linearly to ``M s`` over ``T`` lets the sphere close :math:`s T/(2M) = (g_0 - d_s)/M^2` before it matches
      ``s`` (the arm and the sphere then part): the margin M applies to the speed and to the time.

    The Jacobians are those of ``q0``; the arm's motion changes them, and the controller meets its rows at their
    bounds, not beyond: M covers that, it is not a proof.
    """
    from scipy.optimize import linprog

    speed = float(np.linalg.norm(velocity))
    seg, dseg = robot.capsule_segments(q0), _point_jacobians(robot, q0)
    radii = robot.capsule_radii + SPHERE_RADIUS
    rows, need = [], []
    gap0 = np.inf
    for i, t in enumerate(np.linspace(0.0, moving_for, ESCAPE_SAMPLES)):
        centre = start + velocity * t
        ab = seg[:, 1] - seg[:, 0]
        lam = np.clip(np.einsum("ci,ci->c", centre - seg[:, 0], ab) / np.maximum(np.einsum("ci,ci->c", ab, ab), 1e-18),
                      0.0, 1.0)  # fmt: skip
        point = seg[:, 0] + lam[:, None] * ab
        dist = np.linalg.norm(point - centre, axis=1)
        d = dist - radii
        if i == 0:
            gap0 = float(d.min())
        n = (point - centre) / np.maximum(dist, 1e-12)[:, None]
        approach = n @ velocity
        for c in np.flatnonzero((d < D_INFLUENCE_OBS) & (approach > 0.0)):
            J = (1.0 - lam[c]) * dseg[c, 0] + lam[c] * dseg[c, 1]  # (3, n)
            rows.append(n[c] @ J)
            need.append(approach[c])
    if not rows:
        return np.inf, np.zeros(robot.dof)
    T = 2.0 * (gap0 - D_SAFE_OBS) / (margin * speed)
    amax, tau = a_max(robot), a_max(robot) / j_max(robot)
    cap = np.minimum(robot.v_max, amax * np.maximum(T - tau, 0.0))
    lo = np.maximum(-cap, (robot.q_min - q0) / moving_for)
    hi = np.minimum(cap, (robot.q_max - q0) / moving_for)
    n = robot.dof
    # variables (v, t): maximise t subject to  -row·v + need·t <= 0
    A = np.hstack([-np.array(rows), np.array(need)[:, None]])
    res = linprog(np.r_[np.zeros(n), -1.0], A_ub=A, b_ub=np.zeros(len(rows)),
                  bounds=[*zip(lo, hi), (0.0, 100.0)], method="highs")  # fmt: skip
    return (float(res.x[-1]), res.x[:n]) if res.status == 0 else (0.0, np.zeros(n))


def make_episode(robot: qpik.Robot, seed: int, family: str | None = None) -> Episode:
    """One episode (module docstring). Its start holds the premise of the safety checks: every self pair's
    rows clear (:func:`_clear`), the sphere starts beyond d_i of every link capsule (its direction is drawn
    again until it does), and the arm can escape the sphere within its velocity, position and acceleration
    limits (:func:`escape` ≥ :data:`ESCAPE_MARGIN`); a start that does not is drawn again."""
    rng = np.random.default_rng(seed)
    family = family or FAMILIES[seed % len(FAMILIES)]
    lo, hi = np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi)
    sc = SelfCollisionLimit()
    sc.check(robot, DT)
    for _ in range(1000):
        q0 = lo + (hi - lo) * (0.2 + 0.6 * rng.random(robot.dof))
        v0, start, velocity, moving = np.zeros(robot.dof), PARK.copy(), np.zeros(3), 0.0
        target = robot.fk(q0)
        seg = robot.capsule_segments(q0)
        moving_caps = np.flatnonzero(~robot.fixed_capsules)
        if family == "fold":
            c = int(rng.choice([0, 1, len(robot.capsules) // 2]))  # base column, shoulder, forearm
            point = seg[c, 0] + rng.random() * (seg[c, 1] - seg[c, 0])
            target = target.copy()
            target[:3, 3] = point
        elif family == "sphere":
            c = int(rng.choice(moving_caps[moving_caps >= len(robot.capsules) // 2]))
            point = seg[c, 0] + rng.random() * (seg[c, 1] - seg[c, 0])
            speed = rng.uniform(0.1, 0.5)
            contact = robot.capsules[c].radius + SPHERE_RADIUS
            gap = D_INFLUENCE_OBS + rng.uniform(0.0, 0.05)
            for _ in range(100):  # a direction whose start is beyond d_i of every capsule
                u = rng.normal(size=3)
                u /= np.linalg.norm(u)
                start = point + u * (contact + gap)
                if distances(seg, robot.capsule_radii, [Sphere(start, SPHERE_RADIUS)]).d.min() >= D_INFLUENCE_OBS:
                    break
            velocity, moving = -u * speed, (gap + 0.05) / speed  # it would end 5 cm inside the link
        else:
            j = int(rng.integers(robot.dof))
            vmax, a = robot.v_max[j], a_max(robot)[j]
            tau = a / j_max(robot)[j]
            room = (vmax * vmax / (2 * a) + vmax * (DT + tau)) * (1.0 + 0.2 * rng.random()) + 1e-3
            up = rng.random() < 0.5
            q0 = q0.copy()
            q0[j] = robot.q_max[j] - room if up else robot.q_min[j] + room
            v0[j] = vmax if up else -vmax
            target = robot.fk(q0)
        if family == "sphere" and escape(robot, q0, start, velocity, moving)[0] < ESCAPE_MARGIN:
            continue  # outside the premise: the arm could not escape this sphere within its limits
        if _clear(robot, sc, q0, v0):
            return Episode(seed, robot, family, q0, v0, target, start, velocity, moving)
    raise AssertionError(f"{robot.identifier} seed {seed}: no clear start in 1000 draws")


def limits(robot: qpik.Robot, obstacles: list, off: str | None = None) -> list:
    """Every limit, the one named ``off`` left out (``"braking"`` keeps the plain position limit)."""
    out = [ConfigurationLimit()]
    if off != "braking":
        out.append(BrakingLimit(a_max(robot), j_max(robot)))
    out.append(VelocityLimit())
    if off != "acceleration":
        out.append(AccelerationLimit(a_max(robot)))
    if off != "jerk":
        out.append(JerkLimit(j_max(robot)))
    out.append(ObstacleLimit(obstacles, D_INFLUENCE_OBS, D_SAFE_OBS, xi=0.5, brake=BRAKE, moving=True))
    if off != "self":
        out.append(SelfCollisionLimit(d_safe=D_SAFE_SELF, brake=BRAKE))
    return out


def run_episode(ep: Episode, off: str | None = None) -> Outcome:
    robot = ep.robot
    steps = max(STEPS, int(ep.moving_for / DT) + 150)
    sphere = Sphere(center=ep.start, radius=SPHERE_RADIUS)
    lims = limits(robot, [sphere], off)
    tasks = [FrameTask(ep.target, 50.0, 50.0), PostureTask(ep.q0, 1.0, 1e-3), DampingTask(1e-4)]
    ctrl = Controller(robot, tasks, lims, dt=DT)
    for lim in lims:
        if isinstance(lim, AccelerationLimit | JerkLimit):
            lim.reset(ep.v0, ep.v0)
    obstacle = next(lim for lim in lims if isinstance(lim, ObstacleLimit))
    known = off != "moving"  # "moving": the damper is not told the sphere moves
    obstacle.set_velocities([np.r_[ep.velocity * known, 0.0, 0.0, 0.0]])
    # MuJoCo measures: the model's own geoms, the pairs the controller checks (allowed pairs left out)
    checker = SelfCollisionLimit(d_safe=D_SAFE_SELF)
    checker.check(robot, DT)
    allowed = set(candidate_pairs(robot)) - set(checker.pairs(robot))
    scene = build_scene(robot, [sphere])
    model, data = scene.kin.model, scene.kin.data
    selfd = SelfDistances(model, robot.joint_names, allowed_links(robot, allowed))
    qadr = [model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in robot.joint_names]
    sphere_geom = int(scene.obstacle_geoms[0])
    out = Outcome()
    q, v1, v2 = ep.q0.copy(), ep.v0.copy(), ep.v0.copy()
    vmax, amax, jmax = robot.v_max, a_max(robot), j_max(robot)
    above_self = None
    above_obs = False
    clear = np.empty((len(scene.link_geoms), 1))
    for k in range(steps + 1):
        t = k * DT
        centre = ep.start + ep.velocity * min(t, ep.moving_for)
        model.geom_pos[sphere_geom] = centre
        data.qpos[qadr] = q
        mujoco.mj_kinematics(model, data)
        d_self = selfd.measure(data)
        d_obs = float(scene.clearances(clear).min())
        out.min_self = min(out.min_self, float(d_self.min(initial=np.inf)))
        out.min_obstacle = min(out.min_obstacle, d_obs)
        above_self = d_self >= D_SAFE_SELF if above_self is None else above_self | (d_self >= D_SAFE_SELF)
        low = above_self & (d_self < D_SAFE_SELF - TOL)
        if low.any():
            out.self_violation = max(out.self_violation, float(np.max(D_SAFE_SELF - d_self[low])))
        above_obs |= d_obs >= D_SAFE_OBS
        if above_obs and d_obs < D_SAFE_OBS - TOL:
            out.obstacle_violation = max(out.obstacle_violation, D_SAFE_OBS - d_obs)
        if k == steps:
            break
        if t < ep.moving_for + DT:
            obstacle.move([Sphere(center=centre, radius=SPHERE_RADIUS)])  # its velocity is set above
            if t >= ep.moving_for:
                obstacle.set_velocities(np.zeros((1, 6)))
        v = ctrl.step(q)
        out.statuses.add(ctrl.last.status)
        if not np.all(np.isfinite(v)):
            out.nan += 1
            v = np.zeros(robot.dof)
        a, a1 = (v - v1) / DT, (v1 - v2) / DT
        out.velocity += int(np.any(np.abs(v) > vmax * (1 + REL)))
        out.acceleration += int(np.any(np.abs(a) > amax * (1 + REL)))
        out.jerk += int(np.any(np.abs(a - a1) / DT > jmax * (1 + REL)))
        q = q + v * DT
        span = robot.q_max - robot.q_min
        out.position += int(np.any((q < robot.q_min - REL * span) | (q > robot.q_max + REL * span)))
        v2, v1 = v1, v
    return out
