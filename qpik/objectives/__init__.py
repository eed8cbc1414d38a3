r"""Objectives over a configuration ``q`` (n,), rad: one CasADi expression each, composable.

Shared by the NLPs (:mod:`qpik.nlp`: minimised over δ/ψ or over q) and the QP controller
(:class:`qpik.control.tasks.ObjectiveTask`: its gradient as a secondary task). Every
objective is a cost to *minimise*; :class:`Sum` adds them with weights (``2.0 * a + b``).

An objective writes its math once, :meth:`Objective.split`, against a :class:`Context` of
CasADi symbols (``q``, the robot's frames and Jacobian, the link-capsule/obstacle distances,
the reference configuration ``q_ref``) and its own parameter vector (weights, sharpness,
cap). Parameters, ``q_ref`` and the obstacle geometry are *inputs* of the compiled
functions, so changing them never recompiles. A split is a smooth part plus weighted maxima
of smooth pieces,

.. math:: f(q) = s(q) + \sum_k w_k \max_i h_{k,i}(q),\qquad w_k \ge 0,

so that an NLP can write each maximum in epigraph form (:math:`\min t_k` s.t.
:math:`t_k \ge h_{k,i}`) and stay smooth, and so that the certificate of :mod:`qpik.nlp.certificate`
can bound f over a range of configurations from Taylor models of s and of every piece
(:class:`BoundFunction`).

The objectives (units: the margin is unitless, distances in m, angles in rad):

- :class:`JointLimitMargin`: :math:`-\min_j \min(q_j - l_j, u_j - q_j)/\rho_j`,
  :math:`\rho_j = (u_j - l_j)/2` (0 on a limit, −1 at the middle of every range); epigraph
  form, or with ``smooth=True`` the soft minimum :math:`\tfrac1\beta\log\sum_i e^{-\beta g_i}`
  of the same 2n normalised distances :math:`g_i`;
- :class:`Manipulability`: :math:`-\log m(q)`, Yoshikawa's :math:`m = \sqrt{\det J J^T}`
  (``translational``: :math:`J_v`);
- :class:`Clearance`: :math:`-\min(c, \min_{k,o} d_{k,o}(q))` over every (link capsule k,
  obstacle o) pair, capped at ``cap`` = c (m); epigraph form or the soft minimum;
- :class:`ReferenceDistance`: :math:`\tfrac12 \sum_j w_j (q_j - q_{ref,j})^2`;
- :class:`Expression`: a user's CasADi expression of q.

What a person reads is the measured quantity, not the cost: each objective's
:attr:`Objective.quantity` (:class:`Quantity`) turns the minimised value f into it — the margin
:math:`-f` (maximised), the clearance :math:`-f` in m (maximised), the manipulability
:math:`e^{-f}` (maximised), the distance to q_ref f itself (minimised); a weighted sum of several
terms or a user's expression is shown as the objective f, minimised.
"""

from __future__ import annotations

from qpik.objectives.context import Context, clearance, pair_count
from qpik.objectives.objective import Objective, Sum
from qpik.objectives.quantity import Quantity
from qpik.objectives.split import Split
from qpik.objectives.terms import (
    NAMES,
    Clearance,
    Expression,
    JointLimitMargin,
    Manipulability,
    ReferenceDistance,
    resolve,
)

__all__ = [
    "NAMES",
    "Clearance",
    "Context",
    "Expression",
    "JointLimitMargin",
    "Manipulability",
    "Objective",
    "Quantity",
    "ReferenceDistance",
    "Split",
    "Sum",
    "clearance",
    "pair_count",
    "resolve",
]
