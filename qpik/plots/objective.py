"""The objective of :func:`qpik.solve_best` against δ/ψ: every branch, its feasible set, the optimum.

:func:`objective_map` returns a matplotlib ``Figure`` (no pyplot state): on top, the objective as the
quantity it measures (:attr:`qpik.objectives.Objective.quantity`: the margin itself, not the −margin
that is minimised) along every branch's self-motion over (−π, π] where the branch is inside the joint
limits (the curves break where it leaves them) and, with obstacles, dotted where a link capsule comes
closer than d_s; the answer marked with a star and its value; below, each branch's exact feasible set
(:func:`qpik.feasible_intervals`) as bars. The legends name every line, marker and bar.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from qpik.analytic.api import feasible_intervals, ik
from qpik.core.errors import InputError
from qpik.nlp.best import solve_best
from qpik.nlp.best_result import BestResult
from qpik.plots.closed_form import PI, branch_colors, symbol
from qpik.plots.feasible import feasible_panel
from qpik.scene import Scene

OPTIMUM_GID = "optimum"  # gid of the star at the answer (for readers of the figure)


def objective_map(
    scene: Scene, pose: np.ndarray, result: BestResult | None = None, num: int = 1441, title: str | None = None
) -> Figure:
    """The objective against δ/ψ for every branch, the feasible sets shaded, the optimum marked.

    Args:
        scene: the arm (with a closed form, or the 1-D search's: then each of the ``num`` samples is one search, and
            its sets are sampled, seconds in all), its obstacles, d_safe, objective (default: the margin) and q_ref
            (:class:`~qpik.scene.Scene`), as :func:`qpik.solve_best` takes them.
        pose: (4, 4) end-effector pose, base frame.
        result: the answer to mark (default: :func:`qpik.solve_best` of the same problem).
        num: parameter samples over [−π, π] for the curves.
        title: figure title (default: robot, objective and the answer).
    """
    if not isinstance(scene, Scene):
        raise InputError(f"scene: expected a qpik.Scene (Scene.of(robot, obstacles, ...)), got {type(scene).__name__}")
    scene = scene.with_objective("margin")
    robot, obj, q_ref, d_safe = scene.robot, scene.objective, scene.q_ref, scene.d_safe
    if result is None:
        result = solve_best(scene, pose)
    psi = np.linspace(-PI, PI, num)
    sols = ik(robot, np.broadcast_to(np.asarray(pose, float), (num, 4, 4)), psi)
    fi = feasible_intervals(robot, pose)
    ids = [int(b) for b in sols.branch]
    colors = branch_colors(ids)
    ok = sols.within_limits
    f = np.full(ok.shape, np.nan)
    clear = np.full(ok.shape, True)
    if ok.any():
        values, _, d, _ = scene.evaluator(sols.q[ok], q_ref)
        f[ok] = values
        if d.shape[1]:
            clear[ok] = d.min(axis=1) >= d_safe
    sym = symbol(sols.param_name)
    quantity = obj.quantity
    shown = quantity.value(f)
    fig = Figure(figsize=(11, 8), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(2.2, 1))
    close = False
    for k, b in enumerate(ids):
        y = shown[:, k]
        top.plot(psi, np.where(clear[:, k], y, np.nan), color=colors[b], lw=1.6, label=f"branch {b}")
        if not clear[:, k].all():
            top.plot(psi, np.where(clear[:, k], np.nan, y), color=colors[b], lw=1.0, ls=":")
            close = True
    if close:  # the dotted style, in the legend after the branches
        top.plot([], [], color="0.3", lw=1.0, ls=":", label=f"dotted: a link closer than d_s = {d_safe:g} m")
    if result.status == "optimal":
        value = quantity.value(result.objective)
        answer = "the answer, certified" if result.certified else "the answer (best found, not certified)"
        top.plot([result.param], [value], "*", color="k", ms=16, zorder=5, gid=OPTIMUM_GID, label=answer)
        text = f"branch {result.branch}, {sym} = {result.param:.3f}\n{quantity.text(result.objective, '.4g')}"
        top.annotate(text, (result.param, value), textcoords="offset points", xytext=(10, 10), fontsize=9)
    top.set_ylabel(quantity.header + (", maximised" if quantity.maximised else ", minimised"))
    top.margins(y=0.14)  # room for the answer's label
    top.grid(alpha=0.3)
    top.legend(loc="best", fontsize=7, ncol=2)
    feasible_panel(bottom, fi, ids, result.branch if result.status == "optimal" else ids[0], colors)
    bottom.set_xlabel(f"{sym} [rad]")
    bottom.set_xlim(-PI, PI)
    bottom.set_xticks(np.linspace(-PI, PI, 5), ["−π", "−π/2", "0", "π/2", "π"])
    cert = "" if result.status != "optimal" else (", certified" if result.certified else ", not certified")
    minimised = f"; qpik minimises {quantity.minimised}" if quantity.minimised else ""
    fig.suptitle(title or f"{robot.name}: {quantity.name} against {sym} for every branch ({result.status}{cert}"
                 f"{minimised})", fontsize=11)  # fmt: skip
    return fig
