r"""Feasible sets of the locked joint of the arms whose slots are found per pose and locked angle (the 1-D search's,
:mod:`qpik.analytic.search_solver`; the general 6-R's, :mod:`qpik.analytic.general_solver`), sampled and not
proved.

A slot of a :class:`~qpik.analytic.slot_solver.SlotSolver` changes its state (valid with every joint inside the
limits, or not) where one of its joints reaches a limit, where its solution appears or vanishes (a fold, where two
meet; for the search, :math:`e_b = \partial e_b/\partial x = 0` or the edge of its validity), or where it takes
another solution (one below it in the slots' order appears or vanishes, or crosses ±π). For the search these values
are roots of 2-D systems in the locked angle and x, which no module isolates; for the general 6-R they are where the
eigenproblem's real eigenvalues meet. :class:`SampledSets` therefore samples the solver's answers at :data:`SAMPLES`
values of the locked joint per 2π over its (shrunk) limits, and moves every change of a slot's state between two
neighbouring samples onto the answers to 1e-11 rad, sampling again beside each change and wherever the slots'
validity differs between two samples (:func:`qpik.analytic.set_ends.resample`). A slot that enters and leaves the
limits between two samples where no slot's validity differs (a stretch narrower than 2π/:data:`SAMPLES`, away from
every other change) is not seen, so the answers are not proved (``proved`` False) and an empty set proves nothing.
The values where a slot is singular are not listed.

Each sample and each step of a change is one solve (milliseconds): seconds per pose, with progress lines on stderr
after two.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.intervals import FeasibleIntervals, Interval, shrunk_limits
from qpik.analytic.set_ends import resample

if TYPE_CHECKING:
    from qpik.analytic.slot_solver import SlotSolver

SAMPLES = 512
"""Values of the locked joint per 2π at which every slot's state is sampled."""


class SampledSets:
    """The feasible sets of a :class:`~qpik.analytic.slot_solver.SlotSolver`'s locked joint (a ``ParameterSets``;
    module docstring)."""

    proved = False
    """Sampled: never proved."""

    def __init__(self, solver: SlotSolver):
        self._solver = solver
        self._last: tuple[bytes, float, FeasibleIntervals] | None = None
        """The last pose (bytes), margin and answer."""

    def native_sets(self) -> None:
        """No single C call for this family."""
        return None

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals:
        """Per slot, the values (rad) of the locked joint where it is valid with every joint inside the limits shrunk
        by ``margin`` (:func:`~qpik.analytic.intervals.shrunk_limits`); ``T`` (4, 4), base frame. The last answer is
        kept: the same pose and margin again return the same object."""
        key = np.asarray(T, float).tobytes()
        if self._last is None or self._last[0] != key or self._last[1] != margin:
            self._last = (key, margin, self._sets(T, margin))
        return self._last[2]

    def _sets(self, T: np.ndarray, margin: float) -> FeasibleIntervals:
        s = self._solver
        empty: list[list[Interval]] = [[] for _ in s.branch_ids]
        none = FeasibleIntervals(s.param_name, s.branch_array, empty, [[] for _ in s.branch_ids], proved=False)
        lo, hi = (float(x[s.locked]) for x in shrunk_limits(s.robot.q_min, s.robot.q_max, margin))
        if lo > hi:
            return none
        span = locked_span(lo, hi)
        words = f"the feasible {s.param_name} sets of {s.robot.name} (sampled)"
        return resample(none, s, T, margin, [span] * len(s.branch_ids), 2.0 * np.pi / SAMPLES, words, renumbered=True)


def locked_span(lo: float, hi: float) -> list[Interval]:
    """The values in [−π, π] (rad) of a joint whose limits are [``lo``, ``hi``] (lo ≤ hi, rad): sorted disjoint
    intervals, split at ±π where the limits pass it; the whole circle where they span 2π."""
    if hi - lo >= 2.0 * np.pi:
        return [(-np.pi, np.pi)]
    shift = 2.0 * np.pi * np.floor((lo + np.pi) / (2.0 * np.pi))  # lo - shift in [−π, π)
    a, b = lo - shift, hi - shift
    if b <= np.pi:
        return [(a, b)]
    return [(-np.pi, b - 2.0 * np.pi), (a, np.pi)]
