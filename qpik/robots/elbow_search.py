r"""Recognising the geometry of the 1-D search over the first joint
(:class:`~qpik.analytic.search_geometry.ElbowSearch`): the Rethink Sawyer of robosuite's file, read from the flange.

In the search's order (the arm read from the flange, :func:`~qpik.robots.locked_joint.reversed_chain`, joint k the
arm's joint 8 − k; or the arm itself), with q7 locked, the geometry is

- axes 3 and 4 meet in one point C (not parallel);
- axes 5 and 6 meet in one point W (not parallel);
- C lies off axis 2 and W off axis 4 (by more than :data:`~qpik.robots.locked_joint.NEAR_TOL`): otherwise the
  search's subproblems 3 (about axis 2) and 2 (about C) degenerate.

Axes 1-2, 2-3, 4-5 and 6-7 may be offset. The Sawyer's file has axes 7-6 (of the arm) 0.8 µm apart, so the geometry
of :class:`~qpik.analytic.search_geometry.ShoulderSearch` fits it only as a near member; this one needs its axes 5-4
and 3-2, which meet exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qpik.robots.chain import SerialChain
from qpik.robots.locked_joint import MEET_TOL, NEAR_TOL, feet, off_line


@dataclass(frozen=True)
class ElbowSearchGeometry:
    """The constants of :class:`~qpik.analytic.search_geometry.ElbowSearch`, in the search's order, base frame at
    q = 0 (m, unit vectors).

    Attributes:
        h: (7, 3) unit joint axes.
        o: (7, 3) a point on each axis.
        elbow: (3,) C, where axes 3 and 4 meet.
        wrist: (3,) W, where axes 5 and 6 meet.
        home: (4, 4) the end-effector pose at q = 0.
        reversed: the geometry is that of the arm read from the flange (the arm's q1 is locked).
    """

    h: np.ndarray
    o: np.ndarray
    elbow: np.ndarray
    wrist: np.ndarray
    home: np.ndarray
    reversed: bool = False


def find_elbow_search(chain: SerialChain, reversed: bool = False) -> tuple[ElbowSearchGeometry | None, str]:
    """The geometry of the module docstring in ``chain`` (7 revolute joints, in the search's order), or None and the
    reason in one line; ``reversed``: ``chain`` is the arm read from the flange (its axis k the arm's axis 8 − k, said
    so in the reason)."""
    h, o = chain.axes(np.zeros(7))
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    k = (lambda i: 8 - i) if reversed else (lambda i: i)  # the arm's number of the chain's axis i
    points = []
    for i in (2, 4):
        normal = feet(o[i], h[i], o[i + 1], h[i + 1])
        if normal is None:
            return None, f"axes {k(i + 1)}-{k(i + 2)} are parallel"
        if (gap := float(np.linalg.norm(normal[1] - normal[0]))) > MEET_TOL:
            return None, f"axes {k(i + 1)}-{k(i + 2)} do not meet ({1000 * gap:.4g} mm apart)"
        points.append(normal[0])
    C, W = points
    if off_line(C, o[1], h[1]) <= NEAR_TOL:
        return None, f"the point where axes {k(3)}-{k(4)} meet lies on axis {k(2)}"
    if off_line(W, o[3], h[3]) <= NEAR_TOL:
        return None, f"the point where axes {k(5)}-{k(6)} meet lies on axis {k(4)}"
    return ElbowSearchGeometry(h, o, C, W, chain.fk(np.zeros(7)), reversed), ""
