"""Figures of qpik's results, drawn on matplotlib ``Figure`` objects (never pyplot state).

- :mod:`qpik.plots.closed_form`: self-motion maps, sweeps and stick figures of the closed form;
- :mod:`qpik.plots.runs`: closed-loop runs in MuJoCo (errors, clearance, joints, snapshot strips);
- :mod:`qpik.plots.objective`: the objective of :func:`qpik.solve_best` against δ/ψ for every branch.

The maths packages (:mod:`qpik.analytic`, :mod:`qpik.control`, ...) import none of this.
"""

from qpik.plots.files import save

__all__ = ["save"]
