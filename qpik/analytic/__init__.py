"""Closed-form inverse kinematics: every branch at a given δ (offset shoulder) or ψ (S-R-S)."""

from qpik.analytic.api import IKSolutions, closed_form_for, feasible_intervals, ik, redundancy_parameter
from qpik.analytic.intervals import FeasibleIntervals

__all__ = ["FeasibleIntervals", "IKSolutions", "closed_form_for", "feasible_intervals", "ik", "redundancy_parameter"]
