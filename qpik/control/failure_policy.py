r"""The failure policy of :meth:`qpik.control.controller.Controller.step` (it never raises in the loop unless
``raise_on_failure=True``):

1. the main solver; if it reports no solution (e.g. OSQP stopping on a degenerate QP),
2. DAQP, an exact active-set solver (:data:`FALLBACK`), on the same QP;
3. if the QP is truly infeasible while the box excludes ``v = 0`` for a joint (``lb_j > 0`` or ``ub_j < 0``),
   safety wins: the *yielding* QP keeps every row and the caps, widens those joints' bounds to contain
   ``v = 0`` where the caps allow and asks for the box's velocity in the cost,
   :math:`w \sum_{j\ \rm forced} (v_j - r_j)^2` with :math:`r_j` the box's bound nearer 0 and ``w`` =
   :data:`YIELD_WEIGHT` × (1 + max diag P), above the tasks. For a joint past a position limit
   (:func:`position_forced`) the box's velocity is the return, recovered as fast as the obstacle rows allow
   and never further out (``last.status == "yielding"``); for a joint whose caps alone exclude 0 (moving
   faster than its acceleration limit can stop in one step) the caps cannot widen and it is braking at the
   acceleration limit: while rows conflict, the arm sheds the speed whose narrow acceleration box makes them
   conflict (the status is then the clearance's). The obstacle rows are bounded inside the widened box
   (:class:`~qpik.control.limits.obstacle.ObstacleLimit`), so only rows among themselves can still conflict;
4. if obstacle rows demand separation and conflict (an arm inside the safety distance of two
   obstacles on opposite sides, or a moving obstacle the arm must flee from two sides), the parts of the
   demands that recover from inside a safety distance are scaled first (the escape from a moving obstacle
   kept), and only if that is not enough the whole demands, each time by the largest common fraction that
   can be met: first 0 (for the whole demands: only forbid approach, which ``v = 0`` meets where the
   acceleration limits let the arm stop), then :data:`RELAX_STEPS` bisection steps toward 1, the fraction
   found times :data:`BACK_OFF` (``last.relaxation`` is the part dropped; the QP is then not at the edge of
   feasibility, where its set is too thin for the solvers): as much of the separating speed is kept as can
   be, since rows held at exactly zero approach let the second-order terms of the motion (see
   :class:`~qpik.control.limits.obstacle.ObstacleLimit`) creep closer;
5. otherwise the step returns the command nearest ``v = 0`` that the cap limits allow (their own box: the
   velocity limits and, where given, :class:`~qpik.control.limits_motion.AccelerationLimit` and
   :class:`~qpik.control.limits_motion.JerkLimit` around the last commands): ``v = 0`` without them (the arm
   holds still: never further past a limit, never toward an obstacle), else the arm brakes toward rest at those
   limits, which :class:`~qpik.control.limits_motion.BrakingLimit` leaves room for; ``last.status == "failed"``
   — or raises :class:`~qpik.core.errors.SolverError` with ``raise_on_failure=True``.

:func:`solve_with_fallbacks` runs steps 1 to 4; the controller returns step 5's stop when they find no solution.
"""

from __future__ import annotations

import numpy as np

from qpik.control.qp import QP
from qpik.control.solvers import Solver
from qpik.control.solvers.base import Solution

FALLBACK = "daqp"  # exact active-set solver tried when the main solver reports no solution
RELAX_STEPS = 6
"""Bisection steps on the fraction of their demand that separating rows keep when they conflict (failure policy)."""
BACK_OFF = 15 / 16
"""The fraction found by the bisection is kept times this (failure policy): not at the edge of feasibility."""
YIELD_WEIGHT = 1e3
"""Weight of the return from past a limit in the yielding QP, relative to 1 + the largest diagonal entry of P."""


def solve_with_fallbacks(
    solver: Solver, fallback: Solver | None, qp: QP, caps: tuple[np.ndarray, np.ndarray], recovery: np.ndarray
) -> tuple[Solution, QP, float, bool]:
    """Steps 1 to 4 of the policy: ``(solution, the QP solved, relaxation, yielding)``.

    ``solver`` the main solver, ``fallback`` the exact one (None: the main solver is it), ``caps`` the caps' own
    box ``(lo, hi)`` (n,) each, rad/s, ``recovery`` (m,), m/s, per row the part of its lower bound that asks to
    recover from inside its safety distance; ``relaxation`` the part of the separating demand dropped (0 if
    none), ``yielding`` whether the yielding QP was solved for a joint past a position limit. The solution may be
    not found (then step 5)."""
    sol = solver.solve(qp)
    exact = fallback or solver
    relaxation, yielding = 0.0, False
    if not sol.found and fallback is not None:
        sol = fallback.solve(qp)
    if not sol.found:
        forced = (qp.lb > 0.0) | (qp.ub < 0.0)
        if forced.any():  # the return from past a limit, or the braking of the caps, conflicts with the rows
            yielding = bool(position_forced(qp, *caps).any())
            qp = yielding_qp(qp, forced, *caps)
            sol = exact.solve(qp)
    if not sol.found and (qp.l > 0).any():  # separating rows conflict: ask less of them, down to no approach
        demand = np.maximum(qp.l, 0.0)
        # the recoveries from inside d_s first (an escape from a moving obstacle kept), then every demand
        for part in (np.minimum(recovery, demand), demand):
            if part.any():
                sol, kept = relax(exact, qp, part)
                if sol.found:
                    relaxation = 1.0 - kept
                    break
    return sol, qp, relaxation, yielding


def position_forced(qp: QP, cap_lo: np.ndarray, cap_hi: np.ndarray) -> np.ndarray:
    """(n,) bool: the joints whose box excludes ``v = 0`` by a bound that is not the caps' own (``cap_lo``,
    ``cap_hi``, rad/s): a position limit that makes the joint move back. A joint whose caps alone exclude 0 (it
    moves faster than its acceleration limit can stop in one step) is not: its box is the caps' own."""
    return ((qp.lb > 0.0) & (qp.lb > cap_lo)) | ((qp.ub < 0.0) & (qp.ub < cap_hi))


def relax(solver: Solver, qp: QP, part: np.ndarray) -> tuple:
    """``(solution, kept)``: ``qp`` solved with its lower bounds lowered by ``(1 - kept) · part`` (m,), ≥ 0, for
    the largest fraction ``kept`` that can be met (step 4), ``qp.l`` left so; kept 0 and no
    solution (``qp.l`` as given) if even ``l - part`` cannot."""
    rows = np.flatnonzero(part > 0.0)
    full, part = qp.l[rows].copy(), part[rows]
    qp.l[rows] = full - part
    sol = solver.solve(qp)
    if not sol.found:
        qp.l[rows] = full
        return sol, 0.0
    kept, above = 0.0, 1.0
    for _ in range(RELAX_STEPS):  # bisection on the fraction kept
        middle = 0.5 * (kept + above)
        qp.l[rows] = full - (1.0 - middle) * part
        trial = solver.solve(qp)
        if trial.found:
            kept, sol = middle, trial
        else:
            above = middle
    if kept > 0.0:  # backed off from the edge of feasibility, where the set is too thin for ADMM
        qp.l[rows] = full - (1.0 - BACK_OFF * kept) * part
        trial = solver.solve(qp)
        kept, sol = (BACK_OFF * kept, trial) if trial.found else (kept, sol)
    qp.l[rows] = full - (1.0 - kept) * part  # the QP solved (as StepInfo.active reads it)
    return sol, kept


def yielding_qp(
    qp: QP, forced: np.ndarray, cap_lo: np.ndarray | float = -np.inf, cap_hi: np.ndarray | float = np.inf
) -> QP:
    r"""The QP of step 3 of the policy (module docstring), as a new QP.

    ``forced`` (n,) bool marks the joints whose box excludes ``v = 0`` (past a position limit, or caps that
    exclude 0). Their bounds are widened toward 0 within the caps' own
    box ``[cap_lo, cap_hi]`` (``lb ← max(min(lb, 0), cap_lo)``, ``ub ← min(max(ub, 0), cap_hi)``: they
    may stop, where the acceleration limit lets them, but not move further out), and the cost gains
    :math:`w (v_j - r_j)^2` toward the velocity :math:`r_j` the box demanded (its bound
    nearer to 0), ``w`` = :data:`YIELD_WEIGHT` × (1 + max diag P): the return comes first,
    the tasks after it; every row is kept.
    """
    out = qp.copy()
    r = np.where(qp.lb > 0.0, qp.lb, qp.ub)
    out.lb[:] = np.maximum(np.minimum(out.lb, 0.0), cap_lo)
    out.ub[:] = np.minimum(np.maximum(out.ub, 0.0), cap_hi)
    w = YIELD_WEIGHT * (1.0 + float(np.abs(np.diagonal(qp.P)).max()))
    idx = np.flatnonzero(forced)
    out.P[idx, idx] += 2.0 * w
    out.c[idx] -= 2.0 * w * r[idx]
    return out
