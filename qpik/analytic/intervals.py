"""Feasible redundancy-parameter sets: types and the shared interval assembly (:class:`SetAssembler`).

A solver finds, analytically, every parameter value where something can
change for a branch: a joint reaching a limit, a joint jumping (wrap or a
singular point), the branch becoming invalid. Between two consecutive such
*breakpoints* a branch is either feasible throughout or nowhere, so one
evaluation at each gap's midpoint classifies the gap. This is not
sampling: the boundaries are the analytic breakpoints themselves.
"""

from __future__ import annotations

import ctypes
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from itertools import accumulate, pairwise
from typing import TYPE_CHECKING, Protocol

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.core.errors import InputError, SolverError
from qpik.core.validate import finite_array, number
from qpik.native.compiled import Compiled, NativeFunction
from qpik.native.fastcall import extension
from qpik.native.sources import load_source

if TYPE_CHECKING:
    from qpik.analytic.native_sets import NativeSets
    from qpik.robots.robot import Robot

TWO_PI = 2.0 * np.pi
SAME = 1e-9
"""Breakpoints (rad) closer than this are one: a gap narrower than that is not classified, so a
boundary may be off by as much (the equations of nearly coincident breakpoints, such as a validity
test and its tolerant twin, are solved to about this accuracy anyway)."""

Interval = tuple[float, float]


@dataclass
class FeasibleIntervals:
    """Per branch, the parameter values (rad, in (-pi, pi]) where all joints are within limits.

    Attributes:
        param_name: ``"delta"`` or ``"psi"``.
        branch: public branch ids, shape (B,).
        intervals: per branch, sorted disjoint closed intervals ``(lo, hi)`` with
            ``lo <= hi``; a set that wraps through ±pi is split in two.
        singular: per branch, parameter values where some joint is singular.
        proved: every breakpoint was found by an exact or exactly bounded method, so the sets are exact (an empty
            set proves that no parameter is feasible); False where a search left parts of the circle undecided.
    """

    param_name: str
    branch: np.ndarray
    intervals: list[list[Interval]]
    singular: list[list[float]] = field(default_factory=list)
    proved: bool = True

    def __getitem__(self, b: int) -> list[Interval]:
        """Intervals of the branch with public id ``b``."""
        return self.intervals[self.index(b)]

    def index(self, b: int) -> int:
        """Position of branch id ``b`` in :attr:`branch`; :class:`InputError` if there is no such branch."""
        if isinstance(b, bool) or not isinstance(b, int | np.integer):
            raise InputError(f"branch: expected a branch id (an integer), got {b!r}")
        hits = np.flatnonzero(self.branch == b)
        if hits.size == 0:
            raise InputError(f"branch: no branch {b}; branches are {self.branch.tolist()}")
        return int(hits[0])

    def contains(self, b: int, value: float | np.ndarray, tol: float = 0.0) -> np.ndarray | bool:
        """Whether ``value`` (rad, any shape) lies in branch ``b``'s feasible set."""
        out = within(self[b], finite_array(value, "value"), number(tol, "tol"))
        return bool(out) if out.ndim == 0 else out

    def measure(self, b: int) -> float:
        """Total length (rad) of branch ``b``'s feasible set."""
        return float(sum(hi - lo for lo, hi in self[b]))


def shrunk_limits(q_min: np.ndarray, q_max: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    r"""The joint limits shrunk by ``margin`` (rad, (n,) each): :math:`(l + m\rho,\ u - m\rho)`,
    :math:`\rho = (u - l)/2`.

    A configuration q has the joint-limit margin (:class:`qpik.objectives.JointLimitMargin`)
    :math:`\mu(q) = \min_j \min(q_j - l_j, u_j - q_j)/\rho_j \ge m` iff every joint lies in these limits;
    for m > 1 they are empty (lo > hi).
    """
    lo, hi = np.asarray(q_min, dtype=float), np.asarray(q_max, dtype=float)
    half = margin * 0.5 * (hi - lo)
    return lo + half, hi - half


def within(intervals: list[Interval], x: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """Whether each of ``x`` (rad, any shape) lies in one of the closed ``intervals``, widened by ``tol`` (rad) each
    side."""
    out = np.zeros(np.shape(x), dtype=bool)
    for lo, hi in intervals:
        out |= (x >= lo - tol) & (x <= hi + tol)
    return out


def spaced(lo: float, hi: float, spacing: float) -> np.ndarray:
    """Samples of the interval [``lo``, ``hi``] (rad): its two ends and the multiples of ``spacing`` (rad) strictly
    between them, sorted (the same multiples for every interval, so that neighbouring pieces share them)."""
    inner = np.arange(np.floor(lo / spacing) + 1, np.ceil(hi / spacing)) * spacing
    return np.concatenate([[lo], inner[(inner > lo) & (inner < hi)], [hi]])


def wrap(x: np.ndarray | float) -> np.ndarray:
    """Wrap angles (rad, any shape) to (-pi, pi]: :meth:`qpik.algebra.symbolic.Ops.wrap` on a float array."""
    return sy.NUMPY.wrap(np.asarray(x, dtype=float))


def apart(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The largest difference (rad, modulo 2π) over the last axis of joint angles ``q`` and ``r`` (broadcast; any
    representatives): how far apart two configurations are on the torus."""
    return np.abs(wrap(np.asarray(q, dtype=float) - r)).max(axis=-1)


class Flagging(Protocol):
    """What the breakpoint sets read of a closed-form solver (:class:`~qpik.analytic.solver.AnalyticSolver`)."""

    robot: Robot

    def checked(self, rows: int) -> Compiled: ...

    def flags_many(
        self, T: np.ndarray, params: np.ndarray, rows: int, limits: tuple[np.ndarray, np.ndarray] | None = None
    ) -> np.ndarray: ...


class ParameterSets(Protocol):
    """The feasible sets of one closed form's parameter (``DeltaIntervals``, ``PsiIntervals``, ``Q7Intervals``).

    ``proved``: the answers can be proved: every breakpoint is found by an exact or exactly bounded method, and an
    answer whose search was left unfinished says so (``FeasibleIntervals.proved``); False where the breakpoints
    come from a sampled sweep."""

    proved: bool

    def __call__(self, T: np.ndarray, margin: float = 0.0) -> FeasibleIntervals: ...

    def native_sets(self) -> NativeSets | None: ...


class SetAssembler:
    """Feasible sets and singular values of a solver's first ``rows`` branches, from breakpoints.

    One evaluation of the branches (the compiled IK with its limit test, ``flags``
    of :meth:`~qpik.analytic.solver.AnalyticSolver.checked`) at each gap's midpoint
    classifies the gap; each branch's set is its runs of feasible gaps (:func:`gaps`,
    :func:`merge`). With ``shift``, the sets moved by π follow as rows ``rows..2 rows``
    (:func:`shift`). With a C compiler this runs in ``intervals.c``, which calls the IK's
    generated C directly (a gap costs one IK evaluation, no Python), and the compiled
    extension turns its arrays into the result lists (:mod:`qpik.native.fastcall`, ``circle_lists``;
    in Python without the extension); without a compiler,
    in numpy over :meth:`~qpik.analytic.solver.AnalyticSolver.flags_many`. Both paths
    are checked against dense sampling in the tests.

    Args:
        solver: the closed-form solver.
        rows: how many of its first branches to classify.
        shift: also return the sets moved by π.
    """

    def __init__(self, solver: Flagging, rows: int, shift: bool = False):
        self._solver, self.rows, self.shift = solver, rows, shift
        limits = (np.asarray(solver.robot.q_min, float), np.asarray(solver.robot.q_max, float))
        self._native = _NativeSets.for_function(solver.checked(rows), limits, rows, shift)

    def __call__(
        self,
        T: np.ndarray,
        breaks: np.ndarray,
        singular: np.ndarray,
        limits: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[list[list[Interval]], list[list[float]]]:
        """For the pose T (4, 4): per output row, the feasible set and the values of ``singular`` where the
        branch is valid and singular (sorted).

        Args:
            breaks: (M,) parameter values (rad, any branch of 2π) where some branch's feasibility
                may change.
            singular: (S,) candidate singular values (rad).
            limits: ``(q_min, q_max)`` ((n,) rad each) of the gaps' limit test instead of the robot's, such as
                :func:`shrunk_limits`; ``breaks`` must then hold their crossings.
        """
        if self._native is not None:
            return self._native(T, breaks, singular, limits)
        return self._numpy(T, breaks, singular, limits)

    def _numpy(self, T: np.ndarray, breaks: np.ndarray, singular: np.ndarray, limits):
        lo, hi = gaps(breaks if breaks.size else np.zeros(1))
        sing = np.unique(wrap(singular))
        params = np.concatenate([wrap(0.5 * (lo + hi)), sing])
        flags = self._solver.flags_many(T, params, rows=self.rows, limits=limits)
        ok, hit = flags[: lo.size, 2], flags[lo.size :, 0] & flags[lo.size :, 1]
        sets = merge(lo, hi, ok)
        found: list[list[float]] = [sing[hit[:, r]].tolist() for r in range(self.rows)]
        if self.shift:
            sets += [shift(s, np.pi) for s in sets]
            found += [np.sort(wrap(np.array(x) + np.pi)).tolist() for x in found]
        return sets, found


class _NativeSets:
    """:class:`SetAssembler`'s C path: ``qpik_circle_sets`` (``intervals.c``) calling the IK's generated C; its
    arrays become lists by :func:`list_maker`'s function."""

    def __init__(
        self, dll: ctypes.CDLL, ik: NativeFunction, limits: tuple[np.ndarray, np.ndarray], rows: int, shift: bool
    ):
        self._dll, self._ik = dll, ik
        self.out_rows = (2 if shift else 1) * rows
        # the IK's inputs (T column-major, param, q_min, q_max) and its flags output; Q is not asked for
        ik.args[2][:], ik.args[3][:] = self._limits = limits
        self._other = False  # the IK's limit buffers hold limits other than self._limits
        self._pose = ik.args[0].reshape(4, 4).T  # T column-major, as the IK reads it
        self._head = (*ik.addresses, ik.args[1].ctypes.data, rows, int(shift))
        self._grow(64, 4)
        self._lists = list_maker()

    @classmethod
    def for_function(
        cls, compiled: Compiled, limits: tuple[np.ndarray, np.ndarray], rows: int, shift: bool
    ) -> _NativeSets | None:
        """The C path for the checked IK ``compiled``, or None when it or ``intervals.c`` is not native code."""
        dll = _library()
        ik = None if dll is None else NativeFunction.of(compiled, outputs=(1,))
        return None if ik is None else cls(dll, ik, limits, rows, shift)

    def _grow(self, breaks: int, singular: int) -> None:
        """Input and output room for up to ``breaks`` breakpoints and ``singular`` singular candidates."""
        self._nb, self._ns = breaks, singular
        self._breaks, self._sing = np.zeros(max(breaks, 1)), np.zeros(max(singular, 1))
        self._iv = np.zeros(2 * self.out_rows * (breaks + 2))
        self._count = np.zeros(self.out_rows, np.intc)
        self._sv = np.zeros(self.out_rows * max(singular, 1))
        self._scount = np.zeros(self.out_rows, np.intc)
        # the call's arguments after the head: nb and ns (set per call) and the buffers' addresses
        self._tail = [0, self._breaks.ctypes.data, 0, self._sing.ctypes.data, self.out_rows * (breaks + 2)]
        self._tail += [x.ctypes.data for x in (self._iv, self._count, self._sv, self._scount)]

    def __call__(
        self, T: np.ndarray, breaks: np.ndarray, singular: np.ndarray, limits: tuple[np.ndarray, np.ndarray] | None
    ):
        if limits is not None or self._other:
            self._ik.args[2][:], self._ik.args[3][:] = self._limits if limits is None else limits
            self._other = limits is not None
        nb, ns = breaks.size, singular.size
        if nb > self._nb or ns > self._ns:
            self._grow(max(nb, self._nb), max(ns, self._ns))
        self._breaks[:nb], self._sing[:ns] = breaks, singular  # copies into fixed buffers: no per-call pointers
        self._tail[0], self._tail[2] = nb, ns
        self._pose[...] = T
        m = self._dll.qpik_circle_sets(*self._head, *self._tail)
        check_sets(m, "qpik_circle_sets")
        return self._lists(self._iv, self._count, self._sv, self._scount, ns)


def check_sets(m: int, name: str) -> None:
    """:class:`SolverError` for the negative status ``m`` of the C function ``name`` (``intervals.c``'s codes)."""
    if m < 0:
        raise SolverError(f"{name} failed ({m}: -1 no room, -2 a compiled function failed, -3 no memory)")


def list_maker() -> Callable[..., tuple[list[list[Interval]], list[list[float]]]]:
    """What turns the output arrays of ``circle_sets`` (``intervals.c``) into lists: the compiled extension's
    ``circle_lists`` (:mod:`qpik.native.fastcall`) when there is one, else :func:`python_lists` (same arguments)."""
    ext = extension()
    return python_lists if ext is None else ext.circle_lists


def python_lists(
    iv: np.ndarray, count: np.ndarray, sv: np.ndarray, scount: np.ndarray, ns: int
) -> tuple[list[list[Interval]], list[list[float]]]:
    """The output arrays of ``circle_sets`` (``intervals.c``) as lists, per row: its ``count[r]`` pieces (pairs
    one row after the other in ``iv``) and its ``scount[r]`` singular values (row r's start at ``sv[r * ns]``)."""
    counts = count.tolist()
    ends = iter(iv[: 2 * sum(counts)].tolist())
    pieces = list(zip(ends, ends))
    bounds = [0, *accumulate(counts)]
    sets = [pieces[a:b] for a, b in pairwise(bounds)]
    found = scount.tolist()
    if not any(found):
        return sets, [[] for _ in found]
    flat = sv[: len(found) * ns].tolist()  # row r's values start at r * ns
    return sets, [flat[r * ns : r * ns + c] for r, c in enumerate(found)]


INTERVALS = {"parts": ["intervals.c"], "defines": {"SAME": SAME}}
"""``intervals.c`` for :func:`qpik.native.sources.load_source`: its file and its constant :data:`SAME`; a library
that calls its ``circle_sets`` (``intervals.h``) holds it too."""


@cache
def _library() -> ctypes.CDLL | None:
    """``intervals.c`` compiled (:func:`qpik.native.sources.load_source`), or None without a compiler."""
    args = [ctypes.c_void_p] * 6 + [ctypes.c_int] * 3 + [ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p, ctypes.c_int]
    args += [ctypes.c_void_p] * 4
    return load_source("qpik_intervals", "cdll", **INTERVALS, signatures={"qpik_circle_sets": (ctypes.c_int, args)})


def gaps(breaks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gaps ``(lo[i], hi[i])`` (rad) between breakpoints (any order, any branch of 2π, at least one).

    ``lo`` are the breakpoints wrapped to (−π, π] and sorted, one per cluster of breakpoints
    within :data:`SAME` of each other; ``hi`` the next one, the last gap ending at
    ``lo[0] + 2π``: together the gaps tile the circle.
    """
    lo = wrap(np.asarray(breaks, dtype=float).ravel())
    lo.sort()
    lo = lo[np.concatenate(([True], lo[1:] - lo[:-1] > SAME))]  # one breakpoint per cluster within SAME
    hi = np.empty_like(lo)
    hi[:-1], hi[-1] = lo[1:], lo[0] + TWO_PI
    return lo, hi


def merge(lo: np.ndarray, hi: np.ndarray, ok: np.ndarray) -> list[list[Interval]]:
    """Join the feasible gaps (lo[i], hi[i]) (ok (G, B)) into sorted disjoint intervals of [-pi, pi] per branch.

    The gaps tile the circle, so each branch's set is its runs of feasible gaps
    (a run may continue from the last gap into the first); a run that ends past
    π is split at ±π. The runs are found by one regular-expression scan of the
    flags as bytes (C speed; G is of order 100).
    """
    G, B = ok.shape
    W = G + 1
    lo_l, hi_l = lo.tolist(), hi.tolist()
    flags = np.zeros((B, W), np.uint8)  # one row per branch, a 0 after each: runs stay in their row
    flags[:, :G] = ok.T
    runs: list[list[tuple[int, int]]] = [[] for _ in range(B)]
    for m in _RUN.finditer(flags.tobytes()):
        a, b = m.span()
        j = a // W
        runs[j].append((a - j * W, b - 1 - j * W))  # first and last gap of the run
    out: list[list[Interval]] = []
    for r in runs:
        if r and r[0][0] == 0 and r[-1][1] == G - 1:  # feasible in gap 0 and in gap G-1
            if r[0][1] == G - 1:
                out.append([(-np.pi, np.pi)])
                continue
            if len(r) > 1:  # the last run continues into the first, across ±π: split there
                ivs = [(lo_l[s], hi_l[e]) for s, e in r[1:-1]]
                out.append([(-np.pi, hi_l[r[0][1]]), *ivs, (lo_l[r[-1][0]], np.pi)])
                continue
        ivs = [(lo_l[s], hi_l[e]) for s, e in r]
        if ivs and ivs[-1][1] > np.pi:  # only the last run can pass π: split it there
            a, end = ivs.pop()
            ivs = [(-np.pi, end - TWO_PI), *ivs, (a, np.pi)]
        out.append(ivs)
    return out


_RUN = re.compile(b"\x01+")


def shift(intervals: list[Interval], by: float) -> list[Interval]:
    """The set ``intervals`` (sorted, disjoint, in [−π, π]) moved by ``by`` ∈ [0, 2π) on the circle, same form."""
    return on_circle([(a + by, b + by) for a, b in intervals])


def on_circle(pieces: list[tuple[float, float]]) -> list[Interval]:
    """Intervals (rad, each shorter than a turn) whose ends may lie past ±π, in the form of the sets: one that starts
    past π moved back a turn, one that passes ±π split there, sorted, those that overlap or touch merged (pieces that
    met at ±π meet inside)."""
    split: list[tuple[float, float]] = []
    for a, b in pieces:
        if a > np.pi:
            a, b = a - TWO_PI, b - TWO_PI
        if b > np.pi:
            split += [(a, np.pi), (-np.pi, b - TWO_PI)]
        elif a < -np.pi:
            split += [(a + TWO_PI, np.pi), (-np.pi, b)]
        else:
            split.append((a, b))
    out: list[Interval] = []
    for a, b in sorted(split):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], float(b)))
        else:
            out.append((float(a), float(b)))
    return out
