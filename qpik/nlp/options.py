"""The solver settings of :func:`qpik.solve_best`, :func:`qpik.nlp.solve_full` and :func:`qpik.solve_ik`, one value
each."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

MAX_ITERS = 3000
"""Default budget of Levenberg–Marquardt iterations over all attempts (a few ms; spent in whole chunks)."""

Method = Literal["closed form", "levenberg-marquardt"]


@dataclass(frozen=True)
class BestOptions:
    """How :func:`qpik.solve_best` searches and proves (each checked by it, :class:`~qpik.core.errors.InputError`
    naming the field).

    Attributes:
        certify: prove global optimality (:mod:`qpik.nlp.certificate`); the level sets prove their answers either
            way (their last call is the proof).
        tol: the certificate's tolerance, relative (> 0): it proves that no feasible point is better than the
            answer by more than ``tol · max(1, |f|)``.
        method: ``"levelset"`` (the exact super-level sets of the margin, :mod:`qpik.nlp.levelset`: the plain
            margin objective without obstacles only), ``"search"`` (sampling and polish), ``"ipopt"`` (IPOPT from
            every interval), or ``"auto"``: ``"levelset"`` where it applies and the arm's feasible sets are in
            closed form (:attr:`~qpik.analytic.solver.AnalyticSolver.closed_form_sets`: S-R-S ψ, offset shoulder
            δ), else ``"search"``. With self-collision, the method of the pass without the capsule pairs; a pose
            solved again with them (:mod:`qpik.nlp.best`) goes through the search after the level sets.
        branches: public ids of the branches to search (None: all), e.g. the branch of the current configuration
            (:func:`qpik.redundancy_parameter`), which a continuous motion keeps unless it passes a singular
            configuration.
    """

    certify: bool = True
    tol: float = 1e-4
    method: str = "auto"
    branches: Sequence[int] | None = None


@dataclass(frozen=True)
class FullOptions:
    """The multi-start of :func:`qpik.nlp.solve_full` (each checked by it, :class:`~qpik.core.errors.InputError`
    naming the field).

    Attributes:
        q0: (n,) or (S, n) first start(s), rad, or None (random starts only).
        starts: with an objective, starts solved (≥ 1; the best one that reaches the pose wins; more if none has
            reached it yet). A pure IK stops at the first that reaches it.
        max_starts: most starts tried before giving up (≥ 1; ``"not found"``, or ``"unreachable"`` when proved).
        seed: seed of the random starts (≥ 0).
    """

    q0: np.ndarray | None = None
    starts: int = 8
    max_starts: int = 30
    seed: int = 0


@dataclass(frozen=True)
class IKOptions:
    """The budget and method of :func:`qpik.solve_ik` (each checked by it, :class:`~qpik.core.errors.InputError`
    naming the field).

    Attributes:
        max_iters: budget of Levenberg–Marquardt iterations over all attempts (spent in whole chunks of
            :data:`qpik.nlp.ik.CHUNK`, so up to CHUNK − 1 more).
        max_time: budget in seconds (wall clock, checked between attempts), or None; with it the answer may depend
            on the machine's speed.
        seed: seed of the restarts (the answer is reproducible for a given seed and iteration budget).
        method: ``"closed form"`` (the default for the families of :data:`qpik.nlp.ik.CLOSED_FORM_DEFAULT`) or
            ``"levenberg-marquardt"`` (the default elsewhere, and possible on every arm); None: the default.
    """

    max_iters: int = MAX_ITERS
    max_time: float | None = None
    seed: int = 0
    method: Method | None = None
