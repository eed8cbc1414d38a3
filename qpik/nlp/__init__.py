"""Optimisation over configurations: numerical inverse kinematics (:func:`solve_ik`)."""

from qpik.nlp.ik import IKResult, IKSolver, solve_ik

__all__ = ["IKResult", "IKSolver", "solve_ik"]
