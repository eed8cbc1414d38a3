r"""The QP of one control step and its assembly from tasks and limits.

Decision variable: the joint velocity ``v`` (n,), rad/s:

.. math::

    \min_v\ \tfrac12 v^T P v + c^T v
    \quad\text{s.t.}\quad l \le A v \le u,\quad lb \le v \le ub

with :math:`P = \sum_i P_i + \epsilon I` (tasks; ε = 1e-12 keeps P definite for
active-set solvers, as mink's default damping), the box from the
:class:`~qpik.control.limits.base.BoxLimit` s and the rows from the
:class:`~qpik.control.limits.base.RowLimit` s, which see the final box (a row limit may
relax a row that the box makes unreachable, see
:class:`~qpik.control.limits.obstacle.ObstacleLimit`). No slack variable (the design notes say why).

Shapes are fixed for a controller (the rows of a limit that does not apply this step
are ``−∞ ≤ · ≤ +∞``), so a persistent solver keeps its sparsity pattern.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from qpik.control.inputs import Constant, Filler
from qpik.control.limits.base import BoxLimit, Limit, RowLimit
from qpik.control.state import SymState, kinematics_of
from qpik.control.tasks import Task
from qpik.core.layout import Blocks, Layout
from qpik.native.build import native_library
from qpik.native.compiled import Compiled

REGULARIZATION = 1e-12
LARGE = 512_000
"""Bytes of generated C up to which the step function is compiled at ``-O2``
(:func:`qpik.native.build.optimisation`; above, ``-O1``): it runs at every control step, and ``-O2`` makes it faster
at a compile cost that stays moderate up to this size (gcc's memory grows faster than the source beyond it)."""


@dataclass
class QP:
    """One QP in the form above (arrays are the assembler's buffers: copy to keep).

    Attributes:
        P: (n, n) symmetric positive definite cost matrix.
        c: (n,) linear cost.
        A: (m, n) constraint rows; l, u: (m,) their bounds (±inf where absent).
        lb, ub: (n,) box bounds on v.
        n: number of joint velocities.
        row_names: (m,) name of each row.
    """

    P: np.ndarray
    c: np.ndarray
    A: np.ndarray
    l: np.ndarray
    u: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    n: int
    row_names: tuple[str, ...] = ()

    def copy(self) -> QP:
        return QP(
            *(np.copy(a) for a in (self.P, self.c, self.A, self.l, self.u, self.lb, self.ub)), self.n, self.row_names
        )

    def cost(self, x: np.ndarray) -> float:
        """½ xᵀPx + cᵀx."""
        return float(0.5 * x @ self.P @ x + self.c @ x)

    def violation(self, x: np.ndarray) -> float:
        """Largest violation of the box and the rows at x (0 if feasible)."""
        r = self.A @ x
        return float(
            max(
                0.0,
                np.max(self.lb - x),
                np.max(x - self.ub),
                np.max(self.l - r, initial=0.0),
                np.max(r - self.u, initial=0.0),
            )
        )


class Assembler:
    """Composes the tasks' and limits' expressions into one compiled function of the step.

    At construction the kinematics (:meth:`SymState.of`), every task's ``(P_i, c_i)``,
    every box (intersected, then clipped into the caps) and every row limit's
    ``(A, l, u)`` (given the final box) are traced into ONE CasADi function
    ``q, p -> [P, c, lb, ub, A, l, u, extra]`` (flat, row-major), compiled to machine code
    (:mod:`qpik.native.compiled`); ``p`` stacks dt and the parameters of the tasks, limits and
    obstacles (read from the objects every step, so changing a target never recompiles).
    The compiled function is shared by controllers of the same structure.

    Args:
        robot: the arm (fixes n and the number of rows).
        tasks, limits: the controller's tasks and limits.
        dt: control period, s.
        extra: ``f(s) -> {name: SX}``, outputs appended after the QP (e.g. a pose error), read back by name
            from :attr:`extra`.

    Attributes:
        qp: the :class:`QP` filled by :meth:`build` (views into the output buffer).
        extra: the ``extra`` outputs by name (views into the output buffer, flat).
    """

    def __init__(self, robot, tasks: Sequence[Task], limits: Sequence[Limit], dt: float, extra=None):
        n = robot.dof
        self.n = n
        self.dt = float(dt)
        self.tasks = tuple(tasks)
        self.boxes = tuple(lim for lim in limits if isinstance(lim, BoxLimit) and not lim.cap)
        caps = [lim for lim in limits if isinstance(lim, BoxLimit) and lim.cap]
        self.caps = tuple(sorted(caps, key=lambda lim: lim.rank))  # the highest rank clips last and wins
        self.row_limits = tuple(lim for lim in limits if isinstance(lim, RowLimit))
        m = sum(lim.size(robot) for lim in self.row_limits)
        self.m = m
        self.row_names = tuple(nm for lim in self.row_limits for nm in lim.row_names(robot))
        kin = kinematics_of(robot)
        inputs, sizes, key = self._compose(kin, extra, trace=False)
        entry = kin.composed.get(key)
        if entry is None:
            traced = self._compose(kin, extra, trace=True)
            entry = kin.composed[key] = (traced, native_library(traced, large=LARGE))
        fn, lib = entry
        self._inputs = Filler(inputs)  # this assembler's numbers of the inputs, in the function's order
        self._fn = Compiled(fn, compile=False, library=lib)
        out = self._output_layout(sizes).views(self._fn.outputs[0])
        self._flat = out.qp
        self.qp = self._qp(self._flat)
        self.extra = Blocks({name: out[name] for name in sizes})

    def _qp_layout(self) -> Layout:
        """The QP's part of the output: :class:`QP`'s arrays by name."""
        n, m = self.n, self.m
        return Layout(P=(n, n), c=n, lb=n, ub=n, A=(m, n), l=m, u=m)

    def _output_layout(self, sizes: dict[str, int]) -> Layout:
        """The output: the QP's part, then the ``extra`` outputs by name (``sizes``: their lengths)."""
        return Layout(qp=self._qp_layout(), **sizes)

    def _qp(self, flat: np.ndarray) -> QP:
        """The QP whose arrays are views into ``flat`` (the QP's part of the output)."""
        return QP(**self._qp_layout().views(flat), n=self.n, row_names=self.row_names)

    def _compose(self, kin, extra, trace: bool):
        """The step function (``trace``), else ``(inputs, extra sizes, key)`` from free symbols (the inputs
        beyond q: :class:`~qpik.control.inputs.Input` s bound to this assembler's tasks, limits and obstacles)."""
        n = self.n
        q = ca.SX.sym("q", n)
        dt = ca.SX.sym("dt")
        s = SymState.of(kin, q, dt, trace)
        s.inputs.append(Constant(dt, (self.dt,)))
        P = REGULARIZATION * ca.SX.eye(n)
        c = ca.SX.zeros(n)
        for task in self.tasks:
            Pi, ci = task.bind(s)
            P, c = P + Pi, c + ci
        lb, ub = ca.SX.zeros(n) - ca.inf, ca.SX.zeros(n) + ca.inf
        for lim in self.boxes:
            lo, hi = lim.expr(s, lim.parameters(s))
            lb, ub = ca.fmax(lb, lo), ca.fmin(ub, hi)
        clo, chi = ca.SX.zeros(n) - ca.inf, ca.SX.zeros(n) + ca.inf
        for lim in self.caps:
            lo, hi = lim.expr(s, lim.parameters(s))
            lb, ub = ca.fmin(ca.fmax(lb, lo), hi), ca.fmin(ca.fmax(ub, lo), hi)
            clo, chi = ca.fmin(ca.fmax(clo, lo), hi), ca.fmin(ca.fmax(chi, lo), hi)
        s.caps = (clo, chi)
        A, lo, hi = [ca.SX(0, n)], [ca.SX(0, 1)], [ca.SX(0, 1)]
        for lim in self.row_limits:
            Ai, li, ui = lim.expr(s, lim.parameters(s), lb, ub)
            A.append(Ai)
            lo.append(li)
            hi.append(ui)
        A, lo, hi = ca.vertcat(*A), ca.vertcat(*lo), ca.vertcat(*hi)
        more = extra(s) if extra else {}
        sizes = {name: x.numel() for name, x in more.items()}
        if not trace:
            objects = (*self.tasks, *self.boxes, *self.caps, *self.row_limits)
            structure = tuple((type(o).__module__, type(o).__qualname__, o.structure()) for o in objects)
            key = (structure, tuple(inp.size for inp in s.inputs), tuple(sizes.items()), A.shape)
            return s.inputs, sizes, key
        qp = self._qp_layout().pack(P=P, c=c, lb=lb, ub=ub, A=A, l=lo, u=hi)
        out = ca.densify(self._output_layout(sizes).pack(qp=qp, **more))
        prm = ca.vertcat(*[inp.symbol for inp in s.inputs])
        tag = hashlib.sha256(repr(self._compose(kin, extra, trace=False)[2]).encode()).hexdigest()[:12]
        # cse: the self-collision rows and the summary trace the frames again; one evaluation of each subexpression
        return ca.Function(f"qp_{kin.robot.identifier}_{tag}", [q, prm], [out], {"cse": True})

    def snapshot(self, qp: QP) -> Callable[[], QP]:
        """A function giving ``qp`` as it is now, which later builds do not overwrite: for the assembler's own QP
        one copy of the output buffer now (the QP's views into it are made on call), for any other QP one
        :meth:`QP.copy` now (each call copies that copy)."""
        if qp is not self.qp:
            return qp.copy().copy
        return functools.partial(self._qp, self._flat.copy())

    def build(self, q: np.ndarray) -> QP:
        """Fill the QP for configuration ``q`` (n,), rad, and return it (the same object every call)."""
        self._fn(q, self._inputs())
        return self.qp
