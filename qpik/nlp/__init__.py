"""Optimisation over the self-motion: the best closed-form branch and δ/ψ (:func:`solve_best`), certified."""

from qpik.nlp.best import BestResult, BestResults, BranchOptimum, solve_best

__all__ = ["BestResult", "BestResults", "BranchOptimum", "solve_best"]
