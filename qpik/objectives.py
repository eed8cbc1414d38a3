r"""Objectives over a configuration ``q`` (n,), rad: one CasADi expression each, composable.

Shared by the NLPs (:mod:`qpik.nlp`: minimised over δ/ψ or over q) and the QP controller
(:class:`qpik.control.tasks.ObjectiveTask`: its gradient as a secondary task). Every
objective is a cost to *minimise*; :class:`Sum` adds them with weights (``2.0 * a + b``).

An objective writes its math once, :meth:`Objective.split`, against a :class:`Context` of
CasADi symbols (``q``, the robot's frames and Jacobian, the link-capsule/obstacle distances,
the reference configuration ``q_ref``) and its own parameter vector (weights, sharpness,
cap). Parameters, ``q_ref`` and the obstacle geometry are *inputs* of the compiled
functions, so changing them never recompiles. A split is a smooth part plus weighted maxima
of smooth pieces,

.. math:: f(q) = s(q) + \sum_k w_k \max_i h_{k,i}(q),\qquad w_k \ge 0,

so that an NLP can write each maximum in epigraph form (:math:`\min t_k` s.t.
:math:`t_k \ge h_{k,i}`) and stay smooth, and so that the certificate of :mod:`qpik.nlp.certificate`
can bound f over a range of configurations from Taylor models of s and of every piece
(:class:`BoundFunction`).

The objectives (units: the margin is unitless, distances in m, angles in rad):

- :class:`JointLimitMargin`: :math:`-\min_j \min(q_j - l_j, u_j - q_j)/\rho_j`,
  :math:`\rho_j = (u_j - l_j)/2` (0 on a limit, −1 at the middle of every range); epigraph
  form, or with ``smooth=True`` the soft minimum :math:`\tfrac1\beta\log\sum_i e^{-\beta g_i}`
  of the same 2n normalised distances :math:`g_i`;
- :class:`Manipulability`: :math:`-\log m(q)`, Yoshikawa's :math:`m = \sqrt{\det J J^T}`
  (``translational``: :math:`J_v`);
- :class:`Clearance`: :math:`-\min(c, \min_{k,o} d_{k,o}(q))` over every (link capsule k,
  obstacle o) pair, capped at ``cap`` = c (m); epigraph form or the soft minimum;
- :class:`ReferenceDistance`: :math:`\tfrac12 \sum_j w_j (q_j - q_{ref,j})^2`;
- :class:`Expression`: a user's CasADi expression of q.

What a person reads is the measured quantity, not the cost: each objective's
:attr:`Objective.quantity` (:class:`Quantity`) turns the minimised value f into it — the margin
:math:`-f` (maximised), the clearance :math:`-f` in m (maximised), the manipulability
:math:`e^{-f}` (maximised), the distance to q_ref f itself (minimised); a weighted sum of several
terms or a user's expression is shown as the objective f, minimised.
"""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache, cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik import symbolic as sy
from qpik.build import concurrently
from qpik.compiled import RowMap
from qpik.core.layout import Layout
from qpik.enclosure import taylor_function
from qpik.errors import InputError
from qpik.geometry.distance import PARAMS, ObstacleSet, axis_distance, distances, set_expr
from qpik.robots.manipulability import hessian_rows, jacobian_rows, manipulability_gradient_expr
from qpik.validate import finite_array, flag, number

if TYPE_CHECKING:
    from qpik.robots.robot import Robot

_EMPTY = np.zeros(0)
_TOKENS = itertools.count()


@dataclass
class Split:
    r"""An objective as :math:`s + \sum_k w_k \max(h_k)` (SX).

    Attributes:
        smooth: the smooth part s, a scalar.
        maxima: ``(w_k, h_k)``: a weight (scalar, ≥ 0) and the pieces (m_k,) of each maximum.
    """

    smooth: ca.SX
    maxima: list[tuple[ca.SX, ca.SX]] = field(default_factory=list)

    def value(self) -> ca.SX:
        """:math:`s + \\sum_k w_k \\max(h_k)`."""
        out = self.smooth
        for w, h in self.maxima:
            out = out + w * ca.mmax(h)
        return out

    def epigraph(self) -> tuple[ca.SX, ca.SX, ca.SX]:
        """The epigraph form: ``(t, cost, g)`` with new variables t (K,), the smooth cost
        :math:`s + \\sum_k w_k t_k` and the constraints ``g ≤ 0``, :math:`h_{k,i} - t_k` stacked."""
        t = ca.SX.sym("t", len(self.maxima))
        cost = self.smooth
        g = [ca.SX(0, 1)]
        for k, (w, h) in enumerate(self.maxima):
            cost = cost + w * t[k]
            g.append(h - t[k])
        return t, cost, ca.vertcat(*g)


def _same(f: np.ndarray) -> np.ndarray:
    return f


def _negated(f: np.ndarray) -> np.ndarray:
    return -f


def _exp_negated(f: np.ndarray) -> np.ndarray:
    return np.exp(-f)


@dataclass(frozen=True)
class Quantity:
    """How an objective's value is shown to a person: the quantity it measures, in its own sense.

    The solvers minimise f; :meth:`value` is the measured quantity (the margin for f = −margin, the
    manipulability m for f = −log m, f itself for a quantity that is minimised).

    Attributes:
        name: what the number is (``"margin"``, ``"clearance"``, ``"objective"``, ...).
        unit: its unit (``""``: unitless).
        maximised: whether the best value is the largest.
        minimised: what qpik minimises to maximise it (``"−margin"``), ``""`` when it minimises the quantity itself.
        meaning: what it measures, in words (``""`` when the name says it).
        of: the quantity from the minimised value f (numpy, elementwise).
    """

    name: str
    unit: str = ""
    maximised: bool = False
    minimised: str = ""
    meaning: str = ""
    of: Callable[[np.ndarray], np.ndarray] = _same

    def value(self, f: float | np.ndarray) -> float | np.ndarray:
        """The quantity at the minimised value(s) f (a float for a number, an array for an array)."""
        out = self.of(np.asarray(f, dtype=float))
        return float(out) if np.ndim(out) == 0 else out

    @property
    def header(self) -> str:
        """A table column's title: the name and unit (``"clearance [m]"``)."""
        return self.name + (f" [{self.unit}]" if self.unit else "")

    @property
    def sense(self) -> str:
        """``"maximised (qpik minimises −margin)"`` or ``"minimised"``."""
        if not self.maximised:
            return "minimised"
        return "maximised" + (f" (qpik minimises {self.minimised})" if self.minimised else "")

    @property
    def label(self) -> str:
        """An axis label: the header and the sense (``"margin, maximised (qpik minimises −margin)"``)."""
        return f"{self.header}, {self.sense}"

    @property
    def goal(self) -> str:
        """What a solve asks for, in words: ``"maximise the margin (the smallest ...; qpik minimises −margin)"``."""
        verb = "maximise" if self.maximised else "minimise"
        notes = [x for x in (self.meaning, f"qpik minimises {self.minimised}" if self.minimised else "") if x]
        return f"{verb} the {self.name}" + (f" ({'; '.join(notes)})" if notes else "")

    def text(self, f: float, spec: str = ".6g") -> str:
        """``"margin 0.377787"``, ``"clearance 0.0421 m"``: the quantity at the minimised value f, with its unit."""
        return f"{self.name} {format(self.value(f), spec)}" + (f" {self.unit}" if self.unit else "")

    def scaled(self, weight: float) -> Quantity:
        """The quantity of ``weight`` × the objective (weight > 0): the same quantity, read from f / weight."""
        inner, w = self.of, float(weight)
        what = self.minimised or self.name
        return Quantity(self.name, self.unit, self.maximised, f"{w:g} × ({what})" if w != 1.0 else self.minimised,
                        self.meaning, lambda f: inner(f / w))  # fmt: skip


def pair_count(robot: Robot, obstacles: Sequence | ObstacleSet) -> int:
    """C'·O: the capsule–obstacle pairs of :attr:`Context.distances`, those of the capsules a joint moves."""
    return int(np.count_nonzero(~robot.fixed_capsules)) * len(obstacles)


def clearance(robot: Robot, q: np.ndarray, obstacles: Sequence | ObstacleSet) -> np.ndarray:
    """(M,) the smallest distance of the pairs of :attr:`Context.distances` at configurations q (M, n), m
    (numpy; inf without pairs)."""
    moving = ~robot.fixed_capsules
    if not pair_count(robot, obstacles):
        return np.full(len(q), np.inf)
    d = distances(robot.capsule_segments(q)[:, moving], robot.capsule_radii[moving], obstacles).d
    return d.reshape(len(q), -1).min(axis=1)


class Context:
    """The symbols an objective is written against (CasADi SX).

    Args:
        robot: the arm.
        q: (n,) joint positions, rad.
        q_ref: (n,) reference configuration, rad (an input of the compiled function).
        obstacles: the obstacles of the problem (their families fix the expression's form).
        obstacle_params: their packed parameters (:attr:`ObstacleSet.params`), an input.
        witness: (n,) a second symbol for q, or None; see :attr:`distances`.
        distances: (C'·O,) symbols standing for :attr:`distances`, or None (then they are built from q):
            an objective's split written against them is a function of q and the distances.

    The kinematics are built on first use, so an objective that needs none costs nothing.
    """

    def __init__(
        self,
        robot: Robot,
        q: ca.SX,
        q_ref: ca.SX,
        obstacles: ObstacleSet,
        obstacle_params: ca.SX,
        witness: ca.SX | None = None,
        distances: ca.SX | None = None,
    ):
        self.robot, self.q, self.q_ref = robot, q, q_ref
        self.obstacles, self.obstacle_params, self.witness = obstacles, obstacle_params, witness
        self.n = robot.dof
        self._given_distances = distances

    @cached_property
    def frames(self) -> list:
        """The chain's frames ``[base, frame_1..frame_n, ee]`` (:meth:`DHChain.frames_expr`)."""
        return self.robot.chain.frames_expr([self.q[i] for i in range(self.n)], sy.CASADI)

    @cached_property
    def _jacobian(self) -> tuple[list, list]:
        chain = self.robot.chain
        jv, jw = chain.jacobian_expr(self.frames)
        return jacobian_rows(jv, jw), hessian_rows(chain.hessian_expr(self.frames, (jv, jw)))

    def manipulability(self, translational: bool = False) -> ca.SX:
        """Yoshikawa's :math:`\\sqrt{\\det J J^T}` (``translational``: of J_v), from the QR of
        :func:`~qpik.robots.dh.manipulability_gradient_expr`."""
        J, H = self._jacobian
        rows = 3 if translational else 6
        return manipulability_gradient_expr(J[:rows], [Hk[:rows] for Hk in H])[1]

    @cached_property
    def distances(self) -> ca.SX:
        r"""Signed distances (C'·O,) of the pairs of the C' capsules a joint moves (:func:`pair_count`), m.

        Pair (c, o) is at k·O + o with k the rank of capsule c among those that are not
        :attr:`~qpik.robots.robot.Robot.fixed_capsules`: a fixed capsule's distance is a constant no
        configuration changes (the base column standing on a table), so it constrains nothing.

        With a ``witness`` symbol w, the closest points are found at w and the distance is
        written :math:`n^T(x_s(q) - p_{obs}) - r` with the unit normal n, the obstacle's witness
        point and the capsule-axis parameter s taken at w, and :math:`x_s(q)` the axis point at q.
        At w = q this equals the distance, and (Danskin's theorem) its gradient in q is the
        gradient of the distance, :math:`n^T J_p` (:mod:`qpik.geometry.distance`), at a fraction of
        the cost of differentiating the closest-point kernels; substitute w = q after differentiating.
        Exact wherever the closest points are unique, which holds for every pair clear of its
        obstacle; for a capsule axis inside a box it is the rate of the deepest point's depth
        with that point held (the kernel's own normal), not a derivative of the depth.
        """
        if self._given_distances is not None:
            return self._given_distances
        if not len(self.obstacles):
            return ca.SX(0, 1)
        prm = [self.obstacle_params[i] for i in range(self.obstacle_params.numel())]
        moving = np.flatnonzero(~self.robot.fixed_capsules)
        radii, kinds = self.robot.capsule_radii[moving], self.obstacles.kinds
        at = self.frames if self.witness is None else self._frames_of(self.witness)
        segments = self.robot.capsule_segments_expr(at)
        pairs = set_expr([segments[c] for c in moving], radii, kinds, prm, sy.CASADI)
        if self.witness is None:
            return ca.vertcat(*[d for row in pairs for d, *_ in row])
        out = []
        segments = self.robot.capsule_segments_expr(self.frames)
        for (a, b), r, row in zip([segments[c] for c in moving], radii, pairs):
            for _, _, p_obs, normal, s in row:
                x = sy.vadd(a, sy.vscale(s, sy.vsub(b, a)))
                out.append(sy.dot(normal, sy.vsub(x, p_obs)) - r)
        return ca.vertcat(*out)

    def _frames_of(self, q: ca.SX) -> list:
        return self.robot.chain.frames_expr([q[i] for i in range(self.n)], sy.CASADI)


class Objective(ABC):
    """A cost :math:`f(q)` to minimise (see the module docstring for the form).

    Subclasses implement :meth:`split`. Combine them with ``*`` (a weight) and ``+``.
    """

    name: str = "objective"
    bounded: bool = True
    """Whether the certificate bounds it (:class:`BoundFunction`); False where the Taylor models are too
    loose to prove anything at a useful cell width."""
    __array_ufunc__ = None  # ``array * objective`` calls :meth:`__rmul__` (which checks the weight), not numpy

    def param_size(self, robot: Robot) -> int:
        """Length of :meth:`params` for ``robot`` (default 0)."""
        return 0

    def params(self, robot: Robot) -> np.ndarray:
        """The current parameters, a flat vector (weights, sharpness, cap, ...)."""
        return _EMPTY

    def structure(self) -> tuple:
        """What fixes the expression's form beyond the parameters (part of a compiled function's key)."""
        return ()

    def key(self) -> tuple:
        """Type and :meth:`structure`: objectives with the same key share compiled functions."""
        return (type(self).__module__, type(self).__qualname__, self.structure())

    @abstractmethod
    def split(self, ctx: Context, p: ca.SX) -> Split:
        """The objective at ``ctx.q`` with parameters ``p`` (param_size,), as a :class:`Split`."""

    def expr(self, ctx: Context, p: ca.SX) -> ca.SX:
        """The value f(q) (SX scalar): :meth:`split` summed."""
        return self.split(ctx, p).value()

    @property
    def smooth(self) -> bool:
        """Whether f is twice differentiable (no maximum in its split)."""
        return True

    @property
    def terms(self) -> tuple[tuple[float, Objective], ...]:
        """``((weight, objective), ...)`` whose weighted sum this is (itself with weight 1)."""
        return ((1.0, self),)

    @property
    def quantity(self) -> Quantity:
        """How a value of it is shown (:class:`Quantity`); by default the objective itself, minimised."""
        return Quantity(self.name if self.name != Objective.name else "objective")

    def __mul__(self, weight: float) -> Sum:
        weight = number(weight, "weight")
        return Sum([(w * weight, o) for w, o in self.terms])

    __rmul__ = __mul__

    def __add__(self, other: Objective) -> Sum:
        if not isinstance(other, Objective):
            return NotImplemented
        return Sum([*self.terms, *other.terms])


class Sum(Objective):
    r"""A weighted sum :math:`\sum_i w_i f_i` (weights ≥ 0, parameters: the weights then each term's).

    Args:
        terms: ``(weight, objective)`` pairs (nested sums are flattened).
    """

    name = "sum"

    @property
    def bounded(self) -> bool:
        return all(o.bounded for _, o in self._terms)

    def __init__(self, terms: Sequence[tuple[float, Objective]]):
        flat: list[tuple[float, Objective]] = []
        for w, o in terms:
            if not isinstance(o, Objective):
                raise InputError(f"terms: expected Objective instances, got {type(o).__name__}")
            weight = number(w, "terms: weight", minimum=None)
            flat += [(weight * v, t) for v, t in o.terms]
        if not flat:
            raise InputError("terms: a Sum needs at least one objective")
        weights = np.array([w for w, _ in flat])
        if not np.isfinite(weights).all() or (weights < 0).any():
            raise InputError(f"terms: weights must be finite and >= 0, got {weights.tolist()}")
        self._terms = tuple(flat)
        self.weights = weights

    @property
    def terms(self) -> tuple[tuple[float, Objective], ...]:
        return tuple((float(w), o) for w, (_, o) in zip(self.weights, self._terms))

    def param_size(self, robot: Robot) -> int:
        return len(self._terms) + sum(o.param_size(robot) for _, o in self._terms)

    def params(self, robot: Robot) -> np.ndarray:
        return np.concatenate([self.weights, *(o.params(robot) for _, o in self._terms)])

    def structure(self) -> tuple:
        return tuple(o.key() for _, o in self._terms)

    @property
    def quantity(self) -> Quantity:
        """One term of weight w > 0: its quantity, read from f / w. Several terms that each measure the negative of
        a maximised quantity (margin, clearance): their weighted sum, maximised, −f. Otherwise the objective f,
        minimised."""
        if len(self._terms) == 1 and self.weights[0] > 0:
            return self._terms[0][1].quantity.scaled(self.weights[0])
        quantities = [o.quantity for _, o in self._terms]
        if all(q.maximised and q.of is _negated for q in quantities):
            name = " + ".join(("" if w == 1.0 else f"{w:g} × ") + q.name for w, q in zip(self.weights, quantities))
            units = {q.unit for q in quantities}
            return Quantity(name, units.pop() if len(units) == 1 else "", True, f"−({name})", of=_negated)
        parts = [f"{w:g} × ({q.minimised or q.name})" for w, q in zip(self.weights, quantities)]
        return Quantity("objective", meaning=" + ".join(parts))

    def _slices(self, robot: Robot) -> list[slice]:
        start, out = len(self._terms), []
        for _, o in self._terms:
            size = o.param_size(robot)
            out.append(slice(start, start + size))
            start += size
        return out

    def split(self, ctx: Context, p: ca.SX) -> Split:
        out = Split(ca.SX(0.0))
        for i, ((_, o), sl) in enumerate(zip(self._terms, self._slices(ctx.robot))):
            part = o.split(ctx, p[sl])
            out.smooth = out.smooth + p[i] * part.smooth
            out.maxima += [(p[i] * w, h) for w, h in part.maxima]
        return out

    @property
    def smooth(self) -> bool:
        return all(o.smooth for _, o in self._terms)


def _positive(x: object, name: str) -> float:
    """``x`` as a finite float > 0, else :class:`InputError` naming ``name``."""
    value = number(x, name)
    if value <= 0:
        raise InputError(f"{name}: must be > 0, got {value:g}")
    return value


def _normalised(robot: Robot, q: ca.SX) -> ca.SX:
    """The 2n normalised distances to the limits, :math:`(q - l)/\\rho` and :math:`(u - q)/\\rho`."""
    lo, hi = np.asarray(robot.q_min, float), np.asarray(robot.q_max, float)
    half = 0.5 * (hi - lo)
    return ca.vertcat((q - lo) / half, (hi - q) / half)


def _soft_max(h: ca.SX, beta: ca.SX) -> ca.SX:
    r""":math:`\tfrac1\beta \log \sum_i e^{\beta h_i}` (≥ max h, within log(m)/β), shifted by max h for range."""
    top = ca.mmax(h)
    return top + ca.log(ca.sum1(ca.exp(beta * (h - top)))) / beta


class JointLimitMargin(Objective):
    r"""Minus the smallest normalised distance to a joint limit.

    With :math:`g = ((q - l)/\rho,\ (u - q)/\rho)` (2n values, :math:`\rho = (u - l)/2`):
    :math:`f = \max_i(-g_i) = -\min_j \min(q_j - l_j, u_j - q_j)/\rho_j` (epigraph form), or with
    ``smooth=True`` :math:`f = \tfrac1\beta \log \sum_i e^{-\beta g_i}`, which is smooth, lies
    above the exact value by at most :math:`\log(2n)/\beta` and has the same minimiser as β → ∞.

    Parameters: β (``sharpness``, only with ``smooth=True``).
    """

    name = "margin"

    def __init__(self, smooth: bool = False, sharpness: float = 20.0):
        self._smooth = flag(smooth, "smooth")
        self.sharpness = _positive(sharpness, "sharpness")

    def structure(self) -> tuple:
        return (self._smooth,)

    def param_size(self, robot: Robot) -> int:
        return 1 if self._smooth else 0

    def params(self, robot: Robot) -> np.ndarray:
        return np.array([self.sharpness]) if self._smooth else _EMPTY

    @property
    def smooth(self) -> bool:
        return self._smooth

    @property
    def quantity(self) -> Quantity:
        r"""The margin :math:`-f` (unitless: a fraction of the half range), maximised; with ``smooth=True`` the soft
        minimum, at most :math:`\log(2n)/\beta` below the margin."""
        if self._smooth:
            return Quantity("smooth margin", "", True, "−smooth margin",
                            f"soft minimum (β = {self.sharpness:g}) of the distances to the joint limits over the"
                            " half ranges, a little below the margin", _negated)  # fmt: skip
        return Quantity("margin", "", True, "−margin",
                        "the smallest distance to a joint limit over the joint's half range", _negated)  # fmt: skip

    def split(self, ctx: Context, p: ca.SX) -> Split:
        g = _normalised(ctx.robot, ctx.q)
        if self._smooth:
            return Split(_soft_max(-g, p[0]))
        return Split(ca.SX(0.0), [(ca.SX(1.0), -g)])


class Manipulability(Objective):
    r"""Minus the log of Yoshikawa's manipulability: :math:`f = -\log \sqrt{\det J J^T}`.

    ``translational``: of the rows :math:`J_v` (m) only. Infinite at a singular configuration.

    Not :attr:`~Objective.bounded`: the Taylor model of m through the QR of J is finite only on
    very narrow δ/ψ ranges (the design notes give the figures); answers with it are the search's,
    not certified.
    """

    name = "manipulability"
    bounded = False

    def __init__(self, translational: bool = False):
        self.translational = flag(translational, "translational")

    def structure(self) -> tuple:
        return (self.translational,)

    @property
    def quantity(self) -> Quantity:
        """Yoshikawa's m itself, :math:`e^{-f}` (m³), maximised."""
        name = "translational manipulability" if self.translational else "manipulability"
        meaning = "√det(J_v J_vᵀ)" if self.translational else "√det(J Jᵀ)"
        return Quantity(name, "m³", True, f"−log {name}", meaning, _exp_negated)

    def split(self, ctx: Context, p: ca.SX) -> Split:
        return Split(-ca.log(ctx.manipulability(self.translational)))


class Clearance(Objective):
    r"""Minus the smallest link-capsule/obstacle distance, capped: :math:`f = -\min(c, \min_{k,o} d_{k,o})`.

    The pairs are every link capsule against every obstacle of the problem (m). Distances
    beyond the cap c (m) do not count. Epigraph form, or with ``smooth=True`` the soft
    minimum :math:`\tfrac1\beta \log(e^{-\beta c} + \sum e^{-\beta d_{k,o}})` (β in 1/m).

    Parameters: c, then β (with ``smooth=True``).
    """

    name = "clearance"

    def __init__(self, cap: float = 0.1, smooth: bool = False, sharpness: float = 100.0):
        self.cap, self.sharpness = _positive(cap, "cap"), _positive(sharpness, "sharpness")
        self._smooth = flag(smooth, "smooth")

    def structure(self) -> tuple:
        return (self._smooth,)

    def param_size(self, robot: Robot) -> int:
        return 2 if self._smooth else 1

    def params(self, robot: Robot) -> np.ndarray:
        return np.array([self.cap, self.sharpness][: self.param_size(robot)])

    @property
    def smooth(self) -> bool:
        return self._smooth

    @property
    def quantity(self) -> Quantity:
        """The capped clearance :math:`-f` (m), maximised; with ``smooth=True`` the soft minimum."""
        name = "smooth clearance" if self._smooth else "clearance"
        meaning = f"the smallest link-capsule/obstacle distance, capped at {self.cap:g} m"
        if self._smooth:
            meaning = (f"soft minimum (β = {self.sharpness:g} 1/m) of the link-capsule/obstacle distances and the cap"
                       f" {self.cap:g} m, a little below the smallest")  # fmt: skip
        return Quantity(name, "m", True, f"−{name}", meaning, _negated)

    def split(self, ctx: Context, p: ca.SX) -> Split:
        h = -ca.vertcat(ctx.distances, p[0])
        if self._smooth:
            return Split(_soft_max(h, p[1]))
        return Split(ca.SX(0.0), [(ca.SX(1.0), h)])


class ReferenceDistance(Objective):
    r"""Distance to a reference configuration: :math:`f = \tfrac12 \sum_j w_j (q_j - q_{ref,j})^2` (rad²).

    ``q_ref`` is the problem's (the ``q_ref`` argument of :func:`qpik.solve_best`, or
    :class:`~qpik.control.tasks.ObjectiveTask`'s): the current configuration, for continuity.

    Parameters: the weights w (n,), default 1.

    Args:
        weights: (n,) per-joint weights ≥ 0 (None: all 1).
    """

    name = "distance"

    def __init__(self, weights: np.ndarray | None = None):
        self.weights = None if weights is None else finite_array(weights, "weights", (None,)).copy()
        if self.weights is not None and (self.weights < 0).any():
            raise InputError("weights: must be >= 0")

    def _w(self, robot: Robot) -> np.ndarray:
        if self.weights is None:
            return np.ones(robot.dof)
        if self.weights.shape != (robot.dof,):
            raise InputError(f"weights: expected shape ({robot.dof},), got {self.weights.shape}")
        return self.weights

    def param_size(self, robot: Robot) -> int:
        return robot.dof

    def params(self, robot: Robot) -> np.ndarray:
        return self._w(robot)

    @property
    def quantity(self) -> Quantity:
        """f itself (rad²), minimised."""
        return Quantity("distance to q_ref", "rad²", meaning="½ Σ w_j (q_j − q_ref,j)²")

    def split(self, ctx: Context, p: ca.SX) -> Split:
        e = ctx.q - ctx.q_ref
        return Split(0.5 * ca.dot(p * e, e))


class Expression(Objective):
    """A user's objective: ``fn(q)``, a CasADi expression (SX scalar) of q (n,) SX.

    ``fn`` is a :class:`casadi.Function` of one (n,) input, or a Python function building the
    expression. Answers with it can be certified when every operation of the expression has a
    Taylor-model rule (:func:`qpik.enclosure.taylor_function`); otherwise the certificate says so.

    Args:
        fn: the expression's builder.
        smooth: whether it is twice differentiable (the QP task and the cross-check need that).
        name: a label for tables.
    """

    def __init__(self, fn: Callable[[ca.SX], ca.SX] | ca.Function, smooth: bool = True, name: str = "expression"):
        if not callable(fn):
            raise InputError(f"fn: expected a casadi.Function or a callable, got {type(fn).__name__}")
        self.fn, self._smooth, self.name = fn, flag(smooth, "smooth"), str(name)
        self._token = next(_TOKENS)

    def structure(self) -> tuple:
        return (self._token,)

    @property
    def smooth(self) -> bool:
        return self._smooth

    def split(self, ctx: Context, p: ca.SX) -> Split:
        out = self.fn(ctx.q)
        if isinstance(out, (list, tuple)) and out:
            out = out[0]
        if not isinstance(out, ca.SX):
            try:
                out = ca.SX(out)
            except (NotImplementedError, TypeError, RuntimeError):
                raise InputError(f"fn: must return a scalar CasADi expression of q, got {type(out).__name__}") from None
        if out.numel() != 1:
            raise InputError(f"fn: must return a scalar expression of q, got shape {out.shape}")
        return Split(out)


CHUNKS = (128, 16)
"""Rows per call of an :class:`Evaluator`'s compiled maps (:class:`~qpik.compiled.RowMap`: large calls for the
search's samples of every branch at once, small ones for its polish rounds)."""


class Evaluator:
    """An objective and the capsule–obstacle distances, compiled for one robot and obstacle families.

    Evaluates, per configuration, ``f(q)``, ``∇f(q)`` (n,) (CasADi's exact derivative; at a kink
    of an epigraph term, the gradient of one active piece) and the pair distances (C'·O,), m.
    The objective's parameters, ``q_ref`` and the obstacle geometry are inputs: one compiled
    function serves every value of them (it is cached per robot, objective key and families).

    Args:
        robot: the arm.
        objective: the objective.
        obstacles: shapes or an :class:`ObstacleSet` (their families fix the function; the
            geometry is read at every call from :attr:`obstacles`).
    """

    def __init__(self, robot: Robot, objective: Objective, obstacles: Sequence | ObstacleSet = ()):
        self.robot, self.objective = robot, objective
        self.obstacles = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
        self.n_pairs = pair_count(robot, self.obstacles)
        self.params = objective.params(robot)
        key = ("objective maps", objective.key(), self.obstacles.kinds, len(self.params))
        self._maps = robot.cache.get(key, _Maps, self)

    def function(self) -> ca.Function:
        """``(q (n,), p, q_ref (n,), obstacle params) -> [f, ∇f (n), d (C'·O), ∇ min d (n)]`` in one column."""
        robot, n = self.robot, self.robot.dof
        q, q_ref, w = ca.SX.sym("q", n), ca.SX.sym("q_ref", n), ca.SX.sym("w", n)
        p = ca.SX.sym("p", len(self.params))
        prm = ca.SX.sym("obstacles", len(self.obstacles.params))
        ctx = Context(robot, q, q_ref, self.obstacles, prm, witness=w)
        f = self.objective.expr(ctx, p)
        d = ctx.distances
        nearest = ca.gradient(ca.mmin(d), q) if self.n_pairs else ca.SX.zeros(n)
        out = ca.densify(ca.substitute(self.layout.pack(f=f, grad=ca.gradient(f, q), d=d, nearest=nearest), w, q))
        return ca.Function(f"objective_{robot.identifier}", [q, p, q_ref, prm], [out])

    def value_function(self) -> ca.Function:
        """``(q (n,), p, q_ref (n,), obstacle params) -> [f, d (C'·O)]`` in one column: :meth:`function`
        without the derivatives."""
        robot, n = self.robot, self.robot.dof
        q, q_ref, w = ca.SX.sym("q", n), ca.SX.sym("q_ref", n), ca.SX.sym("w", n)
        p = ca.SX.sym("p", len(self.params))
        prm = ca.SX.sym("obstacles", len(self.obstacles.params))
        ctx = Context(robot, q, q_ref, self.obstacles, prm, witness=w)  # the same expressions as :meth:`function`
        out = ca.densify(ca.substitute(ca.vertcat(self.objective.expr(ctx, p), ctx.distances), w, q))
        return ca.Function(f"objective_value_{robot.identifier}", [q, p, q_ref, prm], [out])

    def __call__(self, q: np.ndarray, q_ref: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """``(f (M,), ∇f (M, n), d (M, C'·O), ∇ min d (M, n))`` at configurations q (M, n) (or (n,): then
        the shapes drop M). ``q_ref``: (n,) or (M, n), rad (zeros if None; only :class:`ReferenceDistance`
        reads it). ``∇ min d`` is the gradient of the smallest pair distance (zeros without obstacles)."""
        n = self.robot.dof
        q = finite_array(q, "q")
        Q = np.atleast_2d(q)
        if Q.ndim != 2 or Q.shape[1] != n:
            raise InputError(f"q: expected shape ({n},) or (M, {n}), got {q.shape}")
        ref = np.zeros(n) if q_ref is None else finite_array(q_ref, "q_ref")
        f, grad, d, grad_d = self.rows(Q, np.broadcast_to(ref, Q.shape))
        return (f[0], grad[0], d[0], grad_d[0]) if q.ndim == 1 else (f, grad, d, grad_d)

    @cached_property
    def layout(self) -> Layout:
        """The column of :meth:`function`: ``f``, ``grad`` (n,), ``d`` (C'·O,), ``nearest`` (n,) (∇ min d)."""
        n = self.robot.dof
        return Layout(f=(), grad=n, d=self.n_pairs, nearest=n)

    def rows(self, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`__call__` for configurations Q (M, n) and references R (M, n) that the caller built
        (float arrays of the right shapes, no check): the search's inner loop."""
        (out,) = self._maps.rows(Q, self.params, R, self.obstacles.params)
        rows = self.layout.views(out)
        return rows.f, rows.grad, rows.d, rows.nearest

    def builds(self) -> list[Callable[[], None]]:
        """The compiles of both maps (:meth:`rows`, :meth:`value_rows`; :meth:`~qpik.compiled.RowMap.build`)."""
        return [self._maps.rows.build, self._maps.values.build]

    def build(self) -> None:
        """Compile both maps now, concurrently."""
        concurrently(*self.builds())

    def value_rows(self, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`rows` without the derivatives (:meth:`value_function`): ``(f (M,), d (M, C'·O))``."""
        (out,) = self._maps.values(Q, self.params, R, self.obstacles.params)
        return out[:, 0], out[:, 1:]


class _Maps:
    """An :class:`Evaluator`'s compiled row maps: :meth:`~Evaluator.function` (traced at once, so that a bad
    expression raises when the evaluator is made) and :meth:`~Evaluator.value_function` (on first use)."""

    def __init__(self, evaluator: Evaluator):
        self.rows = RowMap(evaluator.function(), shared=(1, 3), chunks=CHUNKS)
        self._value_function = evaluator.value_function

    @cached_property
    def values(self) -> RowMap:
        return RowMap(self._value_function(), shared=(1, 3), chunks=CHUNKS)


class BoundFunction:
    r"""Taylor models of an objective's split and of the capsule–obstacle distances, for the certificate.

    For a range of configurations given as Taylor models :math:`q(t) = c + s\,t \pm r` in one
    variable :math:`t \in [-1, 1]` (within [lo, hi]; :func:`qpik.enclosure.taylor_function`, e.g. the
    closed form over a δ/ψ range), :meth:`rows` gives the models of the values

    .. math:: v = [\,s(q);\ w_1 \dots w_K;\ h_1 (m_1);\ \dots;\ h_K (m_K);\ d\ (C \cdot O)\,]

    — the split's smooth part, its weights (parameters: single values), the pieces of each maximum
    (:class:`Split`) and the capsule–obstacle distances (m). Each value lies, for the same t, within
    ``centre + slope·t ± radius`` and within [lo, hi], so for every t, with
    :math:`\ell(t) = \max(lo,\ c + s\,t - r)` of each value (lower lines),

    .. math:: f(q(t)) \ge \ell_s(t) + \sum_k w_k \max_i \ell_{k,i}(t),

    a convex piecewise-linear function of t whose minimum over [−1, 1] is a lower bound of f over the
    range (:func:`qpik.nlp.certificate.lower_bound`); a distance whose upper bound is below d_s on the
    whole range proves the clearance constraint violated there.

    The models are composed from three kinds of Taylor function, each compiled once and evaluated over
    rows: the end points of the moving capsules from q (per robot), the distance of one capsule to one
    obstacle from its end points (per obstacle family, shared by every robot, objective and pair), and
    the split from q and the distances (per objective form). Models compose because they share t: the
    outputs of one Taylor function are model inputs of the next.

    Raises:
        InputError: an operation of the objective's expression has no Taylor-model rule (a user
            expression): then no bound exists, and no certificate.
    """

    def __init__(self, robot: Robot, objective: Objective, obstacles: ObstacleSet):
        n = robot.dof
        self.params = objective.params(robot)
        q, q_ref = ca.SX.sym("q", n), ca.SX.sym("q_ref", n)
        p = ca.SX.sym("p", len(self.params))
        prm = ca.SX.sym("obstacles", len(obstacles.params))
        self.n_pairs = pair_count(robot, obstacles)
        d = ca.SX.sym("d", self.n_pairs)
        split = objective.split(Context(robot, q, q_ref, obstacles, prm, distances=d), p)
        self.sizes = tuple(int(h.numel()) for _, h in split.maxima)
        """m_k: the number of pieces of each maximum."""
        values = ca.vertcat(split.smooth, *[w for w, _ in split.maxima], *[h for _, h in split.maxima], d)
        name = robot.identifier
        self._split = RowMap(
            taylor_function(ca.Function(f"bound_{name}", [q, p, q_ref, prm, d], [ca.densify(values)]), [0, 4]),
            shared=(1, 3),
            chunks=(16, 16),
        )
        self._form = (robot, objective, obstacles)
        self._segments = _segment_models(robot) if self.n_pairs else None
        moving = np.flatnonzero(~robot.fixed_capsules)
        self._pairs = [(c, o, kind) for c in range(len(moving)) for o, kind in enumerate(obstacles.kinds)]
        self._radii = robot.capsule_radii[moving]
        self._starts = np.cumsum([0, *(PARAMS[k] for k in obstacles.kinds)])

    @cached_property
    def values(self) -> ca.Function:
        """v itself at one configuration, ``(q, p, q_ref, obstacle params) -> v`` (L,), written directly (the
        distances from q, not through models): what the models enclose."""
        robot, objective, obstacles = self._form
        q, q_ref = ca.SX.sym("q", robot.dof), ca.SX.sym("q_ref", robot.dof)
        p, prm = ca.SX.sym("p", len(self.params)), ca.SX.sym("obstacles", len(obstacles.params))
        ctx = Context(robot, q, q_ref, obstacles, prm)
        split = objective.split(ctx, p)
        v = ca.vertcat(split.smooth, *[w for w, _ in split.maxima], *[h for _, h in split.maxima], ctx.distances)
        return ca.Function(f"bound_values_{robot.identifier}", [q, p, q_ref, prm], [ca.densify(v)])

    def rows(self, c: np.ndarray, params: np.ndarray, q_ref: np.ndarray, obstacle_params: np.ndarray,
             s: np.ndarray, r: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:  # fmt: skip
        """``[centre, slope, radius, lo, hi]`` of v (each (M, L)) for the q models of M rows: centres ``c``,
        slopes ``s``, radii ``r`` and bounds ``lo``, ``hi`` (each (M, n), rad), with the objective's
        ``params``, ``q_ref`` (M, n) and the packed ``obstacle_params`` (:attr:`ObstacleSet.params`)."""
        M = len(c)
        d = [np.zeros((M, 0))] * 5
        if self._segments is not None:
            seg = self._segments(c, s, r, lo, hi)  # 5 × (M, 6 C')
            d = [np.empty((M, self.n_pairs)) for _ in range(5)]
            for kind, at in _by_kind(self._pairs):
                cap = np.array([self._pairs[k][0] for k in at])
                obs = np.array([self._pairs[k][1] for k in at])
                pick = (6 * cap[:, None] + np.arange(6)).ravel()
                parts = [x[:, pick].reshape(M * len(at), 6) for x in seg]
                radius = np.tile(self._radii[cap], M)[:, None]
                span = self._starts[obs][:, None] + np.arange(PARAMS[kind])
                prm = np.tile(np.asarray(obstacle_params, float)[span], (M, 1))
                out = _pair_models(kind)(parts[0], radius, prm, *parts[1:])
                for whole, part in zip(d, out):
                    whole[:, at] = part.reshape(M, len(at))
        return self._split(c, params, q_ref, obstacle_params, d[0], s, r, lo, hi, *d[1:])

    def builds(self) -> list[Callable[[], None]]:
        """The compiles of every function :meth:`rows` calls (:meth:`~qpik.compiled.RowMap.build`), to run now."""
        maps = [self._split, *([] if self._segments is None else [self._segments])]
        return [m.build for m in maps + [_pair_models(kind) for kind, _ in _by_kind(self._pairs)]]

    def build(self) -> None:
        """Compile every function :meth:`rows` calls now, concurrently (:func:`qpik.build.concurrently`)."""
        concurrently(*self.builds())


def _by_kind(pairs: list[tuple[int, int, str]]) -> list[tuple[str, np.ndarray]]:
    """The pair indices of each obstacle family, in first-seen order."""
    kinds = list(dict.fromkeys(kind for _, _, kind in pairs))
    return [(kind, np.array([k for k, (_, _, x) in enumerate(pairs) if x == kind])) for kind in kinds]


def _segment_models(robot: Robot) -> RowMap:
    """The Taylor models of the moving capsules' axes ``[a, u]`` (6 C', world frame, m) from q's model:
    ``(c, s, r, lo, hi) -> 5 × (6 C')``, compiled once per robot. A capsule of link k with end points
    :math:`p_0, p_1` (link frame) has :math:`a = R_k p_0 + t_k` and :math:`u = R_k (p_1 - p_0)`: u written
    without the link's position, so its model carries none of t_k's remainder."""
    return robot.cache.get("capsule axis models", _build_segment_models, robot)


def _build_segment_models(robot: Robot) -> RowMap:
    q = ca.SX.sym("q", robot.dof)
    frames = robot.chain.frames_expr([q[i] for i in range(robot.dof)], sy.CASADI)
    axes = []
    for c in np.flatnonzero(~robot.fixed_capsules):
        capsule = robot.capsules[c]
        R, t = frames[capsule.link]
        p0, p1 = (tuple(map(sy.snap, p)) for p in (capsule.p0, capsule.p1))
        axes += [*sy.vadd(sy.matvec(R, p0), t), *sy.matvec(R, sy.vsub(p1, p0))]
    fn = ca.Function(f"axes_{robot.identifier}", [q], [ca.densify(ca.vertcat(*axes))])
    return RowMap(taylor_function(fn, [0]), chunks=(16, 16))


@cache
def _pair_models(kind: str) -> RowMap:
    """The Taylor model of one capsule–obstacle distance (m) of family ``kind`` from its axis's models
    (:func:`_segment_models`): ``(axis [a, u] (6,), radius, obstacle params, slope, radius, lo, hi of the axis)
    -> 5 × (1,)``, compiled once."""
    axis, radius, prm = ca.SX.sym("axis", 6), ca.SX.sym("radius"), ca.SX.sym("obstacle", PARAMS[kind])
    a, u = tuple(axis[i] for i in range(3)), tuple(axis[i] for i in range(3, 6))
    d = axis_distance(a, u, radius, kind, [prm[i] for i in range(PARAMS[kind])], sy.CASADI)
    return RowMap(taylor_function(ca.Function(f"pair_{kind}", [axis, radius, prm], [d]), [0]), chunks=(64, 16))


def bound_function(robot: Robot, objective: Objective, obstacles: ObstacleSet) -> BoundFunction | None:
    """The cached :class:`BoundFunction` of the objective's form and the obstacle families, or None when
    the objective is not :attr:`~Objective.bounded` or its expression has an operation without a
    Taylor-model rule."""
    if not objective.bounded:
        return None
    key = ("bound function", objective.key(), obstacles.kinds, len(objective.params(robot)))
    return robot.cache.get(key, _bounds, robot, objective, obstacles)


def _bounds(robot: Robot, objective: Objective, obstacles: ObstacleSet) -> BoundFunction | None:
    try:
        return BoundFunction(robot, objective, obstacles)
    except InputError:
        return None


_NAMED: dict[str, Callable[[], Objective]] = {
    "margin": JointLimitMargin,
    "smooth-margin": lambda: JointLimitMargin(smooth=True),
    "manipulability": Manipulability,
    "clearance": Clearance,
    "smooth-clearance": lambda: Clearance(smooth=True),
    "distance": ReferenceDistance,
}
NAMES = tuple(_NAMED)
"""The names :func:`resolve` accepts."""


def resolve(objective: Objective | str) -> Objective:
    """An objective, or one with default parameters from its name (:data:`NAMES`)."""
    if isinstance(objective, Objective):
        return objective
    if not isinstance(objective, str) or objective not in _NAMED:
        raise InputError(f"objective: expected an Objective or one of {list(NAMES)}, got {objective!r}")
    return _NAMED[objective]()
