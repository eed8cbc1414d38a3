"""qpik.nlp.certificate: it refutes false claims and proves true ones, with obstacles.

A claim is a value f* per pose; the certificate proves that no feasible δ/ψ is below f* − tol.
Soundness: claiming the search's answer + 0.005 is false (the answer itself is feasible and better),
so the certificate must refuse it on every pose, and refuse it by finding a feasible point that
beats the claim (the cell holding the answer can never be dropped by a sound bound). Completeness
(the bounds are tight enough to be useful): the search's answer, which tests/nlp/test_nlp_best.py
checks against dense sampling, is proved on most poses, with the clearance constraint active.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, model_robot, mujoco_poses, random_q

import qpik
from qpik.analytic import closed_form_for
from qpik.analytic.intervals import SAME
from qpik.geometry import Sphere
from qpik.geometry.distance import ObstacleSet
from qpik.nlp import solve_best
from qpik.nlp.certificate import INSET, certify, inside_ends
from qpik.nlp.options import BestOptions
from qpik.nlp.run import BestRun
from qpik.nlp.search import Pieces
from qpik.nlp.selfmotion import columns, selfmotion_of
from qpik.scene import Scene

POSES = 30
OBSTACLES = [Sphere((0.35, 0.25, 0.6), 0.1), Sphere((0.3, -0.35, 0.45), 0.1)]
D_SAFE = 0.02
TOL = 1e-4
EXCESS = 0.005
"""How far above the answer the false claims are (50 tol)."""


def _scene(robot, T, objective):
    sm = selfmotion_of(robot)
    obs = ObstacleSet(OBSTACLES)
    scene = BestRun(Scene.of(robot, obs, d_safe=D_SAFE, objective=objective), sm, T, np.zeros((len(T), robot.dof)))
    pieces = []
    for i, pose in enumerate(T):
        fi = sm.solver.feasible_intervals(pose)
        pieces += [(i, b, a, c) for b in range(sm.searched) for a, c in fi.intervals[b]]
    pose, row, lo, hi = (np.array(x) for x in zip(*pieces))
    return scene, Pieces(pose.astype(int), row.astype(int), lo.astype(float), hi.astype(float))


@pytest.mark.parametrize("focused", [False, True])
@pytest.mark.parametrize(("name", "objective"), [("iiwa14", "margin"), ("nammoto7", "clearance")])
def test_false_claims_are_refuted_and_true_ones_proved(name, objective, focused):
    """With ``focused``, each pose's first cell at a random (branch row, ψ) is cut finer from the start: another
    partition of the same sets, so the verdicts stand."""
    robot = qpik.load_robot(name)
    T = robot.fk(random_q(robot, POSES, 21))
    res = solve_best(robot, T, objective, OBSTACLES, d_safe=D_SAFE, options=BestOptions(certify=False))
    ok = np.flatnonzero([r.status == "optimal" for r in res])
    assert len(ok) >= 0.8 * POSES
    f = np.array([r.objective for r in res])[ok]
    scene, pieces = _scene(robot, T[ok], objective)
    tol = TOL * np.maximum(1.0, np.abs(f))
    rng = np.random.default_rng(3)
    sm = selfmotion_of(robot)
    focus = (rng.integers(0, sm.searched, len(ok)), rng.uniform(-np.pi, np.pi, len(ok))) if focused else None
    false = certify(scene, pieces, f + EXCESS, tol, np.arange(len(ok)), focus)
    assert not false.certified.any()
    assert false.better is not None and set(false.better.pose.tolist()) == set(range(len(ok)))
    assert np.all(false.better.f < (f + EXCESS - tol)[false.better.pose])
    true = certify(scene, pieces, f, tol, np.arange(len(ok)), focus)
    assert true.certified.mean() >= 0.8, [r for r, c in zip(true.reason, true.certified) if not c]
    assert np.all(f[true.certified] - true.bound[true.certified] <= tol[true.certified])


def test_piece_ends_move_onto_their_feasible_side_and_the_answers_are_proved():
    """robosuite's Jaco file (limits narrower than a turn, so a joint past its limit is given as its other
    representative, q ± 2π): its sets' ends are exact to SAME on either side of where a joint meets its limit, and a
    cell reaching past it holds that jump. ``inside_ends`` moves every end inside, by INSET to SAME + INSET, to where
    the compiled IK's branch is valid inside the limits (but ends at ±π, where a set through them is split); some ends
    of 20 poses needed the move. The margins found,
    which tests/nlp/test_nlp_best_files.py checks against dense sampling, are then proved on all of them (19 with the
    ends where they were: a cell at an end past a limit kept its bound below the answer down to 1e-9 rad)."""
    robot = model_robot("robosuite_jaco")
    T = mujoco_poses(robot, random_q(robot, 20, 400))
    scene, pieces = _scene(robot, T, "margin")
    first, last = inside_ends(scene, pieces.pose, pieces.row, pieces.lo, pieces.hi)
    narrow = pieces.hi - pieces.lo < 8 * INSET
    for end, moved in ((pieces.lo, first - pieces.lo), (pieces.hi, pieces.hi - last)):
        seam = np.abs(end) == np.pi  # a set wrapping through ±π split there: not an end, it stays
        assert np.all(narrow | np.where(seam, moved == 0, (moved >= 0.5 * INSET) & (moved <= SAME + 2 * INSET)))
        assert seam.any()
    solver = closed_form_for(robot)
    before, after = 0, 0
    for i, (pose, row) in enumerate(zip(pieces.pose, pieces.row)):
        old = solver.solve_many(T[pose], np.array([pieces.lo[i], pieces.hi[i]])).within_limits[:, row]
        new = solver.solve_many(T[pose], np.array([first[i], last[i]])).within_limits[:, row]
        before, after = before + int((~old).sum()), after + int((~new).sum())
    assert before > 0 and after == 0, (before, after)
    res = solve_best(Scene.of(robot, objective="margin", self_collision=False), T, options=BestOptions(certify=False))
    f = np.array([r.objective for r in res])
    run = BestRun(Scene.of(robot, objective="margin", self_collision=False), selfmotion_of(robot), T,
                  np.zeros((len(T), robot.dof)))  # fmt: skip
    proof = certify(run, pieces, f, TOL * np.maximum(1.0, np.abs(f)), np.arange(len(T)))
    assert proof.certified.all(), [r for r, c in zip(proof.reason, proof.certified) if not c]


ELBOW_POSES = [("erd_panda", [63, 99])] + ([("erd_talos", [4, 69, 83])] if LARGE else [])
"""The poses of the Panda and (in the large run: seconds of compiles) the TALOS file whose answers lay beside an end
where the elbow stretches or folds."""


@pytest.mark.parametrize(("key", "poses"), ELBOW_POSES)
def test_answers_beside_a_stretched_or_folded_elbow_are_proved(key, poses):
    """Poses of example-robot-data's Panda and TALOS arm (of 200 drawn inside the limits) whose sets end where the
    elbow stretches or folds (q4's subproblem 3 at r² = c²). There q4 = φ ± atan2(√(r² − c²), c) sits on atan2's cut
    (the vector (c, 0), c < 0), and a Taylor model over a cell touching that end spanned the whole turn, leaving a
    bound far below the answer at 1e-9 rad. The margins found (checked against dense samples in
    tests/nlp/test_nlp_best_files.py) are now proved on every one of them, and q4's bounds over a cell of 4e-9 rad at
    every end stay within 1e-3 rad (its change there is of order the square root of the width)."""
    robot = model_robot(key)
    T = mujoco_poses(robot, random_q(robot, 200, 400)[poses])
    res = solve_best(Scene.of(robot, objective="margin", self_collision=False), T)
    assert all(r.certified for r in res), [r.summary() for r in res]
    sm, elbow = selfmotion_of(robot), 3
    for pose in T:
        fi, cols = sm.solver.feasible_intervals(pose), columns(pose[None])
        for b in range(sm.searched):
            ends = [(a, a + 4e-9) for a, _ in fi.intervals[b]] + [(c - 4e-9, c) for _, c in fi.intervals[b]]
            for a, c in ends:
                low, high = (x[0, elbow] for x in sm.models(np.array([b]), cols, np.array([a]), np.array([c]))[3:])
                assert high - low < 1e-3, (key, b, a, c, low, high)


def test_answers_where_a_whole_turn_joint_passes_pi_are_proved():
    """robosuite's Jaco file, whose joints 1, 3, 5 and 7 have the limits ±2π: the IK gives each as its wrapped angle,
    which jumps by 2π where the joint passes ±π inside a feasible set (no breakpoint there). Three poses of 200 drawn
    inside the limits had a cell across such a jump whose bound (the hull of both sides) stayed below the answer at
    1e-9 rad. Across every such jump of those poses, found by sampling and bisection, the joint's model with
    ``turned`` (its angle in (0, 2π]) is as narrow as the cell and holds the joint's values at both ends (modulo 2π),
    while the plain model spans the jump; and the margins found (checked against dense samples in
    tests/nlp/test_nlp_best_files.py) are proved on all three."""
    robot = model_robot("robosuite_jaco")
    T = mujoco_poses(robot, random_q(robot, 200, 400)[[26, 119, 122]])
    res = solve_best(Scene.of(robot, objective="margin", self_collision=False), T)
    assert all(r.certified for r in res), [r.summary() for r in res]
    sm = selfmotion_of(robot)
    assert list(sm.turned) == [0, 2, 4, 6]
    jumps = 0
    for pose in T:
        fi, cols = sm.solver.feasible_intervals(pose), columns(pose[None])
        for b in range(sm.searched):
            for lo, hi in fi.intervals[b]:
                psi = np.linspace(lo, hi, 2001)
                q = sm.values(np.full(psi.size, b), np.repeat(cols, psi.size, 0), psi)[0][:, sm.turned]
                for i, k in zip(*np.nonzero(np.abs(np.diff(q, axis=0)) > np.pi)):
                    a, c = psi[i], psi[i + 1]
                    while c - a > 1e-9:  # the jump stays inside [a, c]
                        m = 0.5 * (a + c)
                        qa, qm = sm.values(np.full(2, b), np.repeat(cols, 2, 0), np.array([a, m]))[0][:, sm.turned[k]]
                        a, c = (a, m) if abs(qm - qa) > np.pi else (m, c)
                    ends = sm.values(np.full(2, b), np.repeat(cols, 2, 0), np.array([a, c]))[0][:, sm.turned[k]]
                    plain = sm.models(np.array([b]), cols, np.array([a]), np.array([c]))
                    turned = sm.models(np.array([b]), cols, np.array([a]), np.array([c]), turned=True)
                    low, high = turned[3][0, sm.turned[k]], turned[4][0, sm.turned[k]]
                    assert plain[4][0, sm.turned[k]] - plain[3][0, sm.turned[k]] > np.pi
                    assert high - low < 1e-6
                    assert np.all((np.mod(ends, 2 * np.pi) >= low - 1e-12) & (np.mod(ends, 2 * np.pi) <= high + 1e-12))
                    jumps += 1
    assert jumps >= 3
