"""Analytic inverse kinematics: every branch at a given redundancy parameter (ψ of S-R-S arms, δ of the offset
shoulder, a locked joint in closed form or by a certified 1-D search), and its feasible sets."""

from qpik.analytic.api import IKSolutions, closed_form_for, feasible_intervals, ik, redundancy_parameter
from qpik.analytic.intervals import FeasibleIntervals

__all__ = ["FeasibleIntervals", "IKSolutions", "closed_form_for", "feasible_intervals", "ik", "redundancy_parameter"]
