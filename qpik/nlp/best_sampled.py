r"""``qpik.solve_best`` on the arms whose slots are found per pose and locked angle (the 1-D search's,
:mod:`qpik.analytic.search_solver`: the Sawyer, Baxter; the general 6-R's, :mod:`qpik.analytic.general_solver`):
sampled along the locked joint and polished, never certified.

Their slots are found per pose and locked angle, not expressions of the locked angle t, so neither the level sets nor
the search over expressions with its certificate (:mod:`qpik.nlp.best_search`) applies. Instead, per pose:

1. every slot's answer at the multiples of 2π/:data:`SAMPLES` inside the locked joint's limits and at the limits
   themselves (one solve each, :meth:`~qpik.analytic.slot_solver.SlotSolver.solve_many`);
2. at every sample where a searched slot is valid with every joint inside the limits, the objective and the clearances
   (:meth:`qpik.scene.evaluator.Evaluator.value_rows`); a sample is feasible where the clearances are ≥ d_s;
3. the feasible samples that are local minima of their slot's objective along t (a neighbour that is not feasible
   counts as +inf), the :data:`STARTS` best of them: each is narrowed by :data:`GOLDEN` golden-section steps on its
   own slot between its two neighbouring samples, then polished by IPOPT on the full-joint NLP (:mod:`qpik.nlp.full`:
   the pose an equality, the limits and clearances constraints, exact derivatives) with the locked joint held inside
   the narrowed bracket. Left free, IPOPT may cross a fold into another slot's basin and miss a better minimum beside
   the fold; held, it climbs down to the minimum beside its start, whatever slot that is;
4. the best of the feasible samples and of the polished points that reach the pose inside the limits and clear is
   the answer; a polished point's slot is the search's for its q
   (:meth:`~qpik.analytic.slot_solver.SlotSolver.parameter`).

A basin of the objective narrower than the spacing, or a feasible stretch of a slot between two samples, can be
missed: the answer is the best point found (``certified`` False). Where no sample is feasible and no polish reaches a
feasible point the status is ``"not found"``: nothing is proved, since the samples prove neither that the pose is
unreachable nor that no slot is feasible. Each sample is one search (milliseconds): about a second per pose, with
progress lines on stderr after two.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from qpik.algebra.lie import tracking_errors
from qpik.analytic.api import closed_form_for
from qpik.analytic.intervals import spaced
from qpik.analytic.sampled_sets import locked_span
from qpik.core.progress import Progress
from qpik.nlp.best_result import BestResult, BranchRows
from qpik.nlp.full import REACHED, full_nlp, solve_from

if TYPE_CHECKING:
    from qpik.analytic.slot_solver import SlotSolver
    from qpik.scene.scene import Scene

SAMPLES = 512
"""Values of the locked joint per 2π at which every slot is sampled."""
STARTS = 16
"""Local minima of the sampled objective (the best first) from which the full-joint NLP polishes."""
GOLDEN = 16
"""Golden-section steps on each start's slot before its polish (the bracket shrinks to 0.618^16 ≈ 4.6e-4 of the
start's two spacings)."""
RATIO = 0.5 * (np.sqrt(5.0) - 1.0)
"""The golden section's ratio."""
CHUNK = 64
"""Samples per search call between two progress lines."""
CLEAR = 1e-9
"""m: the tolerance of a clearance against d_s, as :func:`qpik.nlp.full.solve_full` and the answer's check take it."""


@dataclass(frozen=True)
class PoseProblem:
    """One pose's problem: the scene (arm, objective, obstacles, d_s), the arm's search solver, the pose ``T`` (4, 4),
    base frame, the reference ``ref`` (n,) rad and the public ids of the slots searched."""

    scene: Scene
    solver: SlotSolver
    T: np.ndarray
    ref: np.ndarray
    branches: list[int]


@dataclass(frozen=True)
class Samples:
    """Every slot of one pose at the sampled values ``t`` (M,) rad of the locked joint: ``q`` (M, B, n) rad,
    ``valid`` (M, B), the objective ``f`` (M, B; +inf where the slot is not feasible: not valid, outside the limits,
    not searched, or closer than d_s) and the smallest clearance ``clear`` (M, B) m (−inf where the slot is not valid
    inside the limits, or not searched)."""

    t: np.ndarray
    q: np.ndarray
    valid: np.ndarray
    f: np.ndarray
    clear: np.ndarray


def solve_sampled(scene: Scene, T: np.ndarray, q_ref: np.ndarray, branches: list[int]) -> list[BestResult]:
    """The answers for the poses ``T`` (N, 4, 4), base frame, with references ``q_ref`` (N, n) rad, searching the slots
    ``branches`` (public ids) of ``scene``'s arm (module docstring)."""
    solver: SlotSolver = closed_form_for(scene.robot)
    with solver.lock:
        return [_one(PoseProblem(scene, solver, Tk, ref, branches)) for Tk, ref in zip(T, q_ref)]


def grid(lo: float, hi: float) -> np.ndarray:
    """The values (rad, sorted, in [−π, π]) of a joint with limits [``lo``, ``hi``] (rad) at which it is sampled: the
    multiples of 2π/:data:`SAMPLES` inside them, and the limits themselves (wrapped)."""
    return np.unique(np.concatenate([spaced(a, b, 2.0 * np.pi / SAMPLES) for a, b in locked_span(lo, hi)]))


def _one(pp: PoseProblem) -> BestResult:
    scene, solver, robot, ids = pp.scene, pp.solver, pp.scene.robot, pp.solver.branch_ids
    start = time.perf_counter()
    got = _sample(pp)
    rows = _rows(pp, got)
    nlp = full_nlp(robot, scene.objective, scene.obstacles, scene.self_pairs)
    p = nlp.parameters(pp.T, pp.ref, scene.d_safe, scene.objective, scene.obstacles)
    starts = _starts(got.f)
    for q0, a, c in _narrow(pp, got, starts):
        lo, hi = robot.q_min.copy(), robot.q_max.copy()  # the locked joint inside the start's bracket
        lo[solver.locked], hi[solver.locked] = a, c
        try:
            qs, value, err, iters, _, d = solve_from(nlp, q0, p, (lo, hi))
        except RuntimeError:  # an evaluation error inside IPOPT: the start's sample stands
            continue
        if not (err < REACHED and d >= scene.d_safe - CLEAR):
            continue
        k = int(solver.parameter(qs[None])[1][0])  # the search's slot of the polished point
        if k >= 0 and ids[k] in pp.branches and value < rows.f[k]:
            rows.f[k], rows.psi[k], rows.q[k], rows.rounds[k] = float(value), float(qs[solver.locked]), qs, iters
    elapsed = time.perf_counter() - start
    searched = f"{len(got.t)} samples of {solver.param_name}"
    if not np.isfinite(rows.f).any():
        return _not_found(pp, got, rows, f"{searched}, nor after a polish", elapsed)
    k = int(np.argmin(rows.f))
    _, d = scene.evaluator.value_rows(rows.q[k][None], pp.ref[None])
    why = f"sampled: {searched} per slot, {len(starts)} minima narrowed and polished by the full-joint NLP"
    pairs = "constrained" if scene.self_pairs else "off"
    return BestResult("optimal", int(ids[k]), rows.psi[k], rows.q[k].copy(), rows.f[k],
                      clearance=float(d.min(initial=np.inf)), param_name=solver.param_name, message=why, time=elapsed,
                      method="search", rows=rows, self_collision=pairs)  # fmt: skip


def _sample(pp: PoseProblem) -> Samples:
    """Every slot at :func:`grid`'s values of the locked joint (one search each, progress lines after two seconds),
    with the objective and the clearances where it is valid inside the limits and searched."""
    robot, solver = pp.scene.robot, pp.solver
    t = grid(float(robot.q_min[solver.locked]), float(robot.q_max[solver.locked]))
    said = Progress(f"qpik.solve_best on {robot.name}: {solver.param_name} samples", len(t))
    parts = []
    for part in np.array_split(t, -(-len(t) // CHUNK)):
        parts.append(solver.solve_many(pp.T, part))
        said(sum(len(x.q) for x in parts))
    said.finish()
    q = np.concatenate([x.q for x in parts])  # (M, B, n)
    valid = np.concatenate([x.valid for x in parts])
    inside = valid & np.concatenate([x.within_limits for x in parts])
    inside[:, [k for k in range(solver.n_branches) if solver.branch_ids[k] not in pp.branches]] = False
    f, clear = _values(pp, q, inside)
    return Samples(t, q, valid, f, clear)


def _values(pp: PoseProblem, q: np.ndarray, inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The objective (+inf where not ``inside`` or closer than d_s) and the smallest clearance (m; −inf where not
    ``inside``) of configurations ``q`` (..., n), rad, where ``inside`` (...) (valid, within the limits, searched)."""
    f, clear = np.full(inside.shape, np.inf), np.full(inside.shape, -np.inf)
    if inside.any():
        values, d = pp.scene.evaluator.value_rows(q[inside], np.broadcast_to(pp.ref, (int(inside.sum()), len(pp.ref))))
        clear[inside] = d.min(axis=1, initial=np.inf)
        f[inside] = np.where(clear[inside] >= pp.scene.d_safe - CLEAR, values, np.inf)
    return f, clear


def _narrow(pp: PoseProblem, got: Samples, starts: list[tuple[int, int]]) -> list[tuple[np.ndarray, float, float]]:
    """Per start (index along the samples, slot), its slot's objective along t minimised by :data:`GOLDEN` steps of
    golden-section search (Kiefer 1953) between the start's two neighbouring samples, one search per step for all the
    starts: the best configuration found (n,) and the bracket (rad) left around it. The polish that follows stays in
    that bracket, so it cannot cross a fold into another slot's basin."""
    if not starts:
        return []
    t = got.t
    i, b = (np.array(x) for x in zip(*starts))
    a, c = t[np.maximum(i - 1, 0)], t[np.minimum(i + 1, len(t) - 1)]
    rows = np.arange(len(i))

    def value(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sol = pp.solver.solve_many(pp.T, x)  # each start's slot at its own x
        q = sol.q[rows, b]
        return _values(pp, q, sol.valid[rows, b] & sol.within_limits[rows, b])[0], q

    best_q, best_f = got.q[i, b], got.f[i, b]
    x1, x2 = c - RATIO * (c - a), a + RATIO * (c - a)
    (f1, q1), (f2, q2) = value(x1), value(x2)
    for step in range(GOLDEN + 1):
        for f, q in ((f1, q1), (f2, q2)):
            better = f < best_f
            best_f[better], best_q[better] = f[better], q[better]
        if step == GOLDEN:
            break
        left = f1 <= f2  # the minimum lies in [a, x2]
        c, a = np.where(left, x2, c), np.where(left, a, x1)
        x_new = np.where(left, c - RATIO * (c - a), a + RATIO * (c - a))
        f_new, q_new = value(x_new)
        x1, x2 = np.where(left, x_new, x2), np.where(left, x1, x_new)
        f1, f2 = np.where(left, f_new, f2), np.where(left, f1, f_new)
        q1, q2 = np.where(left[:, None], q_new, q2), np.where(left[:, None], q1, q_new)
    return [(best_q[k], float(a[k]), float(c[k])) for k in rows]


def _starts(f: np.ndarray) -> list[tuple[int, int]]:
    """The samples (index along t, slot) that are local minima of their slot's objective ``f`` (M, B) along t (+inf
    where not feasible; a run of equal values counts once), the :data:`STARTS` smallest."""
    pad = np.pad(f, ((1, 1), (0, 0)), constant_values=np.inf)
    low = np.isfinite(f) & (f < pad[:-2]) & (f <= pad[2:])
    i, b = np.nonzero(low)
    order = np.argsort(f[i, b], kind="stable")[:STARTS]
    return list(zip(i[order].tolist(), b[order].tolist()))


def _rows(pp: PoseProblem, got: Samples) -> BranchRows:
    """The per-slot table: each searched slot's best feasible sample (its objective, t, q; +inf where it has none), no
    polish rounds yet, its evaluations the samples (each one search of every slot)."""
    B, ids = pp.solver.n_branches, pp.solver.branch_ids
    best = np.argmin(got.f, axis=0)
    searched = [ids[k] in pp.branches for k in range(B)]
    columns = [(int(ids[k]), k, None, searched[k]) for k in range(B)]
    counts = [len(got.t) if s else 0 for s in searched]
    return BranchRows(columns, got.f[best, np.arange(B)].tolist(), got.t[best].tolist(),
                      got.q[best, np.arange(B)].copy(), [0] * B, counts)  # fmt: skip


def _not_found(pp: PoseProblem, got: Samples, rows: BranchRows, searched: str, elapsed: float) -> BestResult:
    """No feasible point found at the ``searched`` values: ``"not found"``, its q a sample: inside the limits but never
    clear, the one with the largest clearance (violation d_s minus it, m); else the valid one least outside the limits
    (rad); else, where no slot reaches the pose at any sample, the one nearest to it (the norm of its pose error, m and
    rad)."""
    robot, q, valid = pp.scene.robot, got.q, got.valid
    if np.isfinite(got.clear).any():
        i, b = np.unravel_index(np.argmax(got.clear), got.clear.shape)
        violation = pp.scene.d_safe - float(got.clear[i, b])
        why = f"no searched slot is clear of the obstacles at the {searched}; nothing proved"
    elif valid.any():
        beyond = np.maximum(robot.q_min - q, q - robot.q_max).max(axis=2)
        i, b = np.unravel_index(np.argmin(np.where(valid, beyond, np.inf)), valid.shape)
        violation = float(beyond[i, b])
        why = f"no searched slot is inside the limits at the {searched}; nothing proved"
    else:
        pos, rot = tracking_errors(robot.fk(q.reshape(-1, robot.dof)), pp.T)
        i, b = np.unravel_index(int(np.argmin(np.hypot(pos, rot))), valid.shape)
        violation = float(np.hypot(pos, rot).min())
        why = f"no slot reaches the pose at the {searched}; nothing proved"
    return BestResult("not found", int(pp.solver.branch_ids[b]), float(got.t[i]), q[i, b].copy(), np.inf,
                      violation=violation, param_name=pp.solver.param_name, message=why, time=elapsed,
                      method="search", rows=rows)  # fmt: skip
