r"""The per-branch NLP in δ/ψ solved by IPOPT: ``solve_best(..., method="ipopt")``.

For branch b and a feasible interval [lo, hi] of it:

.. math::

    \min_{\psi,\ t}\ s(q_b(\psi)) + \sum_k w_k t_k \quad\text{s.t.}\quad
    h_{k,i}(q_b(\psi)) \le t_k,\quad d_{k,o}(q_b(\psi)) \ge d_s,\quad lo \le \psi \le hi,

the objective's split (:class:`qpik.objectives.Split`) in epigraph form, q the branch's closed
form traced in CasADi (exact first and second derivatives). One ``casadi.nlpsol`` per (robot,
objective form, obstacle families, branch), with the pose, the objective's parameters, q_ref,
the obstacles and d_s as parameters, so it is built once; IPOPT starts at the middle of every
interval. :mod:`qpik.nlp.search` reaches the same minima faster (``qpik bench nlp`` compares
them); this form is kept as the reference the tests check the search against.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from qpik.nlp.run import BestRun
from qpik.nlp.search import Pieces
from qpik.objectives import Context

OPTIONS = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": 1e-12,
    "ipopt.max_iter": 200,
    "show_eval_warnings": False,
    "calc_lam_p": False,
}
"""IPOPT options of the per-branch NLPs."""


def _solver(scene: BestRun, b: int) -> tuple[ca.Function, ca.Function]:
    """``(nlpsol, start)`` of branch row b: ``start(T, ψ, p) -> [t (K,)]`` (the maxima at ψ, a start for t)."""
    robot, obs = scene.robot, scene.obstacles
    key = ("branch nlp", scene.objective.key(), obs.kinds, len(scene.params), b, scene.self_pairs)
    return robot.cache.get(key, _build, scene, b)


def _build(scene: BestRun, b: int) -> tuple[ca.Function, ca.Function]:
    robot, obs = scene.robot, scene.obstacles
    n = robot.dof
    T, psi = ca.SX.sym("T", 4, 4), ca.SX.sym("psi")
    p_obj, q_ref = ca.SX.sym("p", len(scene.params)), ca.SX.sym("q_ref", n)
    prm, d_s = ca.SX.sym("obstacles", len(obs.params)), ca.SX.sym("d_safe")
    Q, _, _ = scene.selfmotion.solver.casadi_function(T, psi)
    ctx = Context(robot, Q[b, :].T, q_ref, obs, prm, self_pairs=scene.self_pairs)
    split = scene.objective.split(ctx, p_obj)
    t, cost, g_epi = split.epigraph()
    g = ca.vertcat(g_epi, d_s - ctx.clearances)
    p = ca.vertcat(ca.vec(T), p_obj, q_ref, prm, d_s)
    nlp = {"x": ca.vertcat(psi, t), "f": cost, "g": g, "p": p}
    solver = ca.nlpsol(f"branch_{robot.identifier}_{b}", "ipopt", nlp, OPTIONS)
    start = ca.Function("start", [psi, p], [ca.vertcat(*[ca.mmax(h) for _, h in split.maxima], ca.SX(0, 1))])
    return solver, start


def solve_pieces(scene: BestRun, pieces: Pieces):
    """IPOPT on every piece; returns ``(pose, row, ψ, q, f, iterations, clearance)`` arrays of the
    converged solutions (the argument order of the search's best-so-far table). The NLPs of the pieces' branch rows
    are built first, with the scene's clock paused."""
    with scene.watch.paused():
        for b in np.unique(pieces.row).tolist():
            _solver(scene, b)
    out: list[tuple] = []
    n_g = None
    for i, b, lo, hi in zip(pieces.pose, pieces.row, pieces.lo, pieces.hi):
        solver, start = _solver(scene, int(b))
        p = np.concatenate(
            [scene.poses[i].T.ravel(), scene.params, scene.q_ref[i], scene.obstacles.params, [scene.d_safe]]
        )
        mid = 0.5 * (lo + hi)
        t0 = np.asarray(start(mid, p)).ravel()
        n_g = solver.size1_out("g") if n_g is None else n_g
        x0 = np.concatenate([[mid], t0 + 1e-3])
        lbx = np.concatenate([[lo], np.full(len(t0), -np.inf)])
        ubx = np.concatenate([[hi], np.full(len(t0), np.inf)])
        sol = solver(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=-np.inf, ubg=0.0)
        stats = solver.stats()
        scene.counts[i, b] += int(stats.get("iter_count", 0)) + 1
        if not stats.get("success", False):
            continue
        psi = float(np.asarray(sol["x"])[0, 0])
        pt = scene.evaluate(np.array([i]), np.array([b]), np.array([psi]))
        if not pt.valid[0] or pt.c[0] < -1e-9:
            continue
        clear = float(pt.d.min()) if pt.d.size else np.inf
        out.append((i, b, psi, pt.q[0], float(pt.f[0]), int(stats["iter_count"]), clear))
    if not out:
        return (np.zeros(0, int),) * 2 + (np.zeros(0),) + (np.zeros((0, scene.robot.dof)),) + (np.zeros(0),) * 3
    cols = list(zip(*out))
    return tuple(np.array(c) for c in cols)
