r"""What :func:`~qpik.nlp.best.solve_best` returns: :class:`BestResult` per pose, :class:`BestResults` per batch.

A result holds the status (one of :data:`STATUSES`), the best branch's public id, its parameter δ or
ψ (rad), its configuration q (n,) (rad, always finite), the objective there, whether it is proved
globally optimal and the gap to the proved lower bound, its clearance (m) and, for a status other
than ``"optimal"``, how far q is from a solution. Its per-branch table (:class:`BranchOptimum` rows)
is built when first read from :class:`BranchRows`, the best point found per searched branch row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from qpik.analytic.intervals import wrap
from qpik.objectives import Quantity

STATUSES = ("optimal", "unreachable", "no feasible branch", "not found", "solver failed")


@dataclass
class BranchOptimum:
    """One branch's row of the table.

    Attributes:
        branch: public branch id.
        searched: whether it was searched (``branches`` of :func:`~qpik.nlp.best.solve_best`).
        feasible: some δ/ψ of it keeps the joints in their limits (and clear of the obstacles).
        param: its best δ/ψ (rad; None if not feasible); objective: the value there (+inf if not feasible).
        q: (n,) its configuration, rad (None if not feasible).
        rounds: polish rounds (iterations) of its best local minimum.
        evaluations: objective evaluations spent on the branch.
        time: its share of the pose's solve time (by evaluations), s.
        self_collides: its point brings two of the scene's capsule pairs closer than d_s: the row is the branch's
            best without them (the answer's pass without them, :mod:`qpik.nlp.best`), a lower bound of its
            objective with them, which was not searched.
    """

    branch: int
    searched: bool
    feasible: bool
    param: float | None
    objective: float
    q: np.ndarray | None
    rounds: int = 0
    evaluations: int = 0
    time: float = 0.0
    self_collides: bool = False


@dataclass(frozen=True, eq=False)
class BranchRows:
    """What one pose's per-branch table is built from: the best point found per searched row, f (R,) (+inf where
    none), ψ (R,), q (R, n), its rounds (R,) and the evaluations per row (R,); ``columns`` the table's branches, per
    branch (public id, its searched row, its shift (None: its own row), whether it was searched); ``collides`` (R,)
    whether a row's point brings the scene's capsule pairs closer than d_s (None: no row does)."""

    columns: list[tuple[int, int, float | None, bool]]
    f: list[float]
    psi: list[float]
    q: np.ndarray
    rounds: list[int]
    counts: list[int]
    collides: list[bool] | None = None

    def table(self, time: float) -> list[BranchOptimum]:
        """The rows, a branch's time its share (by evaluations) of the pose's ``time`` (s); plain floats, which
        cost less than numpy's calls for one pose's few rows."""
        f, psi, q, counts = self.f, self.psi, self.q, self.counts
        per = time / max(sum(counts), 1)
        out = []
        for bid, r, shift, done in self.columns:
            ok = f[r] < math.inf
            param = (psi[r] if shift is None else float(wrap(psi[r] - shift))) if ok else None
            evals = counts[r] if shift is None else 0
            collides = bool(self.collides and self.collides[r])
            out.append(BranchOptimum(bid, done, ok, param, f[r], q[r] if ok else None,
                                     self.rounds[r] if shift is None else 0, evals, evals * per, collides))  # fmt: skip
        return out


@dataclass
class BestResult:
    """The answer for one pose.

    Attributes:
        status: one of :data:`STATUSES`.
        branch: the best branch's public id (for another status, the branch of
            :func:`~qpik.nlp.least_violating.least_violating`'s configuration; -1 if unreachable).
        param: its δ/ψ, rad; q: (n,) its configuration, rad (always finite); objective: the minimised value at q
            (+inf for a status other than ``"optimal"``); :attr:`reported` is the quantity it measures (the margin
            itself for the margin objective, whose ``objective`` is −margin).
        certified: proved to be the global minimum to ``gap`` (:mod:`qpik.nlp.certificate`).
        gap: the objective minus the certified lower bound (inf when not certified).
        clearance: smallest clearance at q, m: capsule–obstacle distances and the distances of the scene's capsule
            pairs (:attr:`~qpik.scene.Scene.self_pairs`); inf without either.
        violation: 0 for ``"optimal"``; else how far q is from a solution: outside the limits (rad),
            inside d_s (m), or, when unreachable, the norm of its pose error (m and rad,
            :func:`~qpik.nlp.least_violating.least_violating`).
        branches: the per-branch table (:class:`BranchOptimum`), built when first read (from :attr:`rows`).
        param_name: ``"delta"`` or ``"psi"``.
        message: why it is not certified, or what failed ("" otherwise).
        method: what found the answer: ``"levelset"`` (then a row of :attr:`branches` other than the best
            holds the best point evaluated on its branch, not the branch's optimum), ``"search"`` or ``"ipopt"``.
        self_collision: how the scene's capsule pairs (:attr:`~qpik.scene.Scene.self_pairs`) were kept ≥ d_s apart
            (:mod:`qpik.nlp.best`): ``"off"`` (the scene has none), ``"clear"`` (the answer solved without them
            keeps them apart, so it is the answer with them), ``"re-solved"`` (the pose was solved again with them
            as constraints: its answer without them came closer, or was not optimal), ``"constrained"`` (one pass
            with them as constraints: the 1-D search's arms, :mod:`qpik.nlp.best_sampled`).
        time: seconds of the solve, without building or compiling its functions (done before the clock starts;
            a batch: the solve's time divided by the number of poses).
        rows: what :attr:`branches` is built from (None: an empty table).
        quantity: how the objective is shown (:attr:`qpik.objectives.Objective.quantity`).
    """

    status: str
    branch: int
    param: float
    q: np.ndarray
    objective: float
    certified: bool = False
    gap: float = np.inf
    clearance: float = np.inf
    violation: float = 0.0
    param_name: str = "psi"
    message: str = ""
    time: float = 0.0
    method: str = "search"
    self_collision: str = "off"
    rows: BranchRows | None = field(default=None, repr=False)
    quantity: Quantity = field(default_factory=lambda: Quantity("objective"), repr=False)

    @property
    def reported(self) -> float:
        """The objective as the quantity it measures (:attr:`quantity`): the margin (not −margin), the clearance (m),
        the manipulability (not −log m), or the minimised value itself."""
        return self.quantity.value(self.objective)

    @cached_property
    def branches(self) -> list[BranchOptimum]:
        """The per-branch table (:class:`BranchOptimum`; each branch's time its share of :attr:`time`)."""
        return [] if self.rows is None else self.rows.table(self.time)

    def table(self) -> str:
        """The per-branch table as text: the parameter (rad), the objective as its :attr:`quantity` (the margin
        itself, ...), polish rounds, evaluations and each branch's share of the solve's time (µs)."""
        sym = {"delta": "δ", "psi": "ψ"}.get(self.param_name, self.param_name)
        head = self.quantity.header
        w = max(13, len(head))
        lines = [
            f"{'branch':>6} {'feasible':>8} {sym + '* [rad]':>11} {head:>{w}}"
            f" {'rounds':>6} {'evals':>6} {'time [µs]':>9}"
        ]
        for r in self.branches:
            mark = " *" if r.branch == self.branch and self.status == "optimal" else ""
            shown = self.quantity.value(r.objective)
            val = f"{r.param:11.6f} {shown:{w}.8g}" if r.feasible else f"{'—':>11} {'—':>{w}}"
            feasible = ("yes" if r.feasible else "no") if r.searched else "skipped"
            mark += " self-collides" if r.self_collides else ""
            lines.append(
                f"{r.branch:>6} {feasible:>8} {val} {r.rounds:>6} {r.evaluations:>6} {r.time * 1e6:9.1f}{mark}"
            )
        if self.method == "levelset":
            lines.append("(level sets: a row other than the best holds the best point evaluated on its branch)")
        if any(r.self_collides for r in self.branches):
            lines.append("(self-collides: the branch's best point without the capsule pairs, closer than d_s there)")
        if self.self_collision == "re-solved":
            lines.append("(self-collision: solved again with the capsule pairs as constraints)")
        return "\n".join(lines)

    def summary(self) -> str:
        """One line: status, branch, parameter, objective, certificate."""
        sym = {"delta": "δ", "psi": "ψ"}.get(self.param_name, self.param_name)
        if self.status == "unreachable":
            return "unreachable: no branch reaches the pose"
        if self.status == "no feasible branch":
            return (
                f"no feasible branch: least violating is branch {self.branch} at {sym} = {self.param:.6f} rad"
                f" (violation {self.violation:.3g})"
            )
        if self.status != "optimal":
            return f"{self.status}: {self.message}"
        cert = f"certified (gap {self.gap:.2g})" if self.certified else f"not certified ({self.message})"
        value = self.quantity.text(self.objective, ".10g")
        cert += ", re-solved with the capsule pairs" if self.self_collision == "re-solved" else ""
        return f"best: branch {self.branch}, {sym} = {self.param:.6f} rad, {value}, {self.quantity.sense}, {cert}"


class BestResults:
    """Answers for a batch of poses: ``results[i]`` is a :class:`BestResult`; the arrays stack them."""

    def __init__(self, results: list[BestResult], n: int):
        self.results, self.n = results, n

    def __len__(self) -> int:
        return len(self.results)

    def __getitem__(self, i: int) -> BestResult:
        return self.results[i]

    def __iter__(self):
        return iter(self.results)

    @property
    def status(self) -> np.ndarray:
        return np.array([r.status for r in self.results])

    @property
    def q(self) -> np.ndarray:
        """(N, n), rad."""
        return np.array([r.q for r in self.results]).reshape(len(self.results), self.n)

    @property
    def objective(self) -> np.ndarray:
        """(N,) the minimised values."""
        return np.array([r.objective for r in self.results])

    @property
    def reported(self) -> np.ndarray:
        """(N,) the objectives as the quantities they measure (:attr:`BestResult.reported`)."""
        return np.array([r.reported for r in self.results])

    @property
    def param(self) -> np.ndarray:
        return np.array([r.param for r in self.results])

    @property
    def branch(self) -> np.ndarray:
        return np.array([r.branch for r in self.results])

    @property
    def certified(self) -> np.ndarray:
        return np.array([r.certified for r in self.results])

    @property
    def self_collision(self) -> np.ndarray:
        """(N,) :attr:`BestResult.self_collision` per pose."""
        return np.array([r.self_collision for r in self.results])
