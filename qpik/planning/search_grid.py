r"""The DP's states for an arm whose branches :func:`qpik.ik` finds per pose (the 1-D search's ``"locked_search"``
family, :mod:`qpik.analytic.locked_search`, and the general 6-R's ``"locked_general"``): the same grid of the parameter
(the locked joint) on every slot at every waypoint as :class:`~qpik.planning.grid.Grid`'s, its states found by one
search per waypoint and grid value.

The family has no expressions of the parameter and no feasible sets, so a state (k, b, i) is *inside* where the
search finds slot b at waypoint k and grid value i within the joint limits (not the grid values inside an exact set:
a set narrower than the grid step may hold none, and an empty grid proves nothing); it is feasible where, beside
that, every link capsule is at least ``d_safe`` from every obstacle and from its checked pairs (the point objective
and the clearances of :meth:`~qpik.planning.grid.Grid.point_terms`, compiled over the states' configurations). A
slot keeps its solution along the parameter between the search's renumbering events (the module docstring there),
and the DP's transitions across slots cover those.
"""

from __future__ import annotations

from functools import cached_property

import casadi as ca
import numpy as np

from qpik.analytic.intervals import FeasibleIntervals
from qpik.core.progress import Progress
from qpik.native.compiled import RowMap
from qpik.objectives import Context
from qpik.planning.grid import UNCHECKED, Grid, Layers

CHUNKS = (64, 16)
"""States per call of the compiled point terms."""


class SearchGrid(Grid):
    """The DP's grid of an arm of the 1-D search's family (see the module docstring): the arguments and attributes of
    :class:`~qpik.planning.grid.Grid`, :attr:`intervals` None. ``progress``: say how far the searches are on stderr."""

    def __init__(self, scene, poses: np.ndarray, resolution: int, progress: bool = True):
        self._progress = progress
        super().__init__(scene, poses, resolution)

    def _feasible(self) -> tuple[list[FeasibleIntervals] | None, np.ndarray]:
        """No sets; :attr:`inside` from the searches, whose configurations (N, B, G, n) are kept (:attr:`_q`)."""
        N, B, G, n = len(self.poses), self.rows, self.G, self.robot.dof
        self._q = np.zeros((N, B, G, n))
        inside = np.zeros((N, B, G), bool)
        said = Progress(f"qpik.ik at {G} values of {self.param_name} per waypoint, waypoint", N, self._progress)
        for k, T in enumerate(self.poses):
            said(k)
            sol = self.solver.solve_many(T, self.values)  # (G, B, n), (G, B)
            self._q[k], inside[k] = sol.q.transpose(1, 0, 2), sol.within_limits.T
        said.finish()
        return None, inside

    @cached_property
    def _terms(self) -> RowMap:
        """``(q (n), objective params, q_ref (n), obstacle input) -> (f, smallest clearance)`` over rows of states."""
        robot = self.robot
        q, q_ref = ca.SX.sym("q", robot.dof), ca.SX.sym("q_ref", robot.dof)
        p = ca.SX.sym("p", self.objective_params.size)
        prm = ca.SX.sym("obstacles", self.obstacle_layout.size)
        given = self.obstacle_layout.symbols(prm)
        ctx = Context(robot, q, q_ref, self.obstacles, given.params, self_pairs=self.self_pairs)
        f, clear = self.point_terms(ctx, p, (1.0 - given.checked) * UNCHECKED)
        d = ca.mmin(clear) if clear.numel() else ca.SX(np.inf)
        fn = ca.Function(f"plan_point_terms_{robot.identifier}", [q, p, q_ref, prm], [ca.vertcat(f, d)])
        return RowMap(fn, shared=(1, 2, 3), chunks=CHUNKS)

    def build(self) -> None:
        """Compile the point terms now (the searches ran when the grid was made)."""
        self._terms.build()

    def layers(self, k0: int, k1: int) -> Layers:
        """The states of waypoints k0 .. k1 - 1 (:class:`~qpik.planning.grid.Layers`): the point terms evaluated only
        at the states :attr:`inside`."""
        inside = self.inside[k0:k1]
        q = self._q[k0:k1]
        f, clear = np.full(inside.shape, np.inf), np.full(inside.shape, -np.inf)
        if inside.any():
            (out,) = self._terms(q[inside], self.objective_params, self.q_ref, self.obstacle_input)
            f[inside], clear[inside] = out[:, 0], out[:, 1]
        ok = inside & (clear >= self.d_safe) & np.isfinite(f)
        return Layers(q, ok, np.where(ok, f, np.inf))

    def configurations(self, ks: np.ndarray, rows: np.ndarray, index: np.ndarray) -> np.ndarray:
        """(M, n) the configurations of the states (waypoint ks, slot, grid index) (M,) each."""
        return self._q[ks, rows, index].copy()
