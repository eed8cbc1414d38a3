"""Public closed-form API: ``ik``, ``redundancy_parameter``, ``feasible_intervals``."""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

import numpy as np

from qpik.analytic.branch_solver import BranchSolver
from qpik.analytic.intervals import FeasibleIntervals, wrap
from qpik.core.errors import InputError, NoClosedFormError
from qpik.core.validate import finite_array, joint_vector, number
from qpik.core.validate import pose as check_pose
from qpik.robots.robot import Robot, as_robot

_SOLVERS = {  # family -> (solver, its feasible sets), each as (module, class or factory)
    "offset_shoulder": (("qpik.analytic.offset_shoulder", "OffsetShoulderSolver"),
                        ("qpik.analytic.offset_shoulder_intervals", "DeltaIntervals")),
    "srs": (("qpik.analytic.srs", "SRSSolver"), ("qpik.analytic.srs_intervals", "PsiIntervals")),
    "locked_joint": (("qpik.analytic.locked_joint_reversed", "locked_joint_solver"),
                     ("qpik.analytic.locked_joint_intervals", "Q7Intervals")),
    "locked_search": (("qpik.analytic.search_solver", "SearchSolver"), ("qpik.analytic.sampled_sets", "SampledSets")),
    "locked_general": (("qpik.analytic.general_solver", "GeneralSolver"),
                       ("qpik.analytic.sampled_sets", "SampledSets")),
}  # fmt: skip
SYMBOL = {"delta": "δ", "psi": "ψ"}
"""The Greek letter of each redundancy parameter name (:attr:`IKSolutions.param_name`)."""


def symbol(param_name: str) -> str:
    """The Greek letter of a redundancy parameter name (``"delta"`` -> ``"δ"``)."""
    return SYMBOL.get(param_name, param_name)


def closed_form_for(robot: Robot) -> BranchSolver:
    """The closed-form solver of ``robot`` (cached per robot object).

    Raises:
        InputError: ``robot`` is not a :class:`~qpik.robots.robot.Robot` (e.g. its name).
        NoClosedFormError: the arm has no closed form.
    """
    return as_robot(robot).cache.get("closed form", _new_solver, robot)


def _new_solver(robot: Robot) -> BranchSolver:
    if robot.closed_form not in _SOLVERS:
        why = (
            robot.notes
            if robot.notes.startswith("no closed form")
            else "only offset-shoulder, S-R-S, locked-q7 and locked-q1 arms, the 1-D search's and the general 6-R's do"
        )
        raise NoClosedFormError(f"{robot.name} has no closed-form IK ({why}); use qpik.solve_ik instead")
    (module, cls), sets = _SOLVERS[robot.closed_form]
    make_sets = getattr(importlib.import_module(sets[0]), sets[1])
    return getattr(importlib.import_module(module), cls)(robot, sets=make_sets)


@dataclass(slots=True)
class IKSolutions:
    """Every closed-form branch for one pose (or a batch of poses).

    Attributes:
        q: joint angles (rad, wrapped to (-pi, pi]): (B, n) or (N, B, n). Rows of
            invalid branches are finite but meaningless.
        valid: (B,) or (N, B) bool, the branch reaches the pose.
        within_limits: (B,) or (N, B) bool, valid and inside the joint limits.
        singular: (B,) or (N, B) bool, a singular case (defined, documented result).
        branch: (B,) public branch ids (Nammoto & Kosuge 2012 Table 2 numbers 1-16, S-R-S 0-7, locked joint 0-7,
            or the slots 0-15 of the 1-D search, :mod:`qpik.analytic.locked_search`, and of the general 6-R,
            :mod:`qpik.analytic.general_solver`); read-only, shared by every result of the arm.
        param: the redundancy parameter (rad): float or (N,).
        param_name: ``"delta"``, ``"psi"``, or the locked joint ``"q7"`` or ``"q1"``.
    """

    q: np.ndarray
    valid: np.ndarray
    within_limits: np.ndarray
    singular: np.ndarray
    branch: np.ndarray
    param: float | np.ndarray
    param_name: str

    def __len__(self) -> int:
        return self.q.shape[-2]

    def table(self) -> str:
        """A text table of the branches of a single pose (degrees are not used: rad)."""
        if self.q.ndim != 2:
            raise InputError("table() needs a single pose; index a batch first")
        head = f"{'branch':>6} " + " ".join(f"{'q' + str(j + 1):>7}" for j in range(self.q.shape[1]))
        lines = [head + "  valid  limits  singular"]
        for i, b in enumerate(self.branch):
            row = " ".join(f"{v:7.3f}" for v in self.q[i])
            flags = f"{'yes' if self.valid[i] else 'no':>6} {'in' if self.within_limits[i] else 'out':>6}"
            lines.append(f"{b:>6} {row} {flags} {'yes' if self.singular[i] else '':>8}")
        return "\n".join(lines)


def ik(robot: Robot, pose: np.ndarray, param: float | np.ndarray, project: bool = False) -> IKSolutions:
    """All closed-form branches for ``pose`` at redundancy parameter ``param``.

    Args:
        robot: an arm with a closed form (``nammoto7``: δ, ``iiwa14``: ψ, ``panda``: q7) or served by the 1-D search
            (``robot.closed_form`` ``"locked_search"``, the Sawyer: q1; the branches are its roots, milliseconds per
            pose, :mod:`qpik.analytic.locked_search`) or by the general 6-R (``"locked_general"``, the YuMi, TIAGo
            Pro: q7; one eigenproblem per pose, :mod:`qpik.analytic.general_solver`).
        pose: end-effector pose in the base frame, (4, 4) or (N, 4, 4).
        param: δ or ψ in rad: a real number (a float or an int, a numpy scalar, a 0-d array: one compiled
            path for all), or (N,) for a batch (a number is broadcast over the batch).
        project: project a non-orthonormal rotation onto SO(3) instead of
            raising :class:`qpik.RotationError`.

    An unreachable pose gives ``valid = False`` rows, never an exception.
    """
    solver = closed_form_for(robot)
    if project is False and (fast := solver.fresh_one) is not None and (out := fast(pose, param)) is not None:
        # a single pose and one real δ/ψ (a float, an int, a numpy scalar or a 0-d array), checked in C
        q, flags = out  # flags (3, B): valid, singular, within limits (indexing beats unpacking the rows)
        par = param if type(param) is float else float(param)
        return IKSolutions(q, flags[0], flags[2], flags[1], solver.branch_array, par, solver.param_name)
    T, batched = check_pose(pose, "pose", project)
    if type(param) is not float:
        try:
            kind = np.asarray(param).dtype.kind
        except (ValueError, TypeError) as exc:  # a ragged sequence
            raise InputError(f"param: cannot be read as a float array ({exc})"[:200]) from None
        if kind == "b":
            raise InputError(f"param: expected δ/ψ in rad, got {param!r}"[:200])
    if not batched:
        if type(param) is float and math.isfinite(param):
            par: float | np.ndarray = param  # the common case, without conversions
        else:
            p = finite_array(param, "param")
            if p.ndim != 0:
                raise InputError(f"param: expected a float for a single pose, got shape {p.shape}")
            par = float(p)
        with solver.lock:
            sol = solver.solve_one(T, par)
    else:
        p = finite_array(param, "param")
        par = np.full(T.shape[0], float(p)) if p.ndim == 0 else finite_array(p, "param", (T.shape[0],))
        with solver.lock:
            sol = solver.solve_batch(T, par)
    return IKSolutions(
        q=sol.q,
        valid=sol.valid,
        within_limits=sol.within_limits,
        singular=sol.singular,
        branch=solver.branch_array,
        param=par,
        param_name=solver.param_name,
    )


def redundancy_parameter(robot: Robot, q: np.ndarray) -> tuple[float | np.ndarray, int | np.ndarray]:
    """The redundancy parameter (rad) and branch id of a configuration (n,) or batch (N, n).

    ``q`` may be given unwrapped (any ``q + 2πk``): it is wrapped to (−π, π] first, as ``ik`` returns it.
    """
    solver = closed_form_for(robot)
    qa, batched = joint_vector(q, robot.dof)
    with solver.lock:
        param, branch = solver.parameter(wrap(np.atleast_2d(qa)))
    if batched:
        return param, branch
    return float(param[0]), int(branch[0])


def feasible_intervals(robot: Robot, pose: np.ndarray, project: bool = False, margin: float = 0.0) -> FeasibleIntervals:
    r"""Per branch, the set of the parameter (δ, ψ, q7 or q1; rad) keeping all joints in limits; see
    :class:`FeasibleIntervals`. Exact for the S-R-S and offset-shoulder families; the locked-q7 family's are proved
    per pose by a bounded search, and ``proved`` says whether it ended (:mod:`qpik.analytic.locked_joint_intervals`;
    never for a near member, a file polished onto the family).

    ``margin`` m >= 0: keeping every joint j in the shrunk limits :math:`[l_j + m\rho_j,\ u_j - m\rho_j]`,
    :math:`\rho_j = (u_j - l_j)/2` instead: the set where the joint-limit margin
    (:class:`qpik.objectives.JointLimitMargin`) is at least m (empty for m > 1).
    """
    solver = closed_form_for(robot)
    T, batched = check_pose(pose, "pose", project)
    if batched:
        raise InputError("pose: feasible_intervals takes one pose (4, 4)")
    m = number(margin, "margin")
    with solver.lock:
        return solver.feasible_intervals(T, m)
