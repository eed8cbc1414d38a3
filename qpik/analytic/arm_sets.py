"""The feasible sets of an arm's closed form as one C call each: the breakpoint function's and the checked IK's
generated C, the wrist roots where there are some, and the gap classification (``intervals.c``), with no numpy
in between.

:class:`ArmSetsCall` is the call over buffers allocated once, :class:`DeltaSetsCall` that of the offset-shoulder
arm (``offset_shoulder_intervals.c``, :mod:`qpik.analytic.offset_shoulder_intervals`) and :class:`PsiSetsCall` that of
the S-R-S arm (``srs_intervals.c``, :mod:`qpik.analytic.srs_intervals`); :class:`NativeSets` hands one to C code
that calls it in a loop (:mod:`qpik.nlp.levelset`). Each library is loaded as a :class:`ctypes.PyDLL` (its call
keeps the interpreter's lock): its buffers belong to the solver, and like every compiled call of qpik's, one arm's
solver is not for several threads at once. Without a compiler there is no call (``build`` gives None) and the
modules of the arms run the same steps in numpy.
"""

from __future__ import annotations

import ctypes
from functools import cache
from typing import TYPE_CHECKING

import numpy as np

from qpik.analytic.intervals import INTERVALS, Interval, check_sets, list_maker
from qpik.analytic.native_sets import REGION, NativeSets
from qpik.analytic.polyroots import FLAGS as POLYROOTS_FLAGS
from qpik.analytic.polyroots import ROOM
from qpik.native.compiled import Compiled, Kernel, NativeFunction
from qpik.native.sources import load_source

if TYPE_CHECKING:
    from qpik.analytic.offset_shoulder import OffsetShoulderSolver
    from qpik.analytic.srs import SRSSolver

NONE = 10.0
"""Stands for a breakpoint or singular value that does not exist in a breakpoint function's output (any value outside
[−π, π])."""


class ArmSetsCall:
    """An arm's feasible sets as one C call ``int name(const Struct *)`` (``offset_shoulder_intervals.c``,
    ``srs_intervals.c``) over its breakpoint function's and its checked IK's generated C (:meth:`functions`) and
    buffers allocated once.

    The struct gets ``breakpoints``, ``ik`` (their :class:`~qpik.native.compiled.Kernel`), ``param`` (the IK's parameter
    buffer), the addresses of ``arrays`` (its buffer fields by name, with the region's of :class:`NativeSets` added)
    and ``fields`` (its other fields). The arrays become lists by :func:`~qpik.analytic.intervals.list_maker`'s
    function (:attr:`lists`).
    """

    def __init__(
        self,
        dll: ctypes.CDLL,
        name: str,
        breaks: NativeFunction,
        ik: NativeFunction,
        struct: type[ctypes.Structure],
        arrays: dict[str, np.ndarray],
        **fields,
    ):
        self._name, self._function = name, getattr(dll, name)
        self._breaks, self._ik = breaks, ik  # the C call uses their buffers: they live as long
        self._pose = breaks.args[0].reshape(4, 4).T  # T column-major, as both generated functions read it
        self._limits = ik.args[2:4]  # the IK's limit buffers, shared with the breakpoint function's when it takes them
        self.arrays = {**arrays, "region": np.zeros(2 * REGION), "n_region": np.full(1, -1, np.intc)}
        buffers = {key: x.ctypes.data for key, x in self.arrays.items()}
        self._call = struct(breakpoints=breaks.kernel, ik=ik.kernel, param=ik.args[1].ctypes.data, **fields, **buffers)
        self._address = ctypes.addressof(self._call)
        self.lists = list_maker()

    @staticmethod
    def functions(
        breaks: Compiled, outputs: tuple[int, ...], checked: Compiled, limits: tuple[np.ndarray, np.ndarray]
    ) -> tuple[NativeFunction, NativeFunction] | None:
        """The C calls of the breakpoint function ``breaks`` (of T, or of T, q_min and q_max; its ``outputs``) and of
        the checked IK ``checked`` (of T, the parameter, q_min and q_max): both read T from one buffer, and q_min and
        q_max too when ``breaks`` takes them; else the IK's hold ``limits``. None when either is not native code."""
        bp = NativeFunction.of(breaks, outputs=outputs)
        if bp is None:
            return None
        shared = {0: bp.args[0]} | ({2: bp.args[1], 3: bp.args[2]} if len(bp.args) == 3 else {})
        ik = NativeFunction.of(checked, outputs=(1,), inputs=shared)
        if ik is None:
            return None
        if len(bp.args) == 1:
            ik.args[2][:], ik.args[3][:] = limits
        return bp, ik

    def run(self, T: np.ndarray, limits: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """The call for the pose T (4, 4) and, for a breakpoint function that takes them, ``limits`` ``(q_min,
        q_max)`` ((n,) rad): its outputs are in :attr:`arrays`."""
        self._pose[...] = T
        if limits is not None:
            self._limits[0][:], self._limits[1][:] = limits
        check_sets(self._function(self._address), self._name)

    def sets(self) -> NativeSets:
        """This call as :class:`NativeSets` (for a breakpoint function of the limits)."""
        a = self.arrays
        address = ctypes.cast(self._function, ctypes.c_void_p).value
        return NativeSets(address, self._address, self._breaks.args[0], *self._limits, a["iv"], a["count"],
                          a["region"], a["n_region"], self)  # fmt: skip


class _DeltaSets(ctypes.Structure):
    """``DeltaSets`` of ``offset_shoulder_intervals.c`` (same fields, same order)."""

    _fields_ = [("breakpoints", Kernel)]
    _fields_ += [(name, ctypes.c_int) for name in ("n_cand", "n_sing", "K", "size", "a7", "b7", "a5", "b5")]
    _fields_ += [("none", ctypes.c_double), ("common", ctypes.c_double), ("ik", Kernel), ("param", ctypes.c_void_p)]
    _fields_ += [("rows", ctypes.c_int), ("shift", ctypes.c_int), ("room_roots", ctypes.c_int)]
    _fields_ += [(name, ctypes.c_void_p) for name in ("delta", "breaks", "sing", "owner")]
    _fields_ += [("room", ctypes.c_int)] + [(name, ctypes.c_void_p) for name in ("iv", "sv", "count", "scount", "ns")]
    _fields_ += [("region", ctypes.c_void_p), ("n_region", ctypes.c_void_p)]


class DeltaSetsCall(ArmSetsCall):
    """:class:`~qpik.analytic.offset_shoulder_intervals.DeltaIntervals` in one C call (``qpik_delta_sets``,
    ``offset_shoulder_intervals.c``): the breakpoint function's and the IK's generated C,
    :func:`~qpik.analytic.polyroots.trig_roots`' root finder and the
    :class:`~qpik.analytic.intervals.SetAssembler`'s gap classification.

    The breakpoint function gives the candidates and the singular candidates (:data:`NONE` where one does not
    exist) and the wrist equations' coefficients A and B (``coeffs`` per equation); its θ7 and θ5 equations are the
    row ranges ``wrist_rows`` ``(a7, b7, a5, b5)``, and a θ5 root within ``common_tol`` (rad) of a θ7 root is a
    wrist singularity.
    """

    ROWS = 8

    def __init__(
        self,
        dll: ctypes.CDLL,
        breaks: NativeFunction,
        ik: NativeFunction,
        wrist_rows: np.ndarray,
        coeffs: int,
        common_tol: float,
    ):
        cand, sing, FA, _ = breaks.res
        K = FA.size // coeffs
        room_roots = ROOM * K
        out_rows = 2 * self.ROWS
        room = out_rows * (cand.size + room_roots + 2)
        arrays = {
            "delta": np.zeros(room_roots),
            "owner": np.zeros(room_roots, np.intc),
            "breaks": np.zeros(cand.size + room_roots),
            "sing": np.zeros(sing.size + room_roots),
            "iv": np.zeros(2 * room),
            "sv": np.zeros(out_rows * (sing.size + room_roots)),
            "count": np.zeros(out_rows, np.intc),
            "scount": np.zeros(out_rows, np.intc),
            "ns": np.zeros(1, np.intc),
        }
        a7, b7, a5, b5 = wrist_rows.tolist()
        super().__init__(
            dll, "qpik_delta_sets", breaks, ik, _DeltaSets, arrays,
            n_cand=cand.size, n_sing=sing.size, K=K, size=coeffs, a7=a7, b7=b7, a5=a5, b5=b5, none=NONE,
            common=1.0 - 0.5 * common_tol**2,  # cos d > 1 − tol²/2 ⇔ |d| < tol on the circle
            rows=self.ROWS, shift=1, room_roots=room_roots, room=room,
        )  # fmt: skip

    @classmethod
    def build(
        cls, breaks: Compiled, solver: OffsetShoulderSolver, wrist_rows: np.ndarray, coeffs: int, common_tol: float
    ) -> DeltaSetsCall | None:
        """The C path over the breakpoint function ``breaks`` (of T, or of T, q_min and q_max) and ``solver``'s checked
        IK (:meth:`ArmSetsCall.functions`), or None when one of them or the C source is not native code."""
        dll = _delta_library()
        limits = (solver.robot.q_min, solver.robot.q_max)
        pair = None if dll is None else cls.functions(breaks, (0, 1, 2, 3), solver.checked(cls.ROWS), limits)
        return None if pair is None else cls(dll, *pair, wrist_rows, coeffs, common_tol)

    def __call__(
        self, T: np.ndarray, limits: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[list[list[Interval]], list[list[float]]]:
        """The sets and singular values of rows 1–16 for the pose T (4, 4); ``limits`` ``(q_min, q_max)`` ((n,) rad)
        for a breakpoint function that takes them."""
        self.run(T, limits)
        a = self.arrays
        return self.lists(a["iv"], a["count"], a["sv"], a["scount"], int(a["ns"][0]))


@cache
def _delta_library() -> ctypes.PyDLL | None:
    """``offset_shoulder_intervals.c`` compiled with ``polyroots.c`` and ``intervals.c`` (whose functions it calls),
    loaded as a :class:`ctypes.PyDLL`; None without a compiler."""
    parts = ["offset_shoulder_intervals.c", "polyroots.c", *INTERVALS["parts"]]
    return load_source("qpik_delta_intervals", "pydll", parts, defines=INTERVALS["defines"], flags=POLYROOTS_FLAGS,
                       signatures={"qpik_delta_sets": (ctypes.c_int, [ctypes.c_void_p])})  # fmt: skip


class _PsiSets(ctypes.Structure):
    """``PsiSets`` of ``srs_intervals.c`` (same fields, same order)."""

    _fields_ = [("breakpoints", Kernel), ("n_breaks", ctypes.c_int), ("n_sing", ctypes.c_int)]
    _fields_ += [("none", ctypes.c_double), ("ik", Kernel), ("param", ctypes.c_void_p), ("rows", ctypes.c_int)]
    _fields_ += [("breaks", ctypes.c_void_p), ("room", ctypes.c_int)]
    _fields_ += [(name, ctypes.c_void_p) for name in ("iv", "sv", "count", "scount")]
    _fields_ += [("region", ctypes.c_void_p), ("n_region", ctypes.c_void_p)]


class PsiSetsCall(ArmSetsCall):
    """:class:`~qpik.analytic.srs_intervals.PsiIntervals` in one C call (``qpik_psi_sets``, ``srs_intervals.c``): the
    breakpoint function's and the IK's generated C and the :class:`~qpik.analytic.intervals.SetAssembler`'s gap
    classification. The breakpoint function gives every breakpoint, the singular ψ (:data:`NONE` where one does not
    exist) and whether the pose is reachable."""

    def __init__(self, dll: ctypes.CDLL, breaks: NativeFunction, ik: NativeFunction, rows: int):
        n_breaks, n_sing = breaks.res[0].size, breaks.res[1].size
        room = rows * (n_breaks + n_sing + 2)  # at most one piece more than gaps per row
        arrays = {
            "breaks": np.zeros(n_breaks + n_sing),
            "iv": np.zeros(2 * room),
            "sv": np.zeros(1),
            "count": np.zeros(rows, np.intc),
            "scount": np.zeros(rows, np.intc),
        }
        super().__init__(
            dll, "qpik_psi_sets", breaks, ik, _PsiSets, arrays,
            n_breaks=n_breaks, n_sing=n_sing, none=NONE, rows=rows, room=room,
        )  # fmt: skip

    @classmethod
    def build(cls, breaks: Compiled, solver: SRSSolver, rows: int) -> PsiSetsCall | None:
        """The C path over the breakpoint function ``breaks`` (of T, or of T, q_min and q_max) and ``solver``'s checked
        IK of its first ``rows`` branches (:meth:`ArmSetsCall.functions`), or None when one of them or the C source
        is not native code."""
        dll = _psi_library()
        limits = (solver.robot.q_min, solver.robot.q_max)
        pair = None if dll is None else cls.functions(breaks, (0, 1, 2), solver.checked(rows), limits)
        return None if pair is None else cls(dll, *pair, rows)

    def __call__(
        self, T: np.ndarray, limits: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[list[list[Interval]], np.ndarray, np.ndarray]:
        """For the pose T (4, 4): the sets of the rows (empty for an unreachable pose), and the breakpoint function's
        singular ψ (8,) and ``valid`` (1,) outputs (views its next call overwrites); ``limits`` ``(q_min, q_max)``
        ((n,) rad) for a breakpoint function that takes them."""
        self.run(T, limits)
        a = self.arrays
        intervals, _ = self.lists(a["iv"], a["count"], a["sv"], a["scount"], 0)
        _, singular, valid = self._breaks.res
        return intervals, singular, valid


@cache
def _psi_library() -> ctypes.PyDLL | None:
    """``srs_intervals.c`` compiled with ``intervals.c`` (whose ``circle_sets`` it calls), loaded as a
    :class:`ctypes.PyDLL`; None without a compiler."""
    parts = ["srs_intervals.c", *INTERVALS["parts"]]
    return load_source("qpik_psi_intervals", "pydll", parts, defines=INTERVALS["defines"],
                       signatures={"qpik_psi_sets": (ctypes.c_int, [ctypes.c_void_p])})  # fmt: skip
