"""Closed-form inverse kinematics: every branch at a given δ (offset shoulder) or ψ (S-R-S)."""

from qpik.analytic.api import IKSolutions, feasible_intervals, ik, redundancy_parameter, solver_for
from qpik.analytic.intervals import FeasibleIntervals

__all__ = ["FeasibleIntervals", "IKSolutions", "feasible_intervals", "ik", "redundancy_parameter", "solver_for"]
