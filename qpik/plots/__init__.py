"""Figures of qpik's results, drawn on matplotlib ``Figure`` objects (never pyplot state).

- :mod:`qpik.plots.closed_form`: self-motion maps, sweeps and stick figures of the closed form;
- :mod:`qpik.plots.runs`: closed-loop runs in MuJoCo (errors, clearance, joints, snapshot strips).

The maths packages (:mod:`qpik.analytic`, :mod:`qpik.control`, ...) import none of this.
"""

from qpik.plots.files import save

__all__ = ["save"]
