r"""A certificate that the answer of :func:`qpik.solve_best` is the global minimum (to a tolerance).

The claim, for a pose with answer value :math:`f^*`: every ψ of every branch that keeps the
joints inside their limits and every link capsule at least :math:`d_s` from every obstacle has
:math:`f(\psi) \ge f^* - \varepsilon` (``tol``). Proof by branch and bound over the exact feasible
intervals (:func:`qpik.feasible_intervals`, which are exact: their ends are the analytic limit
crossings):

1. Cover every interval with cells of width :data:`FIRST_CELL` or less.
2. For each cell, a box of configurations containing :math:`q_b(\psi)` for every ψ of the cell:
   the interval extension of the closed form (:meth:`~qpik.nlp.selfmotion.SelfMotion.boxes`,
   :mod:`qpik.enclosure`). Over that box, the objective's rigorous lower bound
   (:meth:`qpik.objectives.Objective.lower_bound`: exact for the joint-limit margin and the
   reference distance, Lipschitz bounds for the clearance) bounds f from below on the cell, and upper
   bounds of the pair distances
   (:meth:`qpik.objectives.Box.distance_upper`) show cells where the clearance constraint fails.
3. A cell whose bound is :math:`\ge f^* - \varepsilon`, or where some pair is surely closer than
   :math:`d_s`, holds nothing better: it is dropped. The others are cut in :data:`SPLIT` and
   examined again, down to :data:`SMALLEST_CELL`.

If every cell is dropped, the answer is certified: its :attr:`~qpik.nlp.best.BestResult.gap`
(:math:`f^*` minus the smallest bound met) is at most ε. A cell that cannot be dropped at the
smallest width, or more than :data:`MAX_CELLS` cells, leaves it uncertified (the flag says so;
the answer is still the best found). A cell's test point (its left end, where the bound's
inputs are evaluated) that is feasible and better than :math:`f^* - \varepsilon` is returned as a
new start for the search, which then certifies again.

What the proof assumes: the feasible intervals are exact (up to :data:`qpik.analytic.intervals.SAME`,
1e-9 rad, below which a gap is not classified); the closed form is continuous on each
interval (it is, between the analytic breakpoints, where every joint crossing a limit or
wrapping through ±π is a breakpoint); the interval extension is evaluated in round-to-nearest
arithmetic (its bounds may be off by a few units in the last place, far below ε); the
objective's bound is one of the built-in ones (the manipulability and a user
:class:`~qpik.objectives.Expression` have none, so answers with them are never certified).

The bounds are first order in the cell width (the box of q is a few times wider than the
range of q on the cell): near a minimum where f is smooth, cells must shrink to about
:math:`\sqrt{\varepsilon / f''}`, so the tolerance is relative and loose by default
(``tol = 1e-4``: ε = 1e-4·max(1, |f|)) — tight enough to tell the branches and basins apart,
while the answer itself is a local minimum to 1e-13 rad. Kinks (where the epigraph terms of the
margin or the clearance switch) are cheap. With the default, ``qpik bench nlp`` reports how many
cells a certificate takes and how often it succeeds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qpik.nlp.scene import Points, Scene
from qpik.nlp.search import Pieces
from qpik.objectives import Box, lever_arms

FIRST_CELL = 0.4
"""Width (rad) of the first cells."""
SPLIT = 4
"""A cell that is kept is cut in this many."""
SMALLEST_CELL = 1e-9
"""Cells are not cut below this width (rad): one kept there leaves the answer uncertified."""
MAX_CELLS = 3_000
"""Most cells examined per pose."""


@dataclass
class Certificate:
    """Per pose: ``certified`` (bool), ``bound`` (the smallest lower bound met; -inf if none), ``cells``
    examined, ``reason`` (why not certified, "" if certified) and the feasible test points better than
    the answer (``better``, rows of :class:`Points`)."""

    certified: np.ndarray
    bound: np.ndarray
    cells: np.ndarray
    reason: list[str]
    better: Points | None


def certify(scene: Scene, pieces: Pieces, best: np.ndarray, tol: np.ndarray, poses: np.ndarray) -> Certificate:
    """Try to certify ``best`` (N,) to the tolerances ``tol`` (N,) for the poses ``poses`` (indices) over ``pieces``."""
    N = len(scene.poses)
    certified = np.zeros(N, bool)
    bound = np.full(N, np.inf)
    cells_used = np.zeros(N, int)
    reason = [""] * N
    todo = np.zeros(N, bool)
    todo[poses] = True
    if not scene.objective.bounded:
        for i in poses:
            reason[i] = "the objective has no lower bound over a box (a user expression)"
        return Certificate(certified, np.full(N, -np.inf), cells_used, reason, None)
    sel = todo[pieces.pose]
    width = pieces.hi[sel] - pieces.lo[sel]
    count = np.maximum(1, np.ceil(width / FIRST_CELL).astype(int))
    pose = np.repeat(pieces.pose[sel], count)
    row = np.repeat(pieces.row[sel], count)
    j = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    lo = np.repeat(pieces.lo[sel], count) + j * np.repeat(width / count, count)
    hi = np.minimum(lo + np.repeat(width / count, count), np.repeat(pieces.hi[sel], count))
    failed = np.zeros(N, bool)
    better: list[Points] = []
    lever = lever_arms(scene.robot)
    while len(lo):
        np.add.at(cells_used, pose, 1)
        pts = scene.evaluate(pose, row, lo)
        q_lo, q_hi = np.empty_like(pts.q), np.empty_like(pts.q)
        for b in np.unique(row):
            at = np.flatnonzero(row == b)
            q_lo[at], q_hi[at] = scene.selfmotion.boxes(int(b), scene.poses[pose[at]], lo[at], hi[at])
        box = Box(scene.robot, q_lo, q_hi, pts.q, pts.d, len(scene.obstacles), scene.q_ref[pose], lever)
        lb = scene.objective.lower_bound(box, scene.params)
        blocked = (box.distance_upper() < scene.d_safe).any(axis=1) if len(scene.obstacles) else np.zeros(len(lo), bool)
        good = (pts.c >= 0) & (pts.f < best[pose] - tol[pose])
        if good.any():
            better.append(pts.take(good))
            failed[pose[good]] = True
        keep = ~blocked & ~(lb >= best[pose] - tol[pose]) & ~failed[pose]
        dropped = ~blocked & ~keep
        np.minimum.at(bound, pose[dropped], lb[dropped])
        small = keep & (hi - lo <= SMALLEST_CELL)
        for i in np.unique(pose[small]):
            failed[i] = True
            reason[i] = f"a cell of width {SMALLEST_CELL:g} rad keeps a bound below the answer − tol"
        over = cells_used > MAX_CELLS
        for i in np.flatnonzero(over & ~failed & todo):
            failed[i] = True
            reason[i] = f"the bounds did not reach the tolerance within {MAX_CELLS} cells"
        keep &= ~failed[pose]
        if not keep.any():
            break
        k = np.flatnonzero(keep)
        step = (hi[k] - lo[k]) / SPLIT
        pose, row = np.repeat(pose[k], SPLIT), np.repeat(row[k], SPLIT)
        lo = np.repeat(lo[k], SPLIT) + np.tile(np.arange(SPLIT), len(k)) * np.repeat(step, SPLIT)
        hi = lo + np.repeat(step, SPLIT)
    for i in np.flatnonzero(todo):
        if not failed[i]:
            certified[i] = True
        elif not reason[i]:
            reason[i] = "a feasible point better than the answer was found"
    bound[~certified] = -np.inf
    return Certificate(certified, bound, cells_used, reason, Points.join(better) if better else None)
