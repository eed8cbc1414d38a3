"""What an optimised plan is compared with, on the same waypoints, measured by the same checks.

- :func:`constant_parameter`: one closed-form branch at one constant δ/ψ along the whole path (Nammoto &
  Kosuge 2012, Figs. 15 and 16: δ = 0 and δ = 0.70; ψ = 0 for the iiwa). Where the branch does not reach a
  waypoint at that value its configuration misses the pose, which the FK check shows.
- :func:`online`: the QP controller tracking the same waypoints from the plan's first configuration
  (:func:`qpik.planning.track.track`).

The DP-only plan is :attr:`Plan.dp_plan <qpik.planning.plan.Plan.dp_plan>` (or the plan itself when the NLP
did not replace it).
"""

from __future__ import annotations

import numpy as np

from qpik.analytic import ik
from qpik.core.errors import InputError
from qpik.planning.plan import Plan, make_plan, measure
from qpik.planning.setup import Setup
from qpik.planning.track import track


def _setup(plan: Plan) -> Setup:
    if plan.setup is None:
        raise InputError("plan: it carries no setup (made by qpik.plan_self_motion)")
    return plan.setup


def constant_parameter(plan: Plan, value: float, branch: int, mujoco: bool = True) -> Plan:
    """Branch ``branch`` (public id) at the constant parameter ``value`` (rad) at every waypoint of ``plan``."""
    setup = _setup(plan)
    sols = ik(setup.robot, setup.poses, float(value))
    hits = np.flatnonzero(sols.branch == int(branch))
    if not len(hits):
        raise InputError(f"branch: no branch {branch}; the branches are {sols.branch.tolist()}")
    q = sols.q[:, hits[0]]
    continuous = np.ones(len(q) - 1, bool)
    sym = {"delta": "δ", "psi": "ψ"}[sols.param_name]
    out = make_plan(setup, q, "baseline", param=np.full(len(q), float(value)), branch=np.full(len(q), int(branch)),
                    param_name=sols.param_name, cost=setup.cost(q, continuous),
                    label=f"constant {sym} = {value:g} (branch {branch})")  # fmt: skip
    measure(out, mujoco)
    return out


def online(plan: Plan, mujoco: bool = True) -> Plan:
    """The QP controller tracking ``plan``'s waypoints from its first configuration (the online baseline)."""
    setup = _setup(plan)
    if not len(plan.q):
        raise InputError("plan: no planned configuration to start from")
    q = track(setup, plan.q[0])
    out = make_plan(setup, q, "baseline", cost=setup.cost(q, np.ones(len(q) - 1, bool)), label="QP controller (online)")
    measure(out, mujoco)
    return out
