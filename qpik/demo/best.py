"""Demo section: the globally best branch and δ/ψ (:func:`qpik.solve_best`), certified, and cross-checked.

1. ``problems/iiwa_obstacle_reach.toml``: for its target over a table and past a ball, the
   arm angle of every branch with the largest joint-limit margin among those that keep every
   link capsule 3 cm from both (certified), the per-branch table and a plot of the margin
   against ψ for every branch (the margin itself: qpik minimises −margin).
2. The joint-limit margin on ``nammoto7``'s 16 branches in δ for a pose of a random configuration.
3. The cross-validation of :mod:`qpik.checks.crosscheck` on one pose: closed form + 1-D search,
   full-joint NLP from its answer, QP controller at its answer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qpik.checks.crosscheck import crosscheck
from qpik.nlp import solve_best
from qpik.plots import save
from qpik.plots.objective import objective_map
from qpik.problems import find_problem, load
from qpik.robots.loader import load_robot
from qpik.scene import Scene

TITLE = "Best branch and δ/ψ (certified NLP)"
D_SAFE = 0.03  # m


def run(out: Path) -> None:
    folder = out / "best"
    folder.mkdir(parents=True, exist_ok=True)
    problem = load(find_problem("iiwa_obstacle_reach"))
    robot, pose, obstacles = problem.robot, problem.poses[0], problem.obstacles
    best = solve_best(robot, pose, "margin", obstacles, d_safe=D_SAFE)
    print(f"{robot.name}, target of {problem.name}: {best.quantity.goal}, every capsule ≥ {D_SAFE} m from the"
          " obstacles")  # fmt: skip
    print(best.table())
    print(best.summary())
    path = save(objective_map(Scene.of(robot, obstacles, d_safe=D_SAFE), pose, best), folder / "iiwa_margin.png")
    print(f"the margin against ψ for every branch: {path}")

    nammoto = load_robot("nammoto7")
    target = nammoto.fk(np.array([0.57, -0.96, -1.91, -2.01, 1.3, 1.21, 0.46]))
    best = solve_best(nammoto, target, "margin")
    print(f"\n{nammoto.name}: {best.quantity.goal}, over the 16 branches in δ")
    print(best.table())
    print(best.summary())
    path = save(objective_map(Scene.of(nammoto), target, best), folder / "nammoto_margin.png")
    print(f"the margin against δ for every branch: {path}")

    print("\ncross-validation (smooth joint-limit margin, iiwa14 target of the reach problem):")
    print(crosscheck(robot, pose, "smooth-margin", random_starts=10).report())
