"""What the public functions (:mod:`qpik.analytic.api`) call of an arm's IK for a given redundancy parameter:
:class:`BranchSolver`, and its numeric answer :class:`Solved`. :class:`~qpik.analytic.solver.AnalyticSolver` (closed
forms written as expressions) is one kind, :class:`~qpik.analytic.search_solver.SearchSolver` (the roots of a certified
1-D search) another."""

from __future__ import annotations

import math
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from functools import cached_property
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from qpik.algebra.symbolic import Ops, Scalar
from qpik.core.errors import NoClosedFormError

if TYPE_CHECKING:
    from qpik.analytic.intervals import FeasibleIntervals, ParameterSets
    from qpik.analytic.native_sets import NativeSets
    from qpik.robots.robot import Robot


class Solved(NamedTuple):
    """Numeric IK of B branches: q (..., B, n) rad, and (..., B) bools: the branch reaches the
    pose (``valid``), is at a singular case (``singular``), is valid with every joint in
    ``[q_min, q_max]`` (``within_limits``)."""

    q: np.ndarray
    valid: np.ndarray
    singular: np.ndarray
    within_limits: np.ndarray


class BranchSolver(ABC):
    r"""The IK of one arm family for a given redundancy parameter, as the public functions
    (:mod:`qpik.analytic.api`) call it: a fixed number B of branch slots per pose (``branch_ids``, the public
    number of each slot), each valid or not, and the parameter and branch of a configuration.

    :class:`AnalyticSolver` writes its branches once as expressions (closed forms, and their CasADi functions for
    the NLPs); :class:`~qpik.analytic.search_solver.SearchSolver` finds them as the roots of a certified 1-D search
    (no expressions: ``Robot.branch_functions`` False). Subclasses set ``kind`` (the ``Robot.closed_form`` value),
    ``param_name`` and ``branch_ids``; the feasible sets of the parameter come from ``sets``, built from the solver on
    first use (:class:`~qpik.analytic.intervals.ParameterSets`), so the solver does not depend on the module that
    computes them.

    A joint whose limits reach past ±π gets the representative :math:`q + 2\pi k` inside its limits when the
    wrapped angle is outside them (the nearest one, :meth:`representative`), so that ``within_limits`` holds when any
    representative is inside (the others, q ± 2π inside the limits, are the same pose).
    """

    kind: str
    param_name: str
    branch_ids: tuple[int, ...]
    closed_form_sets: bool = True
    """Whether the feasible sets are roots of closed-form functions of the parameter (found in microseconds), not a
    certified root isolation (milliseconds): :func:`qpik.solve_best`'s ``"auto"`` method runs the level sets, which
    ask for the sets at several margins per pose, only where they are."""

    def __init__(self, robot: Robot, sets: Callable[[BranchSolver], ParameterSets] | None = None):
        self.robot = robot
        self._make_sets = sets
        lo, hi = np.asarray(robot.q_min, float), np.asarray(robot.q_max, float)
        self._wide = (lo < -np.pi) | (hi > np.pi)  # joints whose representatives are chosen
        self.full_turn = (lo <= -np.pi) & (hi >= np.pi)
        """Per joint, whether its limits hold every wrapped angle: its value is that angle (:meth:`representative`)."""
        self.lock = threading.RLock()
        """Held by the public functions (:mod:`qpik.analytic.api`) around the solver's calls: its compiled functions
        evaluate in buffers of their own, which two threads must not use at once."""

    @property
    def n_branches(self) -> int:
        return len(self.branch_ids)

    @cached_property
    def branch_array(self) -> np.ndarray:
        """``branch_ids`` as an int array (B,), read-only (the results of :func:`qpik.ik` share it)."""
        out = np.array(self.branch_ids)
        out.flags.writeable = False
        return out

    def representative(self, j: int, x: Scalar, ops: Ops) -> Scalar:
        """The robot's joint j at the angle x (rad, wrapped): x itself, or for a joint whose limits reach past ±π the
        representative x + 2πk inside them where x is outside (the nearest; see the class docstring).

        Limits narrower than a turn hold at most one representative: the smallest x + 2πk ≥ l, written as
        ``where(x > c, x + α, x + α + 2π)`` with c = l − α in (−π, π] (one ulp lower, so that x = c gives l), the
        form whose Taylor model :mod:`qpik.algebra.angle_tags` keeps continuous where x wraps through ±π."""
        if not self._wide[j]:
            return x
        lo, hi, turn = float(self.robot.q_min[j]), float(self.robot.q_max[j]), 2.0 * np.pi
        if self.full_turn[j]:
            return ops.wrap(x)  # every wrapped angle lies inside the limits (the angle tags follow a wrap)
        if hi - lo < turn:
            alpha = turn * math.ceil((lo - np.pi) / turn)
            cut = float(np.nextafter(lo - alpha, -np.inf))
            x = ops.wrap(x)  # the form holds for x in (−π, π] only (a wrapped x stays as it is)
            return ops.where(x > cut, x + alpha, x + (alpha + turn))
        x = ops.where(x > hi, x + turn * ops.floor((hi - x) / turn), x)  # the largest x - 2πk <= hi
        return ops.where(x < lo, x - turn * ops.floor((x - lo) / turn), x)  # the smallest x + 2πk >= lo

    @property
    def fresh_one(self):
        """A call ``fresh(T, param) -> (q (B, n), flags (3, B) bool)`` of one pose through compiled code, or None
        (:attr:`AnalyticSolver.fresh_one`); None here."""
        return None

    @abstractmethod
    def solve_one(self, T: np.ndarray, param: float) -> Solved:
        """One pose (4, 4), one parameter (rad): q (B, n), valid, singular, within_limits (B,) bool."""

    @abstractmethod
    def solve_many(self, T: np.ndarray, params: np.ndarray, rows: int | None = None) -> Solved:
        """One pose (4, 4), parameters (M,): q (M, B, n), valid, singular, within_limits (M, B) bool; ``rows``: only
        the first ``rows`` branches."""

    @abstractmethod
    def solve_batch(self, T: np.ndarray, param: np.ndarray) -> Solved:
        """Poses (N, 4, 4), parameters (N,): q (N, B, n), valid, singular, within_limits (N, B) bool."""

    @abstractmethod
    def parameter(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Redundancy parameter (rad) and branch id of configurations q (N, n) wrapped to (−π, π]: ((N,), (N,) int)."""

    @cached_property
    def _sets(self) -> ParameterSets:
        if self._make_sets is None:
            raise NoClosedFormError(f"{type(self).__name__} was made without its feasible sets")
        return self._make_sets(self)

    def feasible_intervals(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        r"""Per branch, the exact parameter set where every joint j lies in the limits shrunk by ``margin``,
        :math:`[l_j + m\rho_j,\ u_j - m\rho_j]`, :math:`\rho_j = (u_j - l_j)/2`
        (:func:`qpik.analytic.intervals.shrunk_limits`): the parameters whose joint-limit margin
        (:class:`qpik.objectives.JointLimitMargin`) is at least ``margin``. ``T``: (4, 4) pose, world frame;
        ``margin`` >= 0 (0: the joint limits themselves; above 1 every set is empty). The breakpoint
        equations are those of the family's sets module (:mod:`qpik.analytic.offset_shoulder_intervals`,
        :mod:`qpik.analytic.srs_intervals`)."""
        return self._sets(T, margin)

    @property
    def sets_proved(self) -> bool:
        """Whether :meth:`feasible_intervals` can be proved (the sets type's ``ParameterSets.proved``, read without
        building the sets); each answer says whether it is (``FeasibleIntervals.proved``): an empty set then proves
        that no parameter is feasible, and a level set or certificate built on the sets is a proof."""
        return self._make_sets is not None and bool(self._make_sets.proved)

    def native_sets(self) -> NativeSets | None:
        """:meth:`feasible_intervals` under limits given at run time as one C call
        (:class:`~qpik.analytic.native_sets.NativeSets`), for C code that calls it in a loop; None where there is no
        such call (no compiler)."""
        return self._sets.native_sets()
