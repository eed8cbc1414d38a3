"""evaluator: see :mod:`qpik.objectives`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from qpik.core.errors import InputError
from qpik.core.layout import Layout
from qpik.core.validate import finite_array
from qpik.geometry.distance import ObstacleSet
from qpik.native.build import concurrently
from qpik.native.compiled import RowMap

if TYPE_CHECKING:
    from qpik.robots.robot import Robot
from qpik.objectives.context import Context, pair_count
from qpik.objectives.objective import Objective
from qpik.robots.self_pairs import Pair

CHUNKS = (128, 16)


class Evaluator:
    """An objective and the capsule–obstacle distances, compiled for one robot and obstacle families.

    Evaluates, per configuration, ``f(q)``, ``∇f(q)`` (n,) (CasADi's exact derivative; at a kink
    of an epigraph term, the gradient of one active piece) and the clearances (C'·O + P,), m: the
    capsule–obstacle distances, then the distances of the capsule pairs ``self_pairs``
    (:attr:`~qpik.objectives.context.Context.clearances`).
    The objective's parameters, ``q_ref`` and the obstacle geometry are inputs: one compiled
    function serves every value of them (it is cached per robot, objective key and families).

    Args:
        robot: the arm.
        objective: the objective.
        obstacles: shapes or an :class:`ObstacleSet` (their families fix the function; the
            geometry is read at every call from :attr:`obstacles`).
        self_pairs: the capsule pairs kept apart (:func:`~qpik.robots.self_pairs.checked_pairs`; none: ()).
    """

    def __init__(self, robot: Robot, objective: Objective, obstacles: Sequence | ObstacleSet = (),
                 self_pairs: tuple[Pair, ...] = ()):  # fmt: skip
        self.robot, self.objective, self.self_pairs = robot, objective, self_pairs
        self.obstacles = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
        self.n_pairs = pair_count(robot, self.obstacles) + len(self_pairs)
        """The number of clearances: capsule–obstacle pairs, then capsule pairs."""
        self.params = objective.params(robot)
        key = ("objective maps", objective.key(), self.obstacles.kinds, len(self.params), self_pairs)
        self._maps = robot.cache.get(key, _Maps, self)

    def function(self) -> ca.Function:
        """``(q (n,), p, q_ref (n,), obstacle params) -> [f, ∇f (n), d (C'·O + P), ∇ min d (n)]`` in one column."""
        robot, n = self.robot, self.robot.dof
        q, q_ref, w = ca.SX.sym("q", n), ca.SX.sym("q_ref", n), ca.SX.sym("w", n)
        p = ca.SX.sym("p", len(self.params))
        prm = ca.SX.sym("obstacles", len(self.obstacles.params))
        ctx = Context(robot, q, q_ref, self.obstacles, prm, witness=w, self_pairs=self.self_pairs)
        f = self.objective.expr(ctx, p)
        d = ctx.clearances
        nearest = ca.gradient(ca.mmin(d), q) if self.n_pairs else ca.SX.zeros(n)
        out = ca.densify(ca.substitute(self.layout.pack(f=f, grad=ca.gradient(f, q), d=d, nearest=nearest), w, q))
        return ca.Function(f"objective_{robot.identifier}", [q, p, q_ref, prm], [out])

    def value_function(self) -> ca.Function:
        """``(q (n,), p, q_ref (n,), obstacle params) -> [f, d (C'·O + P)]`` in one column: :meth:`function`
        without the derivatives."""
        robot, n = self.robot, self.robot.dof
        q, q_ref, w = ca.SX.sym("q", n), ca.SX.sym("q_ref", n), ca.SX.sym("w", n)
        p = ca.SX.sym("p", len(self.params))
        prm = ca.SX.sym("obstacles", len(self.obstacles.params))
        ctx = Context(robot, q, q_ref, self.obstacles, prm, witness=w, self_pairs=self.self_pairs)  # as function()
        out = ca.densify(ca.substitute(ca.vertcat(self.objective.expr(ctx, p), ctx.clearances), w, q))
        return ca.Function(f"objective_value_{robot.identifier}", [q, p, q_ref, prm], [out])

    def __call__(self, q: np.ndarray, q_ref: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """``(f (M,), ∇f (M, n), d (M, C'·O + P), ∇ min d (M, n))`` at configurations q (M, n) (or (n,): then
        the shapes drop M). ``q_ref``: (n,) or (M, n), rad (zeros if None; only :class:`ReferenceDistance`
        reads it). ``∇ min d`` is the gradient of the smallest clearance (zeros without any)."""
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
        """The column of :meth:`function`: ``f``, ``grad`` (n,), ``d`` (C'·O + P,), ``nearest`` (n,) (∇ min d)."""
        n = self.robot.dof
        return Layout(f=(), grad=n, d=self.n_pairs, nearest=n)

    def rows(self, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`__call__` for configurations Q (M, n) and references R (M, n) that the caller built
        (float arrays of the right shapes, no check): the search's inner loop."""
        (out,) = self._maps.rows(Q, self.params, R, self.obstacles.params)
        rows = self.layout.views(out)
        return rows.f, rows.grad, rows.d, rows.nearest

    def builds(self) -> list[Callable[[], None]]:
        """The compiles of both maps (:meth:`rows`, :meth:`value_rows`; :meth:`~qpik.native.compiled.RowMap.build`)."""
        return [self._maps.rows.build, self._maps.values.build]

    def build(self) -> None:
        """Compile both maps now, concurrently."""
        concurrently(*self.builds())

    def value_rows(self, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`rows` without the derivatives (:meth:`value_function`): ``(f (M,), d (M, C'·O + P))``."""
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
