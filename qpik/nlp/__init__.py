"""Optimisation over the self-motion and over the joints.

- :func:`solve_best`: the best closed-form branch and δ/ψ for a pose, certified (:mod:`qpik.nlp.best`; on the 1-D
  search's arms sampled and polished, :mod:`qpik.nlp.best_sampled`);
- :func:`solve_full`: the full-joint NLP (7 variables, pose equality) for every arm (:mod:`qpik.nlp.full`);
- :class:`BestOptions`, :class:`FullOptions`, :class:`IKOptions`: their solver settings (:mod:`qpik.nlp.options`);
- :func:`solve_ik`: numerical inverse kinematics for every arm (:mod:`qpik.nlp.ik`).
"""

from qpik.nlp.best import solve_best
from qpik.nlp.best_result import BestResult, BestResults, BranchOptimum
from qpik.nlp.full import FullResult, solve_full
from qpik.nlp.ik import IKResult, IKSolver, solve_ik
from qpik.nlp.options import BestOptions, FullOptions, IKOptions

__all__ = [
    "BestOptions",
    "BestResult",
    "BestResults",
    "BranchOptimum",
    "FullOptions",
    "FullResult",
    "IKOptions",
    "IKResult",
    "IKSolver",
    "solve_best",
    "solve_full",
    "solve_ik",
]
