r"""What one control step of :class:`~qpik.control.controller.Controller` did: :class:`StepInfo`.

Its status (ok, recovering, penetrating, yielding, failed), the smallest clearances (m), the part of the
separating rows' demand given up (:mod:`qpik.control.failure_policy`), the frame task's pose error
``[m; rad]``, the solver's status and times (s), and, built when first read, the names of the constraints at
their bound (within :data:`ACTIVE_TOL`: rad/s for the box, the row's units for a row).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

ACTIVE_TOL = 1e-7  # rad/s (box) and row units: a constraint within this of its bound is reported active


@dataclass
class StepInfo:
    """What happened in the last control step.

    Attributes:
        status: ``"ok"``; ``"recovering"`` (started past a position limit or inside the
            safety distance, moving back); ``"penetrating"`` (a capsule overlaps an obstacle,
            d < 0; moving away); ``"yielding"`` (past a position limit, the return conflicts
            with the obstacle rows: it goes only as fast as they allow, see the failure
            policy); ``"failed"`` (no QP solution: the command nearest 0 that the velocity, acceleration and
            jerk limits allow was returned, ``v = 0`` without acceleration limits). When several
            hold, the first of failed, yielding, penetrating, recovering is reported.
        active: names of the constraints at their bound (``"joint3 position upper"``,
            ``"obstacle sphere0 / link4"``, ...).
        min_clearance: smallest capsule–obstacle signed distance, m, over the pairs :mod:`qpik.geometry.contacts`
            checks (not those whose distance no joint motion changes: a base column on its table;
            inf without such pairs).
        min_self_distance: smallest signed distance, m, of the pairs a
            :class:`~qpik.control.self_collision.SelfCollisionLimit` checks (inf without one); below its d_s
            the status is ``"recovering"``, below 0 ``"penetrating"``.
        relaxation: 0 if the QP was solved as built; else the part of the separating rows'
            demand that was dropped when they conflicted, in (0, 1] (1: only approach is forbidden;
            failure policy, step 4).
        task_error: norm of the first FrameTask's pose error ``[m; rad]`` (nan without one).
        solver_status: the solver's own status string.
        solve_time, total_time: seconds in the solver, and in the whole step.
        activity: what :attr:`active` is built from: the step's v (n,), a function giving the step's QP,
            and the controller's velocity limits (None when the step failed).
    """

    status: str = "ok"
    min_clearance: float = np.inf
    min_self_distance: float = np.inf
    relaxation: float = 0.0
    task_error: float = np.nan
    solver_status: str = ""
    solve_time: float = 0.0
    total_time: float = 0.0
    activity: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the constraints at their bound, built on first access."""
        if self.activity is None:
            return ()
        v, saved, caps = self.activity
        qp = saved()
        lb, ub, l, u = qp.lb, qp.ub, qp.l, qp.u
        Av = qp.A @ v
        gap_lo, gap_hi = Av - l, u - Av
        cap = [lim.range for lim in caps if lim.range is not None]

        def kind(j: int, bound: float, side: int) -> str:
            return "velocity" if any(bound == c[side][j] for c in cap) else "position"

        names = [f"joint{j + 1} {kind(j, lb[j], 0)} lower" for j in np.flatnonzero(v - lb < ACTIVE_TOL)]
        names += [f"joint{j + 1} {kind(j, ub[j], 1)} upper" for j in np.flatnonzero(ub - v < ACTIVE_TOL)]
        names += [qp.row_names[r] for r in np.flatnonzero((gap_lo < ACTIVE_TOL) | (gap_hi < ACTIVE_TOL))]
        return tuple(names)
