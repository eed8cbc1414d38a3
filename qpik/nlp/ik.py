r"""Numerical inverse kinematics of every arm: :func:`solve_ik`.

For a target pose :math:`T^*` (4, 4, base frame) and a start :math:`q_0` (n,), find q inside
the joint limits with :math:`\|e(q)\| \le` ``tol``, where

.. math:: e(q) = [p^* - p(q);\ \log(R^* R(q)^T)] \quad (6,),\ \text{m; rad, base frame}

(:func:`qpik.algebra.lie.pose_error`). A start inside the limits that already meets ``tol`` is the
answer. Otherwise, one of two ways:

- **Closed form** (the default where ``robot.closed_form`` is set: ``nammoto7`` in δ,
  ``iiwa14`` in ψ). q₀'s branch b₀ and parameter s₀ (δ or ψ, :func:`qpik.redundancy_parameter`),
  and the exact feasible set of every branch for the pose (:func:`qpik.feasible_intervals`) give
  the answer: ``qpik.ik`` on b₀ at s₀ itself if s₀ lies in b₀'s set (tried first, without the sets: b₀ valid
  inside the limits at s₀), else at whichever of the
  two ends of the gap around s₀ (:data:`EDGE` inside) gives the q nearer q₀. It is exact to
  ~1e-12 and, while s₀ stays in b₀'s set, continuous in the pose (away from singular
  configurations, near which q moves fast with the pose at fixed δ/ψ) and equal to q₀ at
  q₀'s own pose. If b₀'s set is empty, the same two ends on every branch compete. If every
  set is empty and the sets are proved, no configuration inside the limits reaches the pose (up to the sets' 1e-9
  rad resolution, ``"unreachable"``); one Levenberg–Marquardt attempt from q₀ then gives the smallest error to report
  (or the answer, should it find one). Where they are not proved (a near member's, the 1-D search's sampled ones)
  a failed attempt is ``"not found"``.
- **Levenberg–Marquardt** (the default for ``zheng7`` and ``panda``, see :data:`CLOSED_FORM_DEFAULT`; possible on
  every arm).
  With :math:`G = -\partial e/\partial q = [J_v;\ J_l^{-1}(-\omega) J_\omega]` (6, n) (geometric
  Jacobian J, :math:`\omega = \log(R^* R^T)`, :func:`residual_expr`), each iteration takes the
  damped Gauss–Newton step

  .. math:: \Delta q = G^T (G G^T + \lambda I_6)^{-1} e, \qquad \lambda = c\,\|e\|^2 + \bar\lambda,

  the damping proportional to the squared error as in Sugihara 2011 (large far from the
  target, vanishing near it: quadratic convergence at a regular solution), c = :data:`DAMPING`,
  :math:`\bar\lambda` = :data:`DAMPING_FLOOR`. Joint limits: a joint whose step would cross its
  limit is held at the limit and the step is solved again for the others, the held joints'
  motion moved into the right-hand side (:data:`PASSES` solves per iteration, the first steps
  of an active-set method on the box); q is then clipped into the limits, so every iterate is
  inside them. :data:`CHUNK` iterations are one compiled call (CasADi generates C; about 1 µs
  per iteration). An attempt that reduces the error by less than a factor 1/:data:`STALL`
  over a chunk, or runs :data:`ATTEMPT_ITERS` iterations, has stalled and stops: the next
  starts from a configuration drawn uniformly within the limits, every third one from the
  best configuration so far perturbed by :data:`PERTURB` rad per joint. The generator is
  seeded: for a given seed and ``max_iters`` the answer is reproducible.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Literal

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.lie import pose_error_expr, so3_ljacinv_expr
from qpik.analytic.api import closed_form_for as closed_form_solver
from qpik.analytic.api import ik
from qpik.core.errors import InputError, NoClosedFormError, UnreachableError
from qpik.core.validate import finite_array, joint_vector
from qpik.core.validate import pose as check_pose
from qpik.native.compiled import Compiled
from qpik.nlp.options import MAX_ITERS, IKOptions, Method

CLOSED_FORM_DEFAULT = ("srs", "offset_shoulder")
"""The families whose closed form is :func:`solve_ik`'s default: their exact feasible sets take tens of µs. The
locked-q7 sets (the Panda) sweep q7 (~20 ms a pose), so there Levenberg–Marquardt is the default and
``method="closed form"`` the choice."""

if TYPE_CHECKING:
    from qpik.analytic.intervals import Interval
    from qpik.robots.robot import Robot

TOL = 1e-10
"""Default tolerance on ‖e‖ (m and rad together)."""
CHUNK = 8
"""Levenberg–Marquardt iterations per compiled call (the stall test runs between calls)."""
ATTEMPT_ITERS = 96
"""Iterations after which an attempt that has not converged counts as stalled."""
STALL = 0.5
"""An attempt whose error after a chunk exceeds STALL times its error after the previous chunk has stalled."""
DAMPING = 0.2
"""c of the damping λ = c‖e‖² + λ̄ (per m² or rad²)."""
DAMPING_FLOOR = 1e-9
"""λ̄: the damping left at the solution (keeps G Gᵀ + λI invertible at a singular configuration)."""
PASSES = 2
"""Linear solves per iteration: the free step, then the step with the joints that crossed a limit held there."""
PERTURB = 0.3
"""Standard deviation (rad) of the perturbation of the best configuration, every third restart."""
EDGE = 1e-7
"""How far (rad of δ/ψ) inside a feasible interval the closed-form answer is taken when the nearest point is an end."""

Status = Literal["ok", "unreachable", "not found"]


@dataclass
class IKResult:
    """What :meth:`IKSolver.solve` found.

    Attributes:
        q: (n,) configuration, rad, inside the joint limits: the answer if ``status == "ok"``,
            else the configuration with the smallest pose error found.
        status: ``"ok"`` (‖e‖ ≤ tol); ``"unreachable"`` (the closed form proves that no configuration
            inside the limits reaches the pose: every branch's feasible set is empty); ``"not found"``
            (Levenberg–Marquardt spent its budget, ``max_iters`` or ``max_time``, without reaching tol).
        residual: ‖e(q)‖ (m and rad together), ``e = [p* − p; log(R* Rᵀ)]``.
        method: ``"closed form"`` or ``"levenberg-marquardt"``.
        iterations: Levenberg–Marquardt iterations over all attempts (0 for the closed form alone).
        attempts: Levenberg–Marquardt attempts (start points) tried.
        branch, param: the closed-form branch and δ/ψ (rad) of the answer, or None when the closed form
            did not give it (another method, or q0 returned as it is because it reaches the pose).
    """

    q: np.ndarray
    status: Status
    residual: float
    method: Method
    iterations: int = 0
    attempts: int = 0
    branch: int | None = None
    param: float | None = None


def residual_expr(robot: Robot, q: ca.SX, target: ca.SX) -> tuple[ca.SX, ca.SX]:
    r"""The pose error and its negated Jacobian as SX: ``(e (6,), G (6, n))``, :math:`G = -\partial e/\partial q`.

    :math:`e = [p^* - p;\ \omega]`, :math:`\omega = \log(R^* R^T)`. With the world-frame angular
    velocity :math:`w = J_\omega \dot q`, :math:`\dot R = [w]_\times R` and
    :math:`\tfrac{d}{dt}(R^* R^T) = -(R^* R^T)[w]_\times`, so
    :math:`\dot\omega = -J_r^{-1}(\omega)\, w` with :math:`J_r^{-1}(\omega) = J_l^{-1}(-\omega)`;
    hence :math:`G = [J_v;\ J_l^{-1}(-\omega) J_\omega]`.
    """
    T, J = robot.chain.casadi_functions["fk_jacobian"](q)
    e = pose_error_expr(target, T)
    G = ca.vertcat(J[:3, :], ca.mtimes(so3_ljacinv_expr(-e[3:]), J[3:, :]))
    return e, G


def step_expr(robot: Robot, q: ca.SX, target: ca.SX) -> ca.SX:
    """One Levenberg–Marquardt iteration (module docstring) as SX: the next q (n,), inside the limits, from q (n,)
    toward the pose ``target`` (4, 4)."""
    lo, hi = ca.DM(robot.q_min), ca.DM(robot.q_max)
    e, G = residual_expr(robot, q, target)
    err2 = ca.dot(e, e)
    damping = DAMPING * err2 + DAMPING_FLOOR
    free = ca.SX.ones(robot.dof)
    held = ca.SX.zeros(robot.dof)  # motion of the joints held at a limit
    dq = held
    for _ in range(PASSES):
        Gf = G * ca.repmat(free.T, 6, 1)
        A, r = ca.mtimes(Gf, Gf.T) + damping * ca.SX.eye(6), e - ca.mtimes(G, held)
        y = ca.vertcat(*sy.solve_spd([[A[i, j] for j in range(6)] for i in range(6)], [r[i] for i in range(6)]))
        dq = held + free * ca.mtimes(Gf.T, y)
        nxt = q + dq
        cross = free * ca.logic_or(nxt < lo, nxt > hi)
        held = held + cross * (ca.fmin(ca.fmax(nxt, lo), hi) - q)
        free = free * (1 - cross)
    return ca.fmin(ca.fmax(q + dq, lo), hi)


class IKSolver:
    """Inverse kinematics of one arm (module docstring); :func:`solve_ik` uses one per robot (:func:`ik_solver_for`).

    Holds the compiled Levenberg–Marquardt chunk and pose error of the arm, built on first use
    (C generated by CasADi, compiled once and cached on disk: :mod:`qpik.native.compiled`).

    Args:
        robot: the arm.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.lock = threading.RLock()
        """Held around the solver's compiled calls, which evaluate in buffers of their own: threads may share it."""

    @cached_property
    def _chunk(self) -> Compiled:
        """``(q (n,), T (4, 4)) -> (q after CHUNK iterations, ‖e‖ there)``, compiled.

        One iteration is an SX function; CasADi's ``mapaccum`` loops it CHUNK times in the
        generated C (compiled once, quickly, and as fast as the iterations written out).
        """
        n = self.robot.dof
        q, t = ca.SX.sym("q", n), ca.SX.sym("T", 16)
        step = ca.Function("step", [q, t], [step_expr(self.robot, q, ca.reshape(t, 4, 4))])
        qm, Tm = ca.MX.sym("q", n), ca.MX.sym("T", 4, 4)
        x = step.mapaccum("steps", CHUNK)(qm, ca.repmat(ca.vec(Tm), 1, CHUNK))[:, -1]
        return Compiled(ca.Function(f"ik_lm_{self.robot.identifier}", [qm, Tm], [x, self._error_function(x, Tm)]))

    @cached_property
    def _error_function(self) -> ca.Function:
        """``(q (n,), T (4, 4)) -> ‖e(q)‖`` as an SX function."""
        q, T = ca.SX.sym("q", self.robot.dof), ca.SX.sym("T", 4, 4)
        e = pose_error_expr(T, self.robot.chain.casadi_functions["fk"](q))
        return ca.Function(f"ik_error_{self.robot.identifier}", [q, T], [ca.norm_2(e)])

    @cached_property
    def _error(self) -> Compiled:
        """:attr:`_error_function`, compiled."""
        return Compiled(self._error_function)

    def residual(self, q: np.ndarray, pose: np.ndarray) -> float:
        """‖e(q)‖ of ``q`` (n,) toward ``pose`` (4, 4) (m and rad together)."""
        with self.lock:
            return float(self._error(q, pose)[0][0])

    def solve(
        self,
        pose: np.ndarray,
        q0: np.ndarray,
        *,
        tol: float = TOL,
        max_iters: int = MAX_ITERS,
        max_time: float | None = None,
        seed: int = 0,
        project: bool = False,
        method: Method | None = None,
    ) -> IKResult:
        """:func:`solve_ik` with its status: never raises for a pose it does not reach (see :attr:`IKResult.status`)."""
        robot = self.robot
        T = check_pose(pose, "pose", project)[0]
        if T.ndim != 2:
            raise InputError(f"pose: expected shape (4, 4), got {T.shape}")
        q, batched = joint_vector(q0, robot.dof, "q0")
        if batched:
            raise InputError(f"q0: expected shape ({robot.dof},), got {q.shape}")
        tol = float(finite_array(tol, "tol", ()))
        if tol <= 0:
            raise InputError(f"tol: must be > 0, got {tol}")
        if not isinstance(max_iters, int | np.integer) or max_iters < 1:
            raise InputError(f"max_iters: must be an integer >= 1, got {max_iters!r}")
        if max_time is not None and float(finite_array(max_time, "max_time", ())) <= 0:
            raise InputError(f"max_time: must be > 0 or None, got {max_time}")
        if method is None:
            method = "closed form" if robot.closed_form in CLOSED_FORM_DEFAULT else "levenberg-marquardt"
        if method not in ("closed form", "levenberg-marquardt"):
            raise InputError(f"method: 'closed form', 'levenberg-marquardt' or None, got {method!r}")
        if method == "closed form" and not robot.closed_form:
            raise NoClosedFormError(f"method: {robot.name} has no closed form; use 'levenberg-marquardt'")
        with self.lock:  # the compiled calls' buffers are the solver's
            deadline = math.inf if max_time is None else time.perf_counter() + max_time
            start = np.clip(q, robot.q_min, robot.q_max)
            if (start == q).all():  # q0 inside the limits already at the pose: it is the answer
                residual = self.residual(q, T)
                if residual <= tol:
                    return IKResult(q.copy(), "ok", residual, method)
            if method == "levenberg-marquardt":
                return self._levenberg_marquardt(T, start, tol, int(max_iters), deadline, seed)
            found, feasible, proved = self._closed_form(T, q)
            if found is not None and found.residual <= tol:
                return found
            if found is not None:  # a singular case of the closed form, or tol below its accuracy: polish
                return self._levenberg_marquardt(T, found.q, tol, int(max_iters), deadline, seed)
            if feasible:  # a feasible set whose candidates all failed the limit test: iterate instead
                return self._levenberg_marquardt(T, start, tol, int(max_iters), deadline, seed)
            # no branch is feasible: where the sets are proved, nothing inside the limits reaches the pose (up to
            # their 1e-9 rad resolution); one attempt from q0 gives the smallest error to report
            res = self._levenberg_marquardt(T, start, tol, min(int(max_iters), ATTEMPT_ITERS), deadline, seed)
            if res.status != "ok" and proved:
                res.status = "unreachable"
            return res

    # ---- closed form ------------------------------------------------------------

    def _closed_form(self, T: np.ndarray, q0: np.ndarray) -> tuple[IKResult | None, bool, bool]:
        """The closed-form answer chosen from q0's branch and parameter (module docstring), or None; whether any
        branch has a feasible set; and whether the sets are proved (``FeasibleIntervals.proved``: a near member's or
        the 1-D search's are not, so their being empty proves nothing). ``T`` (4, 4) is a checked pose (not checked
        again here)."""
        robot = self.robot
        solver = closed_form_solver(robot)
        with solver.lock:  # its compiled calls' buffers, shared with the public closed-form functions
            param0, branch0 = (x[0] for x in solver.parameter(q0[None]))
        at = ik(robot, T, float(param0))
        here = np.flatnonzero(at.branch == branch0)
        if here.size and at.valid[here[0]] and at.within_limits[here[0]]:  # s0 lies in b0's set: no sets needed
            q = at.q[here[0]].copy()
            res = IKResult(q, "ok", self.residual(q, T), "closed form", branch=int(branch0), param=float(at.param))
            return res, True, True
        with solver.lock:
            sets = solver.feasible_intervals(T)
        k0 = sets.index(branch0)
        rows = [k0] if sets.intervals[k0] else [k for k, iv in enumerate(sets.intervals) if iv]
        cands = [(k, param, iv) for k in rows for param, iv in _candidates(sets.intervals[k], param0)]
        if not cands:
            return None, False, sets.proved
        params = np.array([param for _, param, _ in cands])
        with solver.lock:
            sol = solver.solve_many(T, params)  # every branch at each candidate parameter, one call
        best: tuple[float, int, float, np.ndarray] | None = None
        for i, (k, param, (lo, hi)) in enumerate(cands):
            q = sol.q[i, k]
            if not sol.within_limits[i, k]:  # an end sits on a limit to round-off: take its interval's middle
                param = 0.5 * (lo + hi)
                again = ik(robot, T, param)
                if not again.within_limits[k]:
                    continue
                q = again.q[k]
            dist = float(np.linalg.norm(q - q0)) if len(cands) > 1 else 0.0
            if best is None or dist < best[0]:
                best = (dist, k, param, q.copy())
        if best is None:
            return None, True, sets.proved
        _, k, param, q = best
        res = IKResult(q, "ok", self.residual(q, T), "closed form", branch=int(sets.branch[k]), param=param)
        return res, True, sets.proved

    # ---- Levenberg–Marquardt ----------------------------------------------------

    def _levenberg_marquardt(
        self, T: np.ndarray, q: np.ndarray, tol: float, max_iters: int, deadline: float, seed: int
    ) -> IKResult:
        robot = self.robot
        chunk = self._chunk
        Tf = np.asarray(T, dtype=float).reshape(-1, order="F")
        best_q, best = q.copy(), self.residual(q, T)
        iterations = attempts = 0
        rng: np.random.Generator | None = None
        while best > tol and iterations < max_iters and time.perf_counter() < deadline:
            if attempts:
                if rng is None:
                    rng = np.random.default_rng(seed)
                if attempts % 3 == 0:
                    q = np.clip(best_q + rng.normal(0.0, PERTURB, robot.dof), robot.q_min, robot.q_max)
                else:
                    q = rng.uniform(robot.q_min, robot.q_max)
            attempts += 1
            previous = math.inf
            for _ in range(ATTEMPT_ITERS // CHUNK):
                x, err = chunk(q, Tf)
                iterations += CHUNK
                q, err = x.copy(), float(err[0])
                if err < best:
                    best, best_q = err, q
                if err <= tol or err > STALL * previous or iterations >= max_iters:
                    break
                previous = err
        status = "ok" if best <= tol else "not found"
        return IKResult(best_q, status, best, "levenberg-marquardt", iterations, attempts)


def ik_solver_for(robot: Robot) -> IKSolver:
    """The :class:`IKSolver` of ``robot``, built once (``robot.cache``)."""
    return robot.cache.get("numerical ik", IKSolver, robot)


def solve_ik(
    robot: Robot,
    pose: np.ndarray,
    q0: np.ndarray,
    *,
    tol: float = TOL,
    project: bool = False,
    options: IKOptions | None = None,
) -> np.ndarray:
    """A configuration q (n,), rad, inside the joint limits, with the end-effector at ``pose``.

    The closed form for arms that have one, else Levenberg–Marquardt with restarts (module docstring);
    :meth:`IKSolver.solve` returns the same answer with its status and counts instead of raising.

    Args:
        robot: any arm.
        pose: (4, 4) target pose of the end-effector, base frame.
        q0: (n,) start configuration, rad (clipped into the limits where the iteration starts from it).
        tol: the answer has ‖[p* − p; log(R* Rᵀ)]‖ ≤ tol (m and rad together).
        project: project a non-orthonormal rotation onto SO(3) instead of raising :class:`qpik.RotationError`.
        options: the iteration and time budget, the seed and the method (:class:`~qpik.nlp.options.IKOptions`;
            default its defaults).

    Returns:
        q (n,), rad, with every joint in ``[q_min, q_max]``.

    Raises:
        UnreachableError: the closed form proves that no configuration inside the limits reaches the pose,
            or the iteration spent its budget; the message gives the smallest pose error found.
        InputError: NaN/inf, wrong shapes, a bad tol, budget or method.
        NoClosedFormError: ``method="closed form"`` for an arm without one.
    """
    o = IKOptions() if options is None else options
    if not isinstance(o, IKOptions):
        raise InputError(f"options: expected IKOptions, got {type(options).__name__}")
    res = ik_solver_for(robot).solve(
        pose, q0, tol=tol, max_iters=o.max_iters, max_time=o.max_time, seed=o.seed, project=project, method=o.method
    )
    if res.status == "unreachable":
        raise UnreachableError(
            "solve_ik: no configuration inside the joint limits reaches the pose (the feasible set of every "
            f"closed-form branch is empty); smallest pose error found {res.residual:.3g} (m, rad)"
        )
    if res.status != "ok":
        raise UnreachableError(
            f"solve_ik: smallest pose error {res.residual:.3g} (m, rad) after {res.attempts} attempts and "
            f"{res.iterations} iterations (tol {tol:g})"
        )
    return res.q


def _candidates(intervals: list[Interval], x: float) -> list[tuple[float, Interval]]:
    """Where to evaluate the closed form on a branch with these feasible ``intervals`` (rad, in (-π, π]), each with
    its interval: ``x`` itself if it lies in one of them (:data:`EDGE` inside), else the two ends, EDGE inside,
    of the gap around ``x`` on the circle (the first feasible value above x and the last one below it)."""
    up = down = None
    for lo, hi in intervals:
        inset = min(EDGE, 0.5 * (hi - lo))
        a, b = lo + inset, hi - inset
        if a <= x <= b:
            return [(x, (lo, hi))]
        rise, fall = (a - x) % (2 * math.pi), (x - b) % (2 * math.pi)
        if up is None or rise < up[0]:
            up = (rise, a, (lo, hi))
        if down is None or fall < down[0]:
            down = (fall, b, (lo, hi))
    if up is None or down is None:
        return []
    return [(up[1], up[2])] if up[1] == down[1] else [(up[1], up[2]), (down[1], down[2])]
