r"""The self-motion of a closed-form arm for one pose: q(δ/ψ), dq/dδ and Taylor models of q over ranges.

For each branch b of :meth:`~qpik.analytic.solver.AnalyticSolver.casadi_function`, two
row functions (:class:`~qpik.native.compiled.RowMap`, one row = a pose and a parameter or a range):

- :meth:`SelfMotion.points`: ``q_b(T, ψ)`` (n,), its exact derivative ``dq_b/dψ`` (CasADi)
  and whether the branch reaches the pose (:meth:`SelfMotion.point_function`); the branch is
  an input of each row (a CasADi switch over the branches), so rows of every branch share one call
  (:meth:`SelfMotion.values`: the same without dq/dψ, for the search's samples);
- :meth:`SelfMotion.models`: for a range [lo, hi] of ψ, the Taylor model of ``q_b(T, ψ)`` in
  :math:`t = (\psi - \psi_{mid})/h` (h the half width): centre, slope, radius and bounds (n each) such
  that every q over the range lies within them (:meth:`SelfMotion.taylor_function`,
  :func:`qpik.algebra.enclosure.taylor_function` of the same closed form); a switch over the branches too.
  A joint whose limits hold every wrapped angle (:attr:`SelfMotion.turned`) is that angle itself, which jumps by 2π
  where it passes ±π; ``turned=True`` gives its model as the same angle in (0, 2π] instead, continuous there.

Offset-shoulder arms have 16 branches, but branch k + 8 at δ is branch k at δ + π
(Nammoto & Kosuge 2012, eq. 7: θ1[2] = θ1[1] + π with the rest following), so only the
first 8 are searched (:attr:`SelfMotion.searched`); :meth:`SelfMotion.mirror` maps the others.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.enclosure import taylor_function
from qpik.analytic import closed_form_for
from qpik.native.build import concurrently
from qpik.native.compiled import Compiled, RowMap
from qpik.robots.robot import Robot

MIRRORED = {"offset_shoulder": 8}
"""Closed-form families whose branches k + half at a parameter are branch k at the parameter + π: half."""
CHUNKS = (128, 8)
"""Rows per call of the compiled self-motion functions (:class:`~qpik.native.compiled.RowMap`)."""
MODEL_CHUNKS = (16, 16)
"""The same for the Taylor models: one size, since they take seconds to compile."""


class SelfMotion:
    """The compiled self-motion functions of one robot (built per branch on first use; see the module).

    Attributes:
        solver: the closed-form solver.
        searched: the branches searched (output rows 0..searched-1 of the closed form).
        branch_ids: public ids of all branches.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.solver = closed_form_for(robot)
        self.branch_ids = np.array(self.solver.branch_ids)
        self.searched = MIRRORED.get(self.solver.kind, self.solver.n_branches)
        self.whole_turn = bool(np.any(np.asarray(robot.q_max) - np.asarray(robot.q_min) >= 2.0 * np.pi))
        """Some joint's range spans a whole turn (its configurations are the IK's representatives q + 2πk)."""
        self.turned = np.flatnonzero(self.solver.full_turn)
        """The joints whose limits hold every angle of (−π, π]: the IK gives that angle, which jumps by 2π where the
        joint passes ±π (:meth:`models` with ``turned``)."""
        self._sets_built = False

    def build_sets(self, T: np.ndarray) -> None:
        """Trace and compile the solver's feasible sets under shrunk limits, by evaluating them once at the pose
        ``T`` (4, 4); later calls do nothing."""
        if not self._sets_built:
            self.solver.feasible_intervals(T, 0.5)
            self._sets_built = True

    @cached_property
    def _symbols(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        T, psi = ca.SX.sym("T", 4, 4), ca.SX.sym(self.solver.param_name)
        Q, valid, _ = self.solver.casadi_function(T, psi)
        return T, psi, Q, valid

    def point_function(self, b: int) -> ca.Function:
        """Branch row b: ``(T (4, 4), ψ) -> [q (n); dq/dψ (n); valid]`` (2n + 1,)."""
        T, psi, Q, valid = self._symbols
        q = Q[b, :].T
        return ca.Function(
            f"selfmotion_{self.solver.kind}_{b}", [T, psi], [ca.densify(ca.vertcat(q, ca.jacobian(q, psi), valid[b]))]
        )

    def value_function(self, b: int) -> ca.Function:
        """Branch row b: ``(T (4, 4), ψ) -> [q (n); valid]`` (n + 1,): :meth:`point_function` without dq/dψ."""
        T, psi, Q, valid = self._symbols
        out = ca.densify(ca.vertcat(Q[b, :].T, valid[b]))
        return ca.Function(f"selfmotion_value_{self.solver.kind}_{b}", [T, psi], [out])

    def taylor_function(self, b: int, turned: bool = False) -> ca.Function:
        """Branch row b: the Taylor model of q over a range of ψ, ``(T, ψ centre, ψ slope, 0, lo, hi) ->
        (centre, slope, radius, lo, hi)`` of q (n each) (:func:`qpik.algebra.enclosure.taylor_function`); with
        ``turned``, the joints of :attr:`turned` as their angle in (0, 2π] (the joint is that angle or 2π less)."""
        T, psi, Q, _ = self._symbols
        q = [Q[b, j] for j in range(self.robot.dof)]
        if turned:
            q = [sy.CASADI.wrap(x - np.pi) + np.pi if j in self.turned else x for j, x in enumerate(q)]
        name = f"{self.solver.kind}_{b}" + ("_turned" if turned else "")
        fn = ca.Function(f"selfmotion_q_{name}", [T, psi], [ca.densify(ca.vertcat(*q))])
        return taylor_function(fn, [1], name=f"selfmotion_taylor_{name}")

    @cached_property
    def _point_map(self) -> RowMap:
        rows = [self.point_function(b) for b in range(self.searched)]
        return RowMap(_switch(f"selfmotion_{self.solver.kind}", rows), chunks=CHUNKS)

    @cached_property
    def _value_map(self) -> RowMap:
        rows = [self.value_function(b) for b in range(self.searched)]
        return RowMap(_switch(f"selfmotion_value_{self.solver.kind}", rows), chunks=CHUNKS)

    @cached_property
    def _model_map(self) -> RowMap:
        rows = [self.taylor_function(b) for b in range(self.searched)]
        return RowMap(_switch(f"selfmotion_taylor_{self.solver.kind}", rows), chunks=MODEL_CHUNKS)

    @cached_property
    def _turned_model_map(self) -> RowMap:
        rows = [self.taylor_function(b, turned=True) for b in range(self.searched)]
        return RowMap(_switch(f"selfmotion_taylor_{self.solver.kind}_turned", rows), chunks=MODEL_CHUNKS)

    @cached_property
    def point_call(self) -> Compiled:
        """:meth:`points`' function of one row, ``(b, T (4, 4), ψ) -> [q (n); dq/dψ (n); valid]``, compiled: for C code
        that evaluates rows one at a time (:mod:`qpik.nlp.levelset`)."""
        return Compiled(self._point_map.fn)

    def builds(self, models: bool = True) -> list[Callable[[], None]]:
        """The compiles of what :meth:`points` and :meth:`values` (and with ``models`` :meth:`models`, last) call,
        at every call size, to run now (:func:`qpik.native.build.concurrently`): later calls only evaluate."""
        return [m.build for m in (self._point_map, self._value_map, *([self._model_map] if models else []))]

    def build(self, models: bool = True, point_call: bool = False) -> None:
        """Trace and compile now what :meth:`points` and :meth:`values` (and with ``models`` :meth:`models`, with
        ``point_call`` :attr:`point_call`) call, at every call size: later calls only evaluate."""
        concurrently(*self.builds(models))
        if point_call:
            _ = self.point_call

    def points(self, b: np.ndarray, T: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Branch rows b (M,) at poses T (M, 16) (:func:`columns`) and parameters ψ (M,): q (M, n), dq/dψ (M, n),
        valid (M,) bool."""
        n = self.robot.dof
        (out,) = self._point_map(np.asarray(b, float), T, psi)
        return out[:, :n], out[:, n : 2 * n], out[:, 2 * n] > 0.5

    def values(self, b: np.ndarray, T: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`points` without dq/dψ: q (M, n), valid (M,) bool."""
        (out,) = self._value_map(np.asarray(b, float), T, psi)
        return out[:, :-1], out[:, -1] > 0.5

    def models(
        self, b: np.ndarray, T: np.ndarray, lo: np.ndarray, hi: np.ndarray, turned: bool = False
    ) -> list[np.ndarray]:
        """Branch rows b (M,) at poses T (M, 16) (:func:`columns`) over ψ ∈ [lo, hi] (M,): the Taylor models of q in
        t = (ψ − mid)/half, ``[centre, slope, radius, lo, hi]``, each (M, n); with ``turned``, the joints of
        :attr:`turned` as their angle in (0, 2π] (:meth:`taylor_function`; compiled on first use)."""
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        fn = self._turned_model_map if turned else self._model_map
        return fn(np.asarray(b, float), T, mid, half, np.zeros(len(lo)), lo, hi)

    def mirror(self, b: int) -> tuple[int, float] | None:
        """``(row, shift)`` when branch row b is row ``row`` at the parameter + ``shift`` (rad), else None."""
        if b < self.searched:
            return None
        return b - self.searched, np.pi


def _switch(name: str, rows: list[ca.Function]) -> ca.Function:
    """``(b, *inputs) -> rows[b](*inputs)``: a CasADi switch, so that one mapped call serves rows of every branch
    (a b outside 0..len(rows) - 2 selects the last)."""
    return ca.Function.conditional(name, rows[:-1], rows[-1])


def columns(T: np.ndarray) -> np.ndarray:
    """Poses (M, 4, 4) as rows of their 16 entries in column-major order (CasADi's)."""
    return np.ascontiguousarray(np.swapaxes(T, 1, 2)).reshape(len(T), 16)


def selfmotion_of(robot: Robot) -> SelfMotion:
    """The :class:`SelfMotion` of ``robot``, built once (``robot.cache``)."""
    return robot.cache.get("self-motion", SelfMotion, robot)
