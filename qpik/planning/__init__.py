"""Offline self-motion planning along an end-effector path.

- :func:`plan_self_motion`: DP over the exact feasible intervals, refined by a sparse NLP, for closed-form
  arms; the QP controller's run refined by the same NLP for the others (:mod:`qpik.planning.planner`);
- :class:`PlanOptions`: how it plans (joint-step bounds, grid, NLP, checks) (:mod:`qpik.planning.options`);
- :class:`Plan`: the answer, its checks, CSV/NPZ files and :meth:`Plan.retime` (toppra) (:mod:`qpik.planning.plan`);
- :mod:`qpik.planning.baselines`: constant δ/ψ and the online QP controller on the same waypoints;
- :func:`qpik.planning.many.plan_many`: many paths of one arm, in local processes or on a Dask cluster
  (:mod:`qpik.planning.batch`, which also runs ``qpik plan``'s problem files).
"""

from qpik.planning.options import PlanOptions
from qpik.planning.plan import Check, Plan, Trajectory
from qpik.planning.planner import plan_self_motion

__all__ = ["Check", "Plan", "PlanOptions", "Trajectory", "plan_self_motion"]
