r"""The kinematic state of one control step, computed once and shared by every task and limit.

:class:`State` evaluates, for a configuration ``q`` and the obstacles of the controller,
ONE natively compiled CasADi function (:class:`Kinematics`, :mod:`qpik.compiled`) traced
from the expression builders of the other layers — nothing here re-derives them:

- the frames (:meth:`~qpik.robots.chain.SerialChain.frames_expr`), the end-effector pose and the
  geometric Jacobian ``J = [J_v; J_ω]`` (6, n), world frame;
- the manipulability gradient ∇m (n,), full and translational, from the kinematic
  Hessian (:func:`~qpik.robots.manipulability.manipulability_gradient_expr`);
- the world end points of the link capsules (C, 2, 3)
  (:meth:`~qpik.robots.robot.Robot.capsule_segments_expr`);
- for a packed obstacle set (:class:`~qpik.geometry.distance.ObstacleSet`), every
  capsule–obstacle distance and witness point (:func:`~qpik.geometry.distance.set_expr`)
  and the velocity-damper rows (:meth:`Kinematics.damper_layout`): per row a height ``h``
  (m) and its rate :math:`n^T J_p(x)` (n,) with the point Jacobian of
  :meth:`~qpik.robots.chain.SerialChain.point_jacobian_expr`: joint ``j`` turns about
  :math:`z_j` through :math:`o_j`, and a point :math:`p` of link ``k`` moves with
  :math:`\dot p = \sum_{j \le k} z_j \times (p - o_j)\,\dot q_j`.

:class:`SymState` holds the same quantities as CasADi symbols: the tasks and limits write
their math once against it (``expr``); the controller traces it from the kinematics
(:meth:`SymState.of`) into one compiled function, and :func:`evaluate` runs one task's or
limit's expression on a numeric :class:`State` (:meth:`SymState.free`).
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik import symbolic as sy
from qpik.compiled import Compiled
from qpik.errors import InputError
from qpik.robots.manipulability import hessian_rows, jacobian_rows, manipulability_gradient_expr
from qpik.robots.robot import as_robot
from qpik.validate import joint_vector, number

if TYPE_CHECKING:
    from qpik.geometry.distance import Distances, ObstacleSet
    from qpik.robots.robot import Robot


class Kinematics:
    """Per-robot compiled step functions, one per tuple of obstacle kernel families.

    ``function(kinds)`` maps ``q`` (n,) [and the obstacle parameters] to one flat vector:
    pose (16, row-major), J (6n, row-major), ∇m (n), translational ∇m (n), capsule end
    points (6C), then for C capsules × O obstacles: ``[d, p_link, p_obs, n, s]`` (11 per
    pair), the R damper rows (R × n, row-major) and their heights (R) of
    :meth:`damper_layout`. Built once per robot by :func:`kinematics_of`.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.n = robot.dof
        self.n_capsules = len(robot.capsules)
        self.base_size = 16 + 8 * self.n + 6 * self.n_capsules
        self._functions: dict[tuple[str, ...], Compiled] = {}
        self._layouts: dict[tuple[str, ...], tuple[tuple[int, int, int], ...]] = {}
        self.composed: dict[tuple, tuple] = {}  # the controllers' QP functions and their libraries, by structure

    def function(self, kinds: tuple[str, ...]) -> Compiled:
        """The compiled step function for obstacles of families ``kinds`` (``()``: no obstacles)."""
        fn = self._functions.get(kinds)
        if fn is None:
            fn = self._functions[kinds] = Compiled(self._build(kinds))
        return fn

    def base_expr(self, q: ca.SX) -> tuple[list, ca.SX]:
        """``(frames, base)``: the chain's frames at ``q`` (n,) and the flat base part of the output (SX column)."""
        robot, chain, n = self.robot, self.robot.chain, self.n
        frames = chain.frames_expr([q[i] for i in range(n)], sy.CASADI)
        jv, jw = chain.jacobian_expr(frames)
        Jr, Hr = jacobian_rows(jv, jw), hessian_rows(chain.hessian_expr(frames, (jv, jw)))
        R, p = frames[-1]
        out = [*R[0], p[0], *R[1], p[1], *R[2], p[2], 0.0, 0.0, 0.0, 1.0]
        out += [x for row in Jr for x in row]
        for rows in (6, 3):
            out += manipulability_gradient_expr(Jr[:rows], [Hk[:rows] for Hk in Hr])[0]
        segments = robot.capsule_segments_expr(frames)
        out += [x for ab in segments for end in ab for x in end]
        return frames, ca.vertcat(*out)

    def damper_layout(self, kinds: tuple[str, ...]) -> tuple[tuple[int, int, int], ...]:
        r"""``(capsule, obstacle, end)`` of every velocity-damper row for obstacles of families ``kinds``.

        A pair whose distance is C¹ in q (a sphere, :data:`~qpik.geometry.distance.SMOOTH`) or whose
        link capsule is a point gets one row, ``end = -1``: the witness point :math:`p_{link}`,
        height ``h = d``. Any other pair gets two rows, ``end = 0`` and ``1``: the capsule's axis
        end points :math:`x_0 = a`, :math:`x_1 = b` against the *separating plane* of the step,
        through :math:`p_{obs}` with normal ``n``: height :math:`h_e = n^T (x_e - p_{obs}) - r`.
        The obstacle lies behind that plane and the capsule's distance to the plane is
        :math:`\min_e h_e` (an affine function of the axis point is least at an end), so
        :math:`d \ge \min_e h_e` after any motion: keeping both heights above :math:`d_s`
        keeps the capsule there, whichever feature of the obstacle is nearest next. A capsule no joint
        moves (:attr:`~qpik.robots.robot.Robot.fixed_capsules`) gets no row: its distance is a constant.
        """
        from qpik.geometry.distance import SMOOTH

        layout = self._layouts.get(kinds)
        if layout is None:
            out = []
            for c, cap in enumerate(self.robot.capsules):
                if self.robot.fixed_capsules[c]:
                    continue
                point = not np.any(np.asarray(cap.p0) != np.asarray(cap.p1))
                for o, kind in enumerate(kinds):
                    out += [(c, o, -1)] if point or kind in SMOOTH else [(c, o, 0), (c, o, 1)]
            layout = self._layouts[kinds] = tuple(out)
        return layout

    def pairs_expr(self, frames: list, kinds: tuple[str, ...], prm: ca.SX) -> ca.SX:
        """The flat pair part of the output (SX column) for obstacles ``kinds`` with parameters ``prm``."""
        from qpik.geometry.distance import set_expr

        robot, chain, n = self.robot, self.robot.chain, self.n
        segments = robot.capsule_segments_expr(frames)
        radii = robot.capsule_radii
        pairs = set_expr(segments, radii, kinds, [prm[i] for i in range(prm.numel())], sy.CASADI)
        out = [x for row in pairs for d, p_link, p_obs, nrm, s in row for x in (d, *p_link, *p_obs, *nrm, s)]
        heights = []
        for c, o, end in self.damper_layout(kinds):
            d, p_link, p_obs, nrm, _ = pairs[c][o]
            point = p_link if end < 0 else segments[c][end]
            heights.append(d if end < 0 else sy.dot(nrm, sy.vsub(point, p_obs)) - radii[c])
            link = robot.capsules[c].link
            cols = chain.point_jacobian_expr(frames, point, link)
            out += [sy.dot(nrm, col) for col in cols] + [0.0] * (n - len(cols))
        return ca.vertcat(*out, *heights)

    def pairs_size(self, kinds: tuple[str, ...]) -> int:
        """Length of :meth:`pairs_expr`'s output: 11 per pair, then n + 1 per damper row."""
        return 11 * self.n_capsules * len(kinds) + (self.n + 1) * len(self.damper_layout(kinds))

    def _build(self, kinds: tuple[str, ...]) -> ca.Function:
        from qpik.geometry.distance import PARAMS

        q = ca.SX.sym("q", self.n)
        frames, out = self.base_expr(q)
        inputs = [q]
        if kinds:
            prm = ca.SX.sym("params", sum(PARAMS[k] for k in kinds))
            inputs.append(prm)
            out = ca.vertcat(out, self.pairs_expr(frames, kinds, prm))
        name = f"step_{self.robot.identifier}_{'_'.join(kinds) or 'free'}"
        return ca.Function(name, inputs, [out])


_KIN: dict[int, Kinematics] = {}


def kinematics_of(robot: Robot) -> Kinematics:
    """The cached :class:`Kinematics` of ``robot`` (robots are immutable)."""
    k = _KIN.get(id(robot))
    if k is None or k.robot is not robot:
        k = _KIN[id(robot)] = Kinematics(robot)
    return k


class State:
    """Kinematics of one configuration, shared by the tasks and limits of one control step.

    Args:
        robot: the arm.
        q: joint positions (n,), rad.
        dt: control period, s.
        obstacles: the obstacle set evaluated with the kinematics in the same compiled
            call (others are evaluated on demand by :meth:`distances`).

    Attributes:
        q, dt: as given.
        pose: (4, 4) end-effector pose, world frame.
        J: (6, n) geometric Jacobian ``[v; ω]`` of the end-effector origin, world frame.
        segments: (C, 2, 3) world end points of every link capsule, m (order of ``robot.capsules``).

    The arrays are read-only views of one buffer owned by this state.
    """

    def __init__(self, robot: Robot, q: np.ndarray, dt: float, obstacles: ObstacleSet | None = None):
        robot = as_robot(robot)
        q, batched = joint_vector(q, robot.dof)
        if batched:
            raise InputError(f"q: expected shape ({robot.dof},), got {q.shape}")
        dt = number(dt, "dt", minimum=None)
        kin = kinematics_of(robot)
        self.kin = kin
        self.robot = robot
        self.q = q
        self.dt = dt
        n, C = kin.n, kin.n_capsules
        out = self._evaluate(obstacles)
        self.pose = out[:16].reshape(4, 4)
        self.J = out[16 : 16 + 6 * n].reshape(6, n)
        self._grad = out[16 + 6 * n : 16 + 8 * n].reshape(2, n)
        self.segments = out[16 + 8 * n : kin.base_size].reshape(C, 2, 3)
        self.base = out[: kin.base_size]  # the flat base part (the input of :class:`SymState` ``.free``)
        self._pairs: dict[int, tuple[ObstacleSet, Distances, np.ndarray, np.ndarray, np.ndarray]] = {}
        if obstacles is not None and len(obstacles):
            self._unpack(obstacles, out)

    def _evaluate(self, obstacles: ObstacleSet | None) -> np.ndarray:
        """A read-only copy of the step function's output for ``obstacles`` (None or empty: kinematics only)."""
        if obstacles is None or not len(obstacles):
            out = self.kin.function(())(self.q)[0].copy()
        else:
            out = self.kin.function(obstacles.kinds)(self.q, obstacles.params)[0].copy()
        out.flags.writeable = False
        return out

    def _unpack(
        self, obstacles: ObstacleSet, out: np.ndarray
    ) -> tuple[ObstacleSet, Distances, np.ndarray, np.ndarray, np.ndarray]:
        from qpik.geometry.distance import Distances

        C, O, base, n = self.kin.n_capsules, len(obstacles), self.kin.base_size, self.kin.n
        R = len(self.kin.damper_layout(obstacles.kinds))
        pairs = out[base : base + 11 * C * O].reshape(C, O, 11)
        dist = Distances(
            d=pairs[..., 0], p_link=pairs[..., 1:4], p_obs=pairs[..., 4:7], normal=pairs[..., 7:10], s=pairs[..., 10]
        )
        start = base + 11 * C * O
        rows, heights = out[start : start + R * n].reshape(R, n), out[start + R * n :]
        entry = self._pairs[id(obstacles)] = (obstacles, dist, rows, heights, out[base:])
        return entry

    def _entry(self, obstacles: ObstacleSet) -> tuple[ObstacleSet, Distances, np.ndarray, np.ndarray, np.ndarray]:
        entry = self._pairs.get(id(obstacles))
        if entry is None or entry[0] is not obstacles:
            entry = self._unpack(obstacles, self._evaluate(obstacles))
        return entry

    def manipulability_gradient(self, translational: bool = False) -> np.ndarray:
        """∇m (n,), per rad, of Yoshikawa's index (``translational``: of J_v only)."""
        return self._grad[int(translational)]

    def distances(self, obstacles: ObstacleSet) -> Distances:
        """Capsule–obstacle distances and witness points (C, O) of a packed obstacle set, world frame."""
        return self._entry(obstacles)[1]

    def damper_rows(self, obstacles: ObstacleSet) -> np.ndarray:
        r"""Rows :math:`n^T J_p(x)` (R, n) in the order of :meth:`Kinematics.damper_layout`.

        ``n`` is the pair's unit normal (:meth:`distances`) and ``x`` the row's point on the
        capsule (the witness point or an axis end); ``J_p`` is the point Jacobian of the
        capsule's link (zero columns for the joints beyond it), so the row is the rate
        :math:`\dot h` of the row's height (:meth:`damper_heights`) per unit ``v``.
        """
        return self._entry(obstacles)[2]

    def damper_heights(self, obstacles: ObstacleSet) -> np.ndarray:
        """Heights h (R,), m, of the damper rows (:meth:`Kinematics.damper_layout`): each is ≥ the pair's d."""
        return self._entry(obstacles)[3]

    def pairs(self, obstacles: ObstacleSet) -> np.ndarray:
        """The flat pair part of the step output for ``obstacles`` (the input of :class:`SymState` ``.free``)."""
        return self._entry(obstacles)[4]


_TOKENS = itertools.count()


def _unique(owner) -> int:
    """A number unique to ``owner`` for the life of the process (unlike ``id``, never reused)."""
    token = owner.__dict__.get("_token")
    if token is None:
        token = owner.__dict__["_token"] = next(_TOKENS)
    return token


def _rows(v: ca.SX, r: int, c: int) -> ca.SX:
    """The (r, c) matrix stored row-major in the SX column ``v``."""
    return ca.reshape(v, c, r).T


class SymState:
    """The quantities of :class:`State` as CasADi SX, for the tasks' and limits' ``expr``.

    Either traced from the kinematics (:meth:`of`, what the controller compiles) or free
    symbols standing for a numeric :class:`State` (:meth:`free`, to evaluate one task or
    limit: :func:`evaluate`). Tasks and limits declare their own parameters with
    :meth:`parameter`; they become inputs of the function, so changing them never recompiles.

    Attributes:
        q: (n,) joint positions, rad; dt: control period, s (both SX).
        pose: (4, 4) end-effector pose; J: (6, n) geometric Jacobian ``[v; ω]`` (SX, world frame).
        inputs: ``[(symbol, value)]`` of every input beyond ``q``: ``value(state)`` gives its
            numbers (state: a numeric :class:`State` or None in the controller).
    """

    def __init__(self, kin: Kinematics, q: ca.SX, dt: ca.SX, base: ca.SX, pairs_of):
        n = kin.n
        self.kin, self.q, self.dt, self.n = kin, q, dt, n
        self.pose = _rows(base[:16], 4, 4)
        self.J = _rows(base[16 : 16 + 6 * n], 6, n)
        self._grad = (base[16 + 6 * n : 16 + 7 * n], base[16 + 7 * n : 16 + 8 * n])
        self._pairs_of = pairs_of
        self._pairs: dict[int, tuple[ObstacleSet, ca.SX]] = {}
        self.inputs: list = []
        self._owned: dict[int, ca.SX] = {}

    @classmethod
    def of(cls, kin: Kinematics, q: ca.SX, dt: ca.SX, trace: bool = True) -> SymState:
        """Traced from the kinematics at ``q`` (obstacle parameters become inputs).

        ``trace=False`` stands free symbols in for the kinematics: the same inputs are
        declared in the same order, at a fraction of the cost (to bind a cached function).
        """
        if trace:
            frames, base = kin.base_expr(q)
        else:
            base = ca.SX.sym("base", kin.base_size)

        def pairs_of(s: SymState, obstacles: ObstacleSet) -> ca.SX:
            prm = s.parameter(len(obstacles.params), lambda state: obstacles.params)
            if trace:
                return kin.pairs_expr(frames, obstacles.kinds, prm)
            return ca.SX.sym("pairs", kin.pairs_size(obstacles.kinds))

        return cls(kin, q, dt, base, pairs_of)

    @classmethod
    def free(cls, kin: Kinematics) -> SymState:
        """Free symbols for a numeric :class:`State` (inputs ``q``, dt, base and pairs)."""
        base = ca.SX.sym("base", kin.base_size)

        def pairs_of(s: SymState, obstacles: ObstacleSet) -> ca.SX:
            return s.parameter(kin.pairs_size(obstacles.kinds), lambda state: state.pairs(obstacles))

        s = cls(kin, ca.SX.sym("q", kin.n), ca.SX.sym("dt"), base, pairs_of)
        s.inputs += [(s.q, lambda state: state.q), (s.dt, lambda state: state.dt), (base, lambda state: state.base)]
        return s

    def parameter(self, size: int, value) -> ca.SX:
        """A new input of ``size`` numbers, ``value(state)`` giving them (state: numeric State or None)."""
        sym = ca.SX.sym(f"p{len(self.inputs)}", size)
        self.inputs.append((sym, value))
        return sym

    def params_of(self, owner) -> ca.SX:
        """The parameters of a task or limit (``param_size``, ``params()``) as an input, declared once per owner."""
        sym = self._owned.get(id(owner))
        if sym is None:
            sym = self._owned[id(owner)] = self.parameter(owner.param_size(self.n), lambda state: owner.params())
        return sym

    def manipulability_gradient(self, translational: bool = False) -> ca.SX:
        """∇m (n,) as in :meth:`State.manipulability_gradient`."""
        return self._grad[int(translational)]

    def _entry(self, obstacles: ObstacleSet) -> ca.SX:
        entry = self._pairs.get(id(obstacles))
        if entry is None or entry[0] is not obstacles:
            entry = self._pairs[id(obstacles)] = (obstacles, self._pairs_of(self, obstacles))
        return entry[1]

    def distances(self, obstacles: ObstacleSet) -> ca.SX:
        """Signed distances d (C·O,), pair ``(c, o)`` at ``c·O + o``, m."""
        C, O = self.kin.n_capsules, len(obstacles)
        return self._entry(obstacles)[0 : 11 * C * O : 11]

    def damper_rows(self, obstacles: ObstacleSet) -> ca.SX:
        """Rows (R, n) as in :meth:`State.damper_rows`."""
        start, R = 11 * self.kin.n_capsules * len(obstacles), len(self.kin.damper_layout(obstacles.kinds))
        return _rows(self._entry(obstacles)[start : start + R * self.n], R, self.n)

    def damper_heights(self, obstacles: ObstacleSet) -> ca.SX:
        """Heights (R,) as in :meth:`State.damper_heights`, m."""
        start, R = 11 * self.kin.n_capsules * len(obstacles), len(self.kin.damper_layout(obstacles.kinds))
        return self._entry(obstacles)[start + R * self.n : start + R * (self.n + 1)]


def evaluate(owner, state: State, build, *extra: np.ndarray) -> list[np.ndarray]:
    """Evaluate ``build(s, *x)`` (a list of SX outputs) at a numeric ``state`` and ``extra`` vectors.

    ``s`` is a :meth:`SymState.free` state and ``x`` symbols for the ``extra`` arrays. The
    CasADi function is cached on ``owner`` per robot and builder (``owner._numeric``): the one
    implementation of a task or limit's math is its ``expr``, evaluated here on numbers.
    """
    cache = owner.__dict__.setdefault("_numeric", {})
    key = (id(state.kin), build.__code__, tuple(len(x) for x in extra))
    entry = cache.get(key)
    if entry is None or entry[0] is not state.kin:
        s = SymState.free(state.kin)
        syms = [ca.SX.sym(f"x{i}", len(x)) for i, x in enumerate(extra)]
        outs = build(s, *syms)
        fn = ca.Function("evaluate", [sym for sym, _ in s.inputs] + syms, outs)
        entry = cache[key] = (state.kin, fn, [value for _, value in s.inputs])
    _, fn, values = entry
    return [np.asarray(x) for x in fn.call([value(state) for value in values] + list(extra))]
