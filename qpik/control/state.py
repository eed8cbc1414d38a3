r"""The kinematic state of one control step, computed once and shared by every task and limit.

:class:`State` evaluates, for a configuration ``q`` and the obstacles of the controller,
ONE natively compiled CasADi function (:class:`Kinematics`, :mod:`qpik.native.compiled`) traced
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

from qpik.algebra import symbolic as sy
from qpik.control.inputs import Constant, Input, Owned
from qpik.core.errors import InputError
from qpik.core.layout import Blocks, Layout
from qpik.core.validate import joint_vector, number
from qpik.native.compiled import Compiled
from qpik.robots.manipulability import hessian_rows, jacobian_rows, manipulability_gradient_expr
from qpik.robots.robot import as_robot

if TYPE_CHECKING:
    from qpik.geometry.distance import Distances, ObstacleSet
    from qpik.robots.robot import Robot


class Kinematics:
    """Per-robot compiled step functions, one per tuple of obstacle kernel families.

    ``function(kinds)`` maps ``q`` (n,) [and the obstacle parameters] to one flat vector laid out by
    :meth:`layout`: the :attr:`base` part (pose (4, 4), J (6, n), ∇m and translational ∇m (2, n), capsule
    end points (C, 2, 3)), then with obstacles the :meth:`pair_layout` part (for C capsules × O obstacles
    one :data:`~qpik.geometry.distance.PAIR` record each, the R damper rows (R, n) and their heights (R,)
    of :meth:`damper_layout`). Built once per robot by :func:`kinematics_of`.

    Attributes:
        base: the :class:`~qpik.core.layout.Layout` of the part without obstacles.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.n = robot.dof
        self.n_capsules = len(robot.capsules)
        self.base = Layout(pose=(4, 4), J=(6, self.n), grad=(2, self.n), segments=(self.n_capsules, 2, 3))
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
        pose = [[*R[i], p[i]] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
        grad = [manipulability_gradient_expr(Jr[:rows], [Hk[:rows] for Hk in Hr])[0] for rows in (6, 3)]
        segments = robot.capsule_segments_expr(frames)
        return frames, self.base.pack(pose=pose, J=Jr, grad=grad, segments=segments)

    def pair_layout(self, kinds: tuple[str, ...]) -> Layout:
        """The layout of the part for obstacles of families ``kinds``: ``pairs`` (C, O, PAIR.size), ``rows``
        (R, n) and ``heights`` (R,) of :meth:`damper_layout`."""
        from qpik.geometry.distance import PAIR

        R = len(self.damper_layout(kinds))
        return Layout(pairs=(self.n_capsules, len(kinds), PAIR.size), rows=(R, self.n), heights=R)

    def layout(self, kinds: tuple[str, ...]) -> Layout:
        """The layout of :meth:`function`'s output: ``base`` (:attr:`base`) and, with obstacles, ``pairs``
        (:meth:`pair_layout`)."""
        return Layout(base=self.base, pairs=self.pair_layout(kinds)) if kinds else Layout(base=self.base)

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
        from qpik.geometry.distance import pair_record, set_expr

        robot, chain, n = self.robot, self.robot.chain, self.n
        segments = robot.capsule_segments_expr(frames)
        radii = robot.capsule_radii
        pairs = set_expr(segments, radii, kinds, [prm[i] for i in range(prm.numel())], sy.CASADI)
        heights, rows = [], []
        for c, o, end in self.damper_layout(kinds):
            d, p_link, p_obs, nrm, _ = pairs[c][o]
            point = p_link if end < 0 else segments[c][end]
            heights.append(d if end < 0 else sy.dot(nrm, sy.vsub(point, p_obs)) - radii[c])
            link = robot.capsules[c].link
            cols = chain.point_jacobian_expr(frames, point, link)
            rows.append([sy.dot(nrm, col) for col in cols] + [0.0] * (n - len(cols)))
        records = [pair_record(pair) for row in pairs for pair in row]
        return self.pair_layout(kinds).pack(pairs=records, rows=rows, heights=heights)

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


def kinematics_of(robot: Robot) -> Kinematics:
    """The :class:`Kinematics` of ``robot``, built once (``robot.cache``)."""
    return robot.cache.get("control kinematics", Kinematics, robot)


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
        out = self._evaluate(obstacles)
        base = kin.base.views(out.base)
        self.pose, self.J, self._grad, self.segments = base.pose, base.J, base.grad, base.segments
        self.base = out.base  # the flat base part (the input of :class:`SymState` ``.free``)
        self._pairs: dict[ObstacleSet, Blocks] = {}
        if obstacles is not None and len(obstacles):
            self._pairs[obstacles] = out

    def _evaluate(self, obstacles: ObstacleSet | None) -> Blocks:
        """The step function's output for ``obstacles`` (None or empty: kinematics only), read-only, by
        :meth:`Kinematics.layout`; its ``pairs`` block as :meth:`Kinematics.pair_layout`'s blocks, with the
        distances as :class:`~qpik.geometry.distance.Distances` and the flat part as ``flat``."""
        from qpik.geometry.distance import PAIR, Distances

        kinds = () if obstacles is None else obstacles.kinds
        out = self.kin.function(kinds)(self.q, obstacles.params)[0] if kinds else self.kin.function(())(self.q)[0]
        out = out.copy()
        out.flags.writeable = False
        blocks = dict(self.kin.layout(kinds).views(out))
        if kinds:
            pairs = dict(self.kin.pair_layout(kinds).views(blocks["pairs"]))
            pairs["distances"], pairs["flat"] = Distances(**PAIR.views(pairs["pairs"])), blocks["pairs"]
            blocks["pairs"] = Blocks(pairs)
        return Blocks(blocks)

    def _entry(self, obstacles: ObstacleSet) -> Blocks:
        """The pair part for ``obstacles``: ``distances``, ``rows``, ``heights`` and ``flat``."""
        out = self._pairs.get(obstacles)
        if out is None:
            out = self._pairs[obstacles] = self._evaluate(obstacles)
        return out.pairs

    def manipulability_gradient(self, translational: bool = False) -> np.ndarray:
        """∇m (n,), per rad, of Yoshikawa's index (``translational``: of J_v only)."""
        return self._grad[int(translational)]

    def distances(self, obstacles: ObstacleSet) -> Distances:
        """Capsule–obstacle distances and witness points (C, O) of a packed obstacle set, world frame."""
        return self._entry(obstacles).distances

    def damper_rows(self, obstacles: ObstacleSet) -> np.ndarray:
        r"""Rows :math:`n^T J_p(x)` (R, n) in the order of :meth:`Kinematics.damper_layout`.

        ``n`` is the pair's unit normal (:meth:`distances`) and ``x`` the row's point on the
        capsule (the witness point or an axis end); ``J_p`` is the point Jacobian of the
        capsule's link (zero columns for the joints beyond it), so the row is the rate
        :math:`\dot h` of the row's height (:meth:`damper_heights`) per unit ``v``.
        """
        return self._entry(obstacles).rows

    def damper_heights(self, obstacles: ObstacleSet) -> np.ndarray:
        """Heights h (R,), m, of the damper rows (:meth:`Kinematics.damper_layout`): each is ≥ the pair's d."""
        return self._entry(obstacles).heights

    def pairs(self, obstacles: ObstacleSet) -> np.ndarray:
        """The flat pair part of the step output for ``obstacles`` (the input of :class:`SymState` ``.free``)."""
        return self._entry(obstacles).flat


_TOKENS = itertools.count()


class Traced:
    """The base of tasks and limits: math written once as a CasADi expression of a :class:`SymState` and of
    named parameters.

    Attributes:
        token: a number unique to this object for the life of the process (unlike ``id``, never reused).
        evaluators: this object's expressions compiled for numeric states (:func:`evaluate`), by kinematics.
    """

    def __new__(cls, *args: object, **kwargs: object):
        self = super().__new__(cls)
        self.token = next(_TOKENS)
        self.evaluators = {}
        return self

    def param_layout(self, n: int) -> Layout:
        """The parameters' layout for an arm with n joints (default: none)."""
        return Layout()

    def param_values(self) -> dict[str, object]:
        """The current parameters by name (numbers or arrays of :meth:`param_layout`'s shapes)."""
        return {}

    def structure(self) -> tuple:
        """What fixes the expression's form beyond the parameters (part of the compiled function's key).

        The default is unique to this object (its compiled function is never shared);
        subclasses whose form depends only on their parameters return ``()``.
        """
        return (self.token,)


class SymState:
    """The quantities of :class:`State` as CasADi SX, for the tasks' and limits' ``expr``.

    Either traced from the kinematics (:meth:`of`, what the controller compiles) or free
    symbols standing for a numeric :class:`State` (:meth:`free`, to evaluate one task or
    limit: :func:`evaluate`). Tasks and limits declare their own parameters with
    :meth:`parameter`; they become inputs of the function, so changing them never recompiles.

    Attributes:
        q: (n,) joint positions, rad; dt: control period, s (both SX).
        pose: (4, 4) end-effector pose; J: (6, n) geometric Jacobian ``[v; ω]`` (SX, world frame).
        inputs: every input beyond ``q`` (:class:`~qpik.control.inputs.Input` s: a symbol and how its numbers
            are found), in order.
        caps: ``(lo, hi)`` (n,) SX, the box of the cap limits alone (velocity, acceleration, jerk), which
            every command must stay in; set by the controller's assembler before the rows (None elsewhere).
    """

    def __init__(self, kin: Kinematics, q: ca.SX, dt: ca.SX, base: ca.SX, pairs_of):
        self.kin, self.q, self.dt, self.n = kin, q, dt, kin.n
        blocks = kin.base.symbols(base)
        self.pose, self.J = blocks.pose, blocks.J
        self._grad = (blocks.grad[0, :].T, blocks.grad[1, :].T)
        self._pairs_of = pairs_of
        self._pairs: dict[ObstacleSet, Blocks] = {}
        self.inputs: list[Input] = []
        self.caps: tuple[ca.SX, ca.SX] | None = None  # the caps' own box (n,) each, set by the assembler
        self._owned: dict[int, Blocks] = {}
        self.packed: dict[ObstacleSet, ca.SX] = {}  # the obstacles' packed parameters, where declared

    @classmethod
    def of(cls, kin: Kinematics, q: ca.SX, dt: ca.SX, trace: bool = True) -> SymState:
        """Traced from the kinematics at ``q`` (obstacle parameters become inputs).

        ``trace=False`` stands free symbols in for the kinematics: the same inputs are
        declared in the same order, at a fraction of the cost (to bind a cached function).
        """
        if trace:
            frames, base = kin.base_expr(q)
        else:
            base = ca.SX.sym("base", kin.base.size)

        def pairs_of(s: SymState, obstacles: ObstacleSet) -> ca.SX:
            prm = s.parameter(len(obstacles.params), lambda state: obstacles.params)
            s.packed[obstacles] = prm
            if trace:
                return kin.pairs_expr(frames, obstacles.kinds, prm)
            return ca.SX.sym("pairs", kin.pair_layout(obstacles.kinds).size)

        return cls(kin, q, dt, base, pairs_of)

    @classmethod
    def free(cls, kin: Kinematics) -> SymState:
        """Free symbols for a numeric :class:`State` (inputs ``q``, dt, base and pairs)."""
        base = ca.SX.sym("base", kin.base.size)

        def pairs_of(s: SymState, obstacles: ObstacleSet) -> ca.SX:
            return s.parameter(kin.pair_layout(obstacles.kinds).size, lambda state: state.pairs(obstacles))

        s = cls(kin, ca.SX.sym("q", kin.n), ca.SX.sym("dt"), base, pairs_of)
        s.inputs += [Input(s.q, lambda state: state.q), Input(s.dt, lambda state: state.dt),
                     Input(base, lambda state: state.base)]  # fmt: skip
        return s

    def parameter(self, size: int, value) -> ca.SX:
        """A new input of ``size`` numbers, ``value(state)`` giving them at every call (state: numeric State or
        None)."""
        sym = ca.SX.sym(f"p{len(self.inputs)}", size)
        self.inputs.append(Input(sym, value))
        return sym

    def constant(self, numbers: np.ndarray) -> ca.SX:
        """A new input whose numbers are ``numbers`` (a vector, copied) at every call."""
        sym = ca.SX.sym(f"p{len(self.inputs)}", np.size(numbers))
        self.inputs.append(Constant(sym, numbers))
        return sym

    def params_of(self, owner: Traced) -> Blocks:
        """The parameters of a task or limit as an input (SX blocks of its ``param_layout``, by name), declared
        once per owner; their numbers are read from ``param_values()`` at every call."""
        blocks = self._owned.get(owner.token)
        if blocks is None:
            layout = owner.param_layout(self.n)
            sym = ca.SX.sym(f"p{len(self.inputs)}", layout.size)
            self.inputs.append(Owned(sym, owner, layout))
            blocks = self._owned[owner.token] = layout.symbols(sym)
        return blocks

    def manipulability_gradient(self, translational: bool = False) -> ca.SX:
        """∇m (n,) as in :meth:`State.manipulability_gradient`."""
        return self._grad[int(translational)]

    def _entry(self, obstacles: ObstacleSet) -> Blocks:
        """The pair part for ``obstacles`` as SX blocks of :meth:`Kinematics.pair_layout`."""
        blocks = self._pairs.get(obstacles)
        if blocks is None:
            flat = self._pairs_of(self, obstacles)
            blocks = self._pairs[obstacles] = self.kin.pair_layout(obstacles.kinds).symbols(flat)
        return blocks

    def distances(self, obstacles: ObstacleSet) -> ca.SX:
        """Signed distances d (C·O,), pair ``(c, o)`` at ``c·O + o``, m."""
        from qpik.geometry.distance import PAIR

        pairs = self._entry(obstacles).pairs
        return PAIR.symbols(pairs, count=pairs.numel() // PAIR.size).d

    def witnesses(self, obstacles: ObstacleSet) -> Blocks:
        """Every pair's :data:`~qpik.geometry.distance.PAIR` fields, pair ``(c, o)`` at record ``k = c·O + o``: each
        field one column record by record (``normal[3k : 3k + 3]``: unit normal from the obstacle to the capsule)."""
        from qpik.geometry.distance import PAIR

        pairs = self._entry(obstacles).pairs
        return PAIR.symbols(pairs, count=pairs.numel() // PAIR.size)

    def obstacle_params(self, obstacles: ObstacleSet) -> ca.SX:
        """The packed parameters of ``obstacles`` (:attr:`~qpik.geometry.distance.ObstacleSet.params`) as an input."""
        self._entry(obstacles)
        prm = self.packed.get(obstacles)
        if prm is None:
            prm = self.packed[obstacles] = self.parameter(len(obstacles.params), lambda state: obstacles.params)
        return prm

    def damper_rows(self, obstacles: ObstacleSet) -> ca.SX:
        """Rows (R, n) as in :meth:`State.damper_rows`."""
        return self._entry(obstacles).rows

    def damper_heights(self, obstacles: ObstacleSet) -> ca.SX:
        """Heights (R,) as in :meth:`State.damper_heights`, m."""
        return self._entry(obstacles).heights


def evaluate(owner, state: State, build, *extra: np.ndarray) -> list[np.ndarray]:
    """Evaluate ``build(s, *x)`` (a list of SX outputs) at a numeric ``state`` and ``extra`` vectors.

    ``s`` is a :meth:`SymState.free` state and ``x`` symbols for the ``extra`` arrays. The
    CasADi function is kept in ``owner.evaluators`` per kinematics and builder: the one
    implementation of a task or limit's math is its ``expr``, evaluated here on numbers.
    """
    key = (state.kin, build.__code__, tuple(len(x) for x in extra))
    entry = owner.evaluators.get(key)
    if entry is None:
        s = SymState.free(state.kin)
        syms = [ca.SX.sym(f"x{i}", len(x)) for i, x in enumerate(extra)]
        outs = build(s, *syms)
        fn = ca.Function("evaluate", [inp.symbol for inp in s.inputs] + syms, outs)
        entry = owner.evaluators[key] = (fn, [inp.value for inp in s.inputs])
    fn, values = entry
    return [np.asarray(x) for x in fn.call([value(state) for value in values] + list(extra))]
