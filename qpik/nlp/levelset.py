r"""The joint-limit margin's global maximum from its exact super-level sets (:func:`qpik.solve_best`'s method
for the margin objective without obstacles).

The margin of a configuration (:class:`~qpik.objectives.JointLimitMargin`, :math:`\rho_j` the half range)

.. math:: \mu(q) = \min_j \min(q_j - l_j,\ u_j - q_j) / \rho_j

is at least m exactly where every joint lies in the limits shrunk by :math:`m\rho_j`. So the super-level
set :math:`S(m) = \{(b, \psi) : \mu(q_b(\psi)) \ge m\}` of every branch b is its exact feasible set under
the shrunk limits, :meth:`~qpik.analytic.solver.AnalyticSolver.feasible_intervals` with ``margin=m``:
computed from the breakpoint equations, not sampled. Per pose, from :math:`S(0)` (the feasible intervals):

1. On every piece [a, b] of :math:`S(m_k)` (a piece through ±π joined into one), evaluate μ and
   dμ/dψ at both ends and the middle, then μ at the trial points: the crossing of the tangents at the two
   ends (exact at a kink, where two joints' margins cross), the root of the secant of dμ/dψ between them
   (exact at a quadratic top), both again on the half of the piece toward which dμ/dψ points at the
   middle, and samples at most :data:`STEP` apart. All pieces of all poses share each compiled call.
2. :math:`\mu_{k+1}` is the best value found, :math:`m_{k+1} = \mu_{k+1} + \varepsilon`
   (:data:`EPS`).
3. An empty :math:`S(m_{k+1})` proves that no branch and δ/ψ reaches :math:`\mu_{k+1} + \varepsilon`:
   the answer is certified to ε. Otherwise every point of :math:`S(m_{k+1})` beats it: back to 1.

Every point of :math:`S(m_{k+1})` is better than the best so far by ε, so each round gains at least ε;
near a top the pieces close in on it from both sides, and the trial points land on it (a kink: the
tangents; a smooth top: the secant), so the gap closes about quadratically, in a few rounds. A pose
whose round finds nothing inside its own super-level set (the sets' boundaries are exact to
:data:`qpik.analytic.intervals.SAME` only), or that needs more than :data:`MAX_ROUNDS`, is left
uncertified: :func:`qpik.solve_best` searches it by sampling and proves it with the Taylor models
(:mod:`qpik.nlp.certificate`) instead.

The certificate costs one feasible-interval call (tens of µs) where the Taylor models of the
certificate need ~150 cells of a compiled bound function; it covers only the plain margin (a weighted
sum with other terms has no such level sets).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from qpik.analytic.intervals import FeasibleIntervals, wrap
from qpik.geometry.distance import ObstacleSet
from qpik.nlp.scene import Points, Scene
from qpik.nlp.search import END
from qpik.objectives import JointLimitMargin, Objective

EPS = 1e-9
r"""ε: each level is the best margin found plus this (the certificate's gap, in μ; about what the sets'
boundaries, exact to 1e-9 rad, can resolve)."""
MAX_ROUNDS = 12
"""Most rounds per pose before it is left to the search."""
TWO_PI = 2.0 * np.pi
NEAR = 1e-7
"""A trial point this close (rad) to an end of a piece gives the slope there."""
SLACK = 1e-12
"""A piece lies in its parent to this (rad): the sets' ends move with the level, and by rounding."""
ROWS = 64
"""More than any arm's branch rows (a piece's key: pose · ROWS + row)."""


def margin_weight(objective: Objective, obstacles: ObstacleSet, robot) -> float | None:
    """w when the objective is w · the (epigraph) margin with w > 0, there are no obstacles and no joint's
    range spans a whole turn: the cases this method solves. None otherwise."""
    if len(obstacles) or len(objective.terms) != 1:
        return None
    ((w, term),) = objective.terms
    if not isinstance(term, JointLimitMargin) or term.smooth or not w > 0:
        return None
    if np.any(np.asarray(robot.q_max) - np.asarray(robot.q_min) >= TWO_PI):
        return None
    return float(w)


@dataclass
class LevelSets:
    """What :func:`maximise` found.

    Attributes:
        points: every evaluated point.
        rounds: (M,) the round of each point (1 for the first).
        certified: (N,) the best point of the pose is proved to be within ε of the maximum.
        bound: (N,) for a certified pose, a lower bound of the objective over every feasible point
            (−w (μ + ε)); -inf otherwise.
    """

    points: Points
    rounds: np.ndarray
    certified: np.ndarray
    bound: np.ndarray


def maximise(scene: Scene, sets: list[FeasibleIntervals], rows: list[int], weight: float) -> LevelSets:
    """The rounds of the module docstring for every pose of ``scene`` from its feasible sets ``sets`` (the
    level-0 super-level sets), over the branch rows ``rows``; f = −``weight`` · μ."""
    solver = scene.selfmotion.solver
    N = len(scene.poses)
    best = np.full(N, -np.inf)
    level = np.zeros(N)
    certified = np.zeros(N, bool)
    parts, rounds = [], []
    current = dict(enumerate(sets))
    parent = None
    for k in range(MAX_ROUNDS):
        pieces = _pieces(current, rows, level)
        found = np.zeros(N, bool)
        found[pieces.pose] = True
        if k:
            certified[[i for i in current if not found[i]]] = True
        if not len(pieces):
            break
        psi = _trials(pieces, parent)  # (3, P)
        pts = scene.evaluate(np.tile(pieces.pose, len(psi)), np.tile(pieces.row, len(psi)), wrap(psi.ravel()))
        parts.append(pts)
        rounds.append(np.full(len(pts), k + 1))
        ok = pts.valid & np.isfinite(pts.f)
        mu = np.where(ok, -pts.f / weight, -np.inf)
        top = np.full(N, -np.inf)
        np.maximum.at(top, pts.pose, mu)
        pieces.x, pieces.mu = psi, mu.reshape(len(psi), -1)
        pieces.slope = np.where(ok, -pts.df / weight, np.nan).reshape(len(psi), -1)
        # inside S(level) every point has μ ≥ level: a pose whose round found nothing there is left to the search
        moved = found & (top > level - 0.5 * EPS) if k else found
        best = np.where(found, np.maximum(best, top), best)
        moved &= np.isfinite(best)
        level = np.maximum(best, 0.0) + EPS
        current = {i: solver.feasible_intervals(scene.poses[i], margin=float(level[i])) for i in np.flatnonzero(moved)}
        parent = pieces
    points = Points.join(parts) if parts else scene.values(np.zeros(0, int), np.zeros(0, int), np.zeros(0))
    bound = np.where(certified, -weight * level, -np.inf)
    return LevelSets(points, np.concatenate(rounds) if rounds else np.zeros(0, int), certified, bound)


@dataclass
class _Pieces:
    """Pieces of super-level sets: [lo, hi] (rad, hi ≤ lo + 2π) of branch row ``row`` of pose ``pose`` at
    ``level`` (μ), all (P,); after their round, the trial points ``x`` (3, P) with μ (``mu``) and dμ/dψ
    (``slope``) there (−inf and NaN where the branch does not reach the pose)."""

    pose: np.ndarray
    row: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    level: np.ndarray
    x: np.ndarray | None = None
    mu: np.ndarray | None = None
    slope: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.lo)

    @property
    def key(self) -> np.ndarray:
        """(P,) one integer per (pose, branch row)."""
        return self.pose * ROWS + self.row


def _pieces(sets: dict[int, FeasibleIntervals], rows: list[int], level: np.ndarray) -> _Pieces:
    """The pieces of the sets' rows ``rows`` (pose i's sets at ``level[i]``); a set through ±π (one interval
    ending at π, one starting at −π) is one piece [lo, hi + 2π]."""
    pose, row, lo, hi = [], [], [], []
    for i, fi in sets.items():
        for b in rows:
            ivs = fi.intervals[b]
            if len(ivs) > 1 and ivs[0][0] == -np.pi and ivs[-1][1] == np.pi:
                ivs = [(ivs[-1][0], ivs[0][1] + TWO_PI), *ivs[1:-1]]
            for a, c in ivs:
                pose.append(i), row.append(b), lo.append(a), hi.append(c)
    pose_a = np.array(pose, int)
    return _Pieces(pose_a, np.array(row, int), np.array(lo, float), np.array(hi, float), level[pose_a])


def _trials(pieces: _Pieces, parent: _Pieces | None) -> np.ndarray:
    """(3, P) trial points of the pieces (rad, in [lo, hi]): the middle, the crossing of the tangents at the two
    ends, and the root of the secant of dμ/dψ between the points the tangents' slopes come from.

    The slope at the left end (a level crossing) comes from the best point x with dμ/dψ > 0 of the previous
    round's piece that holds this one (its parent): 2 (level − μ(x))/(lo − x) − μ'(x), exact for a quadratic
    (μ'(x) itself when x is the end, :data:`NEAR`);
    without such a point, the secant through the two level crossings (lo_parent, level_parent) and (lo, level).
    The right end likewise, with dμ/dψ < 0. Where one side has no such point, the end of that side (:data:`END`
    inside) instead of the root: its slope serves the next round. In the first round: the middle and both ends.

    After the first round a pose has a few pieces: plain floats, which cost less than numpy's calls here."""
    lo, hi = pieces.lo, pieces.hi
    inset = np.minimum(END, 0.25 * (hi - lo))
    if parent is None:
        return np.stack([0.5 * (lo + hi), lo + inset, hi - inset])
    holders: dict[int, list[int]] = {}
    for k, key in enumerate(parent.key.tolist()):
        holders.setdefault(key, []).append(k)
    p_lo, p_hi, p_level = parent.lo.tolist(), parent.hi.tolist(), parent.level.tolist()
    p_x, p_mu, p_slope = parent.x.T.tolist(), parent.mu.T.tolist(), parent.slope.T.tolist()
    out = []
    rows = zip(lo.tolist(), hi.tolist(), pieces.level.tolist(), pieces.key.tolist(), inset.tolist())
    for a, b, level, key, e in rows:
        mid = 0.5 * (a + b)
        k = next((k for k in holders.get(key, ()) if p_lo[k] <= a + SLACK and b <= p_hi[k] + SLACK), None)
        if k is None:
            out.append((mid, mid, mid))
            continue
        side = []  # per end: (the slope there, the point it came from or None)
        for end, p_end, sign in ((a, p_lo[k], 1.0), (b, p_hi[k], -1.0)):
            top = None
            for x, f, d in zip(p_x[k], p_mu[k], p_slope[k]):
                if sign * d > 0 and (top is None or f > top[1]):
                    top = (x + TWO_PI * round((mid - x) / TWO_PI), f, d)  # beside this piece (one may pass π)
            if top is not None and abs(end - top[0]) <= NEAR:  # the point is the end: its own slope
                side.append((top[2], top))
            elif top is not None:
                side.append((2.0 * (level - top[1]) / (end - top[0]) - top[2], top))
            else:
                side.append(((level - p_level[k]) / (end - p_end) if end != p_end else sign * math.inf, None))
        (sl, left), (sr, right) = side
        cross = (sl * a - sr * b) / (sl - sr) if sl > 0 > sr and math.isfinite(sl - sr) else mid
        if left is not None and right is not None and left[2] != right[2]:
            root = left[0] - left[2] * (right[0] - left[0]) / (right[2] - left[2])
        else:
            root = b - e if left is not None else a + e
        out.append((mid, min(max(cross, a), b), min(max(root, a), b) if math.isfinite(root) else mid))
    return np.array(out).T
