"""The data of an arm's feasible sets as one C call (:class:`NativeSets`): what C code that calls the sets in a loop
(:mod:`qpik.nlp.levelset`) is handed. The calls themselves are built in :mod:`qpik.analytic.arm_sets`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class NativeSets:
    """An arm's feasible sets under limits given at run time, as one C call, for C code that calls it in a loop
    (:mod:`qpik.nlp.levelset`).

    ``function`` is the address of ``int f(const void *context)``: it reads the pose T from :attr:`pose` (16,
    column-major) and the limits from :attr:`lo` and :attr:`hi` ((n,) rad, the robot's angles), and writes
    ``count[r]`` pieces of output row r, their ``(lo, hi)`` pairs one row after the other in :attr:`iv` (rad,
    in [−π, π], sorted per row); it returns the number of pieces, or a negative status
    (:func:`~qpik.analytic.intervals.check_sets`). An unreachable pose gives no pieces. With ``n_region[0] = k >= 0``
    (−1: none, as the call leaves it), the caller knows every feasible parameter to lie in the k pairs ``(lo, hi)``
    of :attr:`region` (rad, in [−π, π]; room for :data:`REGION`): gaps outside them are not evaluated. ``owner``
    keeps the buffers and the library alive.
    """

    function: int
    context: int
    pose: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    iv: np.ndarray
    count: np.ndarray
    region: np.ndarray
    n_region: np.ndarray
    owner: object


REGION = 256
"""Pairs of a :class:`NativeSets` region."""
