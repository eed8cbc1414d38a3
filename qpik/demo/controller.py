"""Demo section: the QP controller in closed loop on the MuJoCo twin.

1. ``problems/iiwa_obstacle_reach.toml``: the iiwa reaches over a table past a
   ball, its posture reference chosen by the closed form; the same controller
   without the obstacle limit runs into the ball (3 s instead of the file's 5 s).
2. ``problems/zheng2019_clik.toml`` (Zheng et al. 2019): QP vs PD CLIK vs velocity-only
   feedback on the first 5 s of the path (the file runs 20 s).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from qpik.problems import find_problem, load
from qpik.problems.control import run_reach, run_track

TITLE = "QP controller"


def run(out: Path) -> None:
    folder = out / "controller"
    folder.mkdir(parents=True, exist_ok=True)
    for name, settings, runner in (
        ("iiwa_obstacle_reach", {"duration": 3.0}, run_reach),
        ("zheng2019_clik", {"duration": 5.0, "dt": 0.001}, run_track),
    ):
        problem = load(find_problem(name))
        problem = dataclasses.replace(problem, solver={**problem.solver, **settings})
        print(runner(problem, folder))
        print()
