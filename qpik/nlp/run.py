r"""What one :func:`qpik.solve_best` call evaluates: poses, objective, obstacles, and the 1-D functions of δ/ψ.

A :class:`BestRun` evaluates, for rows (pose i, branch row b, parameter ψ), everything the
search and the certificate need, from two compiled functions: the self-motion
(:class:`~qpik.nlp.selfmotion.SelfMotion`: q, dq/dψ) and the objective
(:class:`~qpik.scene.evaluator.Evaluator`: f, ∇f, the capsule–obstacle distances):

- the objective :math:`f(\psi) = f(q_b(\psi))` and :math:`f'(\psi) = \nabla f \cdot dq_b/d\psi`;
- the clearance constraint :math:`c(\psi) = \min_{k} d_{k}(q_b(\psi)) - d_s` over the clearances
  (capsule–obstacle pairs, then the scene's capsule pairs :attr:`~qpik.scene.Scene.self_pairs`; +∞ without
  any) and :math:`c'(\psi)`, the rate of the nearest pair.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from qpik.core.stopwatch import Stopwatch
from qpik.native.build import concurrently
from qpik.nlp.selfmotion import SelfMotion, columns
from qpik.scene.bounds import BoundFunction, bound_function
from qpik.scene.evaluator import Evaluator
from qpik.scene.scene import Scene


@dataclass
class Points:
    """Evaluations at M rows (pose, branch row, parameter).

    Attributes:
        pose, row: (M,) int; psi: (M,) rad.
        q, dq: (M, n) configuration (rad) and dq/dψ; valid: (M,) the branch reaches the pose.
        f, df: (M,) objective and its derivative in ψ.
        c, dc: (M,) clearance margin min d − d_s (m; +inf without clearances) and its derivative.
        d: (M, C'·O + P) the clearances, m (:attr:`~qpik.scene.evaluator.Evaluator.n_pairs`).
    """

    pose: np.ndarray
    row: np.ndarray
    psi: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    valid: np.ndarray
    f: np.ndarray
    df: np.ndarray
    c: np.ndarray
    dc: np.ndarray
    d: np.ndarray

    def __len__(self) -> int:
        return len(self.psi)

    def take(self, idx: np.ndarray) -> Points:
        """The rows ``idx`` (an index array or a boolean mask)."""
        return Points(*(getattr(self, f.name)[idx] for f in fields(self)))

    @staticmethod
    def join(parts: list[Points]) -> Points:
        return Points(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Points)))


def least_per_row(pose: np.ndarray, row: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Indices of the point with the smallest ``f`` of each (pose, branch row) among points (M,) (the first of equal
    ones), ordered by pose and row."""
    order = np.lexsort((f, row, pose))
    first = np.ones(len(order), bool)
    first[1:] = (pose[order][1:] != pose[order][:-1]) | (row[order][1:] != row[order][:-1])
    return order[first]


class BestRun:
    """The data of one solve and the evaluation of rows (see the module docstring).

    Attributes:
        columns: (N, 16) the poses' entries in CasADi's column-major order (:func:`~qpik.nlp.selfmotion.columns`).
        evaluations: rows evaluated so far; counts: (N, searched branches) of them per pose and branch,
            as attributed by the search (:mod:`qpik.nlp.best`).
        watch: the solve's clock, started when the scene is made; functions are built with it paused
            (:meth:`build_search`, :meth:`build_certificate`).

    Args:
        scene: the arm (with a closed form), the obstacles (clearance constraint, and the objective's pairs),
            d_s (m) and the objective (:class:`~qpik.scene.Scene`, with an objective).
        selfmotion: the arm's :class:`SelfMotion`.
        poses: (N, 4, 4) end-effector poses.
        q_ref: (N, n) reference configurations, rad.
    """

    def __init__(self, scene: Scene, selfmotion: SelfMotion, poses: np.ndarray, q_ref: np.ndarray):
        self.robot, self.selfmotion, self.objective = scene.robot, selfmotion, scene.objective
        self.obstacles, self.d_safe, self.self_pairs = scene.obstacles, scene.d_safe, scene.self_pairs
        self.problem = scene
        self.poses, self.q_ref = poses, q_ref
        self.columns = columns(poses)
        self.evaluations = 0
        self.counts = np.zeros((len(poses), selfmotion.searched), int)
        self.watch = Stopwatch()

    def _search_builds(self) -> list[Callable[[], object]]:
        """What the search calls, to compile: the exact feasible sets (by evaluating them at the first pose), the
        self-motion and the objective at every call size."""
        return [lambda: self.selfmotion.solver.feasible_intervals(self.poses[0]),
                *self.selfmotion.builds(models=False), *self.evaluator.builds()]  # fmt: skip

    def build_search(self) -> None:
        """Trace and compile what the search calls (:meth:`_search_builds`) now, concurrently, with :attr:`watch`
        paused."""
        with self.watch.paused():
            concurrently(*self._search_builds())

    def build_certificate(self) -> BoundFunction | None:
        """:meth:`build_search` and the certificate's Taylor models (of q and of the objective's split), compiled
        concurrently with :attr:`watch` paused; returns the bound function (None: the objective has none)."""
        with self.watch.paused():
            bounds = bound_function(self.robot, self.objective, self.obstacles, self.self_pairs)
            models = [self.selfmotion.builds(models=True)[-1]]
            concurrently(*self._search_builds(), *models, *([] if bounds is None else bounds.builds()))
        return bounds

    @cached_property
    def evaluator(self) -> Evaluator:
        """The objective's and the clearances' compiled rows (built on first use: the level sets need none)."""
        return Evaluator(self.robot, self.objective, self.obstacles, self.self_pairs)

    @property
    def params(self) -> np.ndarray:
        """The objective's parameter values."""
        return self.evaluator.params

    def evaluate(self, pose: np.ndarray, row: np.ndarray, psi: np.ndarray) -> Points:
        """Every quantity of :class:`Points` at the rows (pose (M,), branch row (M,), ψ (M,))."""
        pose, row, psi = np.asarray(pose, int), np.asarray(row, int), np.asarray(psi, float)
        M, n = len(psi), self.robot.dof
        if not M:
            e = np.zeros(0)
            return Points(pose, row, psi, np.zeros((0, n)), np.zeros((0, n)), np.zeros(0, bool), e, e, e, e,
                          np.zeros((0, self.evaluator.n_pairs)))  # fmt: skip
        q, dq, valid = self.selfmotion.points(row, self.columns[pose], psi)
        f, grad, d, grad_d = self.evaluator.rows(q, self.q_ref[pose])
        df = (grad * dq).sum(axis=1)
        if d.shape[1]:
            c, dc = d.min(axis=1) - self.d_safe, (grad_d * dq).sum(axis=1)
        else:
            c, dc = np.full(M, np.inf), np.zeros(M)
        self.evaluations += M
        return Points(pose, row, psi, q, dq, valid, f, df, c, dc, d)

    def values(self, pose: np.ndarray, row: np.ndarray, psi: np.ndarray) -> Points:
        """:meth:`evaluate` without the derivatives (``dq``, ``df`` and ``dc`` are NaN): less work per
        row (:meth:`~qpik.nlp.selfmotion.SelfMotion.values`, :meth:`~qpik.scene.evaluator.Evaluator.value_rows`), for
        the samples of the search; f, c and d are the same numbers as :meth:`evaluate`'s (the same expressions)."""
        pose, row, psi = np.asarray(pose, int), np.asarray(row, int), np.asarray(psi, float)
        if not len(psi):
            return self.evaluate(pose, row, psi)
        M = len(psi)
        q, valid = self.selfmotion.values(row, self.columns[pose], psi)
        f, d = self.evaluator.value_rows(q, self.q_ref[pose])
        c = d.min(axis=1) - self.d_safe if d.shape[1] else np.full(M, np.inf)
        nan = np.full(M, np.nan)
        self.evaluations += M
        return Points(pose, row, psi, q, np.full(q.shape, np.nan), valid, f, nan, c, nan, d)

    def bound_rows(self, bounds: BoundFunction, *q_model: np.ndarray) -> list[np.ndarray]:
        """The Taylor models of the values of ``bounds`` (:class:`~qpik.scene.bounds.BoundFunction`) for rows of
        q's models ``centre, slope, radius, lo, hi`` (M, n each) and their poses (M,): ``[centre, slope,
        radius, lo, hi]``, each (M, L)."""
        c, s, r, lo, hi, pose = q_model
        return bounds.rows(c, self.params, self.q_ref[pose], self.obstacles.params, s, r, lo, hi)
