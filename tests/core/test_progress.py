"""qpik.core.progress: long work speaks on stderr; short work does not."""

from __future__ import annotations

import numpy as np

import qpik
import qpik.core.progress as progress
from qpik.planning import PlanOptions, plan_self_motion


def test_silent_when_quick_then_counts_and_ends(capsys, monkeypatch):
    quiet = progress.Progress("work", 5)
    for k in range(5):
        quiet(k)
    quiet.finish()
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(progress, "QUIET", 0.0)
    monkeypatch.setattr(progress, "TICK", 0.0)
    said = progress.Progress("work", 5)
    for k in range(3):
        said(k)
    said.finish(3)
    lines = capsys.readouterr().err.splitlines()
    assert [ln.split(" (")[0] for ln in lines] == ["qpik: work: 0/5", "qpik: work: 1/5", "qpik: work: 2/5",
                                                   "qpik: work: 3/5"]  # fmt: skip
    off = progress.Progress("work", 5, enabled=False)
    off(1)
    off.finish()
    assert capsys.readouterr().err == ""


def test_a_plan_says_how_far_its_dp_is(capsys, monkeypatch):
    """With no quiet time the DP of a plan prints its waypoint count, up to the last waypoint."""
    monkeypatch.setattr(progress, "QUIET", 0.0)
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home + np.linspace(0.0, 0.2, 6)[:, None] * np.array([1, 0, 0, 1, 0, 0, 0])
    plan = plan_self_motion(robot, robot.fk(q), options=PlanOptions(resolution=64, refine=False, mujoco=False))
    assert plan.status == "dp", plan.summary()
    err = capsys.readouterr().err
    assert "the DP over 6 waypoints × 8 branches × 64 values, waypoint: 0/6" in err
    assert "waypoint: 6/6" in err
