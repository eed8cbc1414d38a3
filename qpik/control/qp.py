r"""The QP of one control step and its assembly from tasks and limits.

Decision variable: the joint velocity ``v`` (n,), rad/s:

.. math::

    \min_v\ \tfrac12 v^T P v + c^T v
    \quad\text{s.t.}\quad l \le A v \le u,\quad lb \le v \le ub

with :math:`P = \sum_i P_i + \epsilon I` (tasks; ε = 1e-12 keeps P definite for
active-set solvers, as mink's default damping), the box from the
:class:`~qpik.control.limits.BoxLimit` s and the rows from the
:class:`~qpik.control.limits.RowLimit` s, which see the final box (a row limit may
relax a row that the box makes unreachable, see
:class:`~qpik.control.limits.ObstacleLimit`). No slack variable: a shared slack with an
exact penalty was tried and measured to slow OSQP from ~40 to ~450–2500 ADMM iterations
per step (the penalty dominates the problem's scaling).

Shapes are fixed for a controller (the rows of a limit that does not apply this step
are ``−∞ ≤ · ≤ +∞``), so a persistent solver keeps its sparsity pattern.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from qpik.control.limits import BoxLimit, Limit, RowLimit
from qpik.control.state import State
from qpik.control.tasks import Task

REGULARIZATION = 1e-12


@dataclass
class QP:
    """One QP in the form above (arrays are the assembler's buffers: copy to keep).

    Attributes:
        P: (n, n) symmetric positive definite cost matrix.
        c: (n,) linear cost.
        A: (m, n) constraint rows; l, u: (m,) their bounds (±inf where absent).
        lb, ub: (n,) box bounds on v.
        n: number of joint velocities.
        row_names: (m,) name of each row.
    """

    P: np.ndarray
    c: np.ndarray
    A: np.ndarray
    l: np.ndarray
    u: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    n: int
    row_names: tuple[str, ...] = ()

    def copy(self) -> QP:
        return QP(
            *(np.copy(a) for a in (self.P, self.c, self.A, self.l, self.u, self.lb, self.ub)), self.n, self.row_names
        )

    def cost(self, x: np.ndarray) -> float:
        """½ xᵀPx + cᵀx."""
        return float(0.5 * x @ self.P @ x + self.c @ x)

    def violation(self, x: np.ndarray) -> float:
        """Largest violation of the box and the rows at x (0 if feasible)."""
        r = self.A @ x
        return float(
            max(
                0.0,
                np.max(self.lb - x),
                np.max(x - self.ub),
                np.max(self.l - r, initial=0.0),
                np.max(r - self.u, initial=0.0),
            )
        )


class Assembler:
    """Builds the QP of each step into preallocated buffers.

    Args:
        robot: the arm (fixes n and the number of rows).
        tasks, limits: the controller's tasks and limits.
    """

    def __init__(self, robot, tasks: Sequence[Task], limits: Sequence[Limit]):
        n = robot.dof
        self.tasks = tuple(tasks)
        self.boxes = tuple(lim for lim in limits if isinstance(lim, BoxLimit) and not lim.cap)
        self.caps = tuple(lim for lim in limits if isinstance(lim, BoxLimit) and lim.cap)
        self.row_limits = tuple(lim for lim in limits if isinstance(lim, RowLimit))
        sizes = [lim.size(robot) for lim in self.row_limits]
        self.slices = []
        start = 0
        for m in sizes:
            self.slices.append(slice(start, start + m))
            start += m
        m = start
        names = tuple(nm for lim in self.row_limits for nm in lim.row_names(robot))
        self.qp = QP(
            P=np.zeros((n, n)),
            c=np.zeros(n),
            A=np.zeros((m, n)),
            l=np.full(m, -np.inf),
            u=np.full(m, np.inf),
            lb=np.full(n, -np.inf),
            ub=np.full(n, np.inf),
            n=n,
            row_names=names,
        )
        self._reg = REGULARIZATION * np.eye(n)  # P starts from εI

    def build(self, state: State) -> QP:
        """Fill the QP for ``state`` and return it (the same object every call)."""
        qp = self.qp
        P, c = qp.P, qp.c
        np.copyto(P, self._reg)
        c.fill(0.0)
        for task in self.tasks:
            Pi, ci = task.compute(state)
            P += Pi
            c += ci
        lb, ub = qp.lb, qp.ub
        lb.fill(-np.inf)
        ub.fill(np.inf)
        for lim in self.boxes:
            lo, hi = lim.bounds(state)
            np.maximum(lb, lo, out=lb)
            np.minimum(ub, hi, out=ub)
        for lim in self.caps:
            lo, hi = lim.bounds(state)
            np.minimum(np.maximum(lb, lo, out=lb), hi, out=lb)  # clip into the cap (np.clip is slower)
            np.minimum(np.maximum(ub, lo, out=ub), hi, out=ub)
        for lim, sl in zip(self.row_limits, self.slices):
            A, lo, hi = lim.rows(state, lb, ub)
            qp.A[sl] = A
            qp.l[sl] = lo
            qp.u[sl] = hi
        return qp
