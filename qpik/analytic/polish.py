r"""Newton's method on a chain's own FK, the redundancy joint held: a closed form's branches made exact on a file.

A model file whose axes miss a closed-form family by rounding (an rpy written as 1.5708) gets the closed form of
the nearest ideal geometry (:func:`qpik.robots.locked_joint.ideal_chain`); its branches then miss the pose on the
file's own chain by about that deviation (µm, µrad). :func:`polish` removes it: with q7 fixed, the six joints
1-6 and the six pose equations, each step

.. math:: (J^T J + \lambda I)\,\Delta q = J^T e,\qquad
          e = \begin{pmatrix} p^* - p(q) \\ \tfrac12\,\mathrm{vee}\big(R^* R(q)^T - R(q) R^{*T}\big) \end{pmatrix},

with J the geometric Jacobian's columns 1-6 (base frame, ``[v; ω]`` of the end-effector origin) and :math:`\lambda` =
:data:`DAMPING` (Levenberg 1944: the step stays bounded where J is singular; elsewhere it changes the step by a
relative :math:`\lambda/\sigma_{\min}^2`). The linear system is solved by :math:`LDL^T`
(:func:`qpik.algebra.symbolic.solve_spd`; symmetric positive definite: no pivoting), so that the steps are written
once against :mod:`qpik.algebra.symbolic` and run on numpy batches and CasADi symbols alike. Newton converges
quadratically from a start within about the deviation: :data:`STEPS` steps take a 1e-4 error to round-off. The
residual after the last step (the largest entry of :math:`p^* - p(q)` and :math:`R^* - R(q)`) is returned, for the
caller's validity flag.
"""

from __future__ import annotations

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Mat, Ops, Scalar, Vec
from qpik.robots.chain import SerialChain

STEPS = 4
"""Newton steps of :func:`polish` by default."""
DAMPING = 1e-12
r""":math:`\lambda` of :func:`polish` (m² and rad², the units of :math:`J^T J`'s entries)."""
RESIDUAL_TOL = 1e-11
"""Largest residual (m for the position, none for the rotation matrix's entries) of a polished branch that reaches
the pose."""
STEP_MAX = 0.5
"""Largest change of one joint in one step (rad): from a start far from any answer (an unreachable pose) the steps
stay bounded and q finite."""


def _error(chain: SerialChain, R: Mat, p: Vec, q: list[Scalar], ops: Ops) -> tuple[list, list[Scalar], Scalar]:
    """The frames of ``chain`` at q, the pose error e (6 scalars, module docstring) and the residual: the largest
    entry of :math:`p^* - p(q)` and :math:`R^* - R(q)` (m and 1), which a turn by π about some axis, where e's
    rotation part vanishes, does not pass."""
    frames = chain.frames_expr(q, ops)
    Rq, pq = frames[-1]
    m = [[sy.dot(R[i], Rq[j]) for j in range(3)] for i in range(3)]  # R* R(q)^T
    w = [0.5 * (m[2][1] - m[1][2]), 0.5 * (m[0][2] - m[2][0]), 0.5 * (m[1][0] - m[0][1])]
    dp = sy.vsub(p, pq)
    residual = ops.fabs(dp[0])
    for x in [*dp[1:], *(R[i][j] - Rq[i][j] for i in range(3) for j in range(3))]:
        residual = ops.fmax(residual, ops.fabs(x))
    return frames, [*dp, *w], residual


def polish(
    chain: SerialChain, R: Mat, p: Vec, q: list[Scalar], ops: Ops, steps: int = STEPS
) -> tuple[list[Scalar], Scalar]:
    """``steps`` (≥ 1) Newton steps on ``chain``'s FK toward the pose ``(R, p)`` (base frame) from ``q`` (7 scalars,
    rad), the last joint held; returns the joints (not wrapped) and the residual (m and rad) at them."""
    q = list(q)
    frames, e, _ = _error(chain, R, p, q, ops)
    for _ in range(steps):
        jv, jw = chain.jacobian_expr(frames)
        cols = [(*jv[j], *jw[j]) for j in range(6)]
        A = [[sum((a * b for a, b in zip(cols[i], cols[j])), 0.0) for j in range(i + 1)] for i in range(6)]
        for i in range(6):
            A[i][i] = A[i][i] + DAMPING
        dq = sy.solve_spd(A, [sum((a * b for a, b in zip(cols[i], e)), 0.0) for i in range(6)])
        q = [q[j] + ops.fmax(ops.fmin(dq[j], STEP_MAX), -STEP_MAX) for j in range(6)] + q[6:]
        frames, e, residual = _error(chain, R, p, q, ops)
    return q, residual
