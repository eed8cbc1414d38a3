r"""One round of the certified 1-D search of :mod:`qpik.analytic.locked_search` on a cell of its search variable:
the isolation step of the error function of a branch over the cell (:func:`step_function`), with its tolerances."""

from __future__ import annotations

import casadi as ca
import numpy as np

from qpik.algebra.enclosure import isolation_step

WINDOW = 1e-10
"""Width (rad) of a window of roots that is a candidate."""
SLACK = 1e-12
"""Added to every remainder: the round-off of the enclosures of values of order 1."""
TOUCH = 4 * SLACK
r"""An error function within this of 0 over a whole cell makes the cell's ends candidates: its model
:math:`|f_0| + |f_1| + r` then lies within the round-off :data:`SLACK` of each of its terms and of the window's test,
so that no round can tell the cell from a root (a double root, where the window stays the whole cell however it is
cut; above :data:`SLACK`, so that such a cell is touched before it is cut to nothing)."""
NEAR_WINDOW = 1e-3
"""Width (rad) of a window of roots that is a candidate on a near member's ideal chain: its roots are not the file's,
and each candidate is polished on the file's chain from the root of the window's linear model."""
NEAR_GAIN = 2.0
r"""Safety factor on the first-order bound :math:`D\,|\nabla_p e_b|_1` (at a cell's centre) of the change of an error
function of a near member between its ideal chain and the file's
(:attr:`~qpik.analytic.locked_search.LockedSearch.deviation`)."""


def step_function(
    model: ca.Function, signs: np.ndarray, gain: ca.Function | None = None, deviation: float = 0.0
) -> ca.Function:
    r"""One round of the search on a cell of a branch (:func:`~qpik.algebra.enclosure.isolation_step` with
    :data:`SLACK`, :data:`WINDOW`, :data:`TOUCH`; gone too where :math:`v_b < 0` over the cell) from ``model``, the
    Taylor models in x of :math:`(e_b, v_b)` of inputs (T, q7, x, signs). Inputs: T (4, 4; the search's pose,
    column-major), q7 (rad), the cell (3,): its ends a < b (rad) and its branch b (a row of ``signs``, (B, 2): the signs
    of the branch's subproblems' roots). Output (5,): the window's ends (rad), the branch, the cell's fate, and the
    point of the window where the model's linear part :math:`|f_0 + f_1 t|` is least (rad): its first three entries are
    the next cell's where the window is that.

    A near member (``gain``, :math:`|\nabla_p e_b|_1` of the same inputs, and ``deviation`` D > 0, m): the file's
    roots are the roots of the ideal chain's :math:`e_b` at a pose whose position is at most D away, so its slack and
    touch are :data:`SLACK` + :data:`NEAR_GAIN` :math:`D\,|\nabla_p e_b|_1` at the cell's centre (a cell goes only
    where the file's :math:`e_b` has no root either, to first order in D) and its window :data:`NEAR_WINDOW`."""
    T, q7, cell = ca.SX.sym("T", 4, 4), ca.SX.sym("q7"), ca.SX.sym("cell", 3)
    a, b, k = ca.vertsplit(cell)
    sign = sum((ca.fabs(k - i) < 0.5) * ca.DM(row) for i, row in enumerate(signs))  # the signs of row k of signs
    c, s, r, lo, hi = model(T, q7, 0.5 * (a + b), sign, 0.5 * (b - a), 0.0, a, b)
    if gain is None:
        slack, window, touch = SLACK, WINDOW, TOUCH
    else:
        slack = SLACK + NEAR_GAIN * deviation * gain(T, q7, 0.5 * (a + b), sign)
        window, touch = NEAR_WINDOW, slack
    x1, x2, fate = isolation_step(a, b, (c[0], s[0], r[0], lo[0], hi[0]), hi[1] < -SLACK, slack, window, touch)
    m, w = 0.5 * (a + b), 0.5 * (b - a)
    t = ca.if_else(ca.fabs(s[0]) > 0, -c[0] / s[0], 0.0)
    best = ca.fmin(ca.fmax(m + w * t, x1), x2)
    return ca.Function("locked_search_step", [T, q7, cell], [ca.vertcat(x1, x2, k, fate, best)])
