"""The README's promises: its first two commands, .ci/run, and its Python examples run."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_readme_opens_with_the_two_setup_commands_and_ci_runs_the_test_one() -> None:
    first_block = re.search(r"```bash\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert first_block == ['pip install -e . && qpik demo', 'pip install -e ".[test]" && pytest']
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install -e ".[test]" && pytest' in ci


def test_python_examples_run_and_mean_what_they_say() -> None:
    ns: dict = {}
    for block in re.findall(r"```python\n(.*?)```", README, re.S):
        exec(compile(block, "README.md", "exec"), ns)
    robot, sols = ns["robot"], ns["sols"]  # the last robot is the controller example's iiwa14
    assert sols.q.shape == (16, 7) and sols.valid.all()
    # the controller example's solve_ik reached its target (FK, independent of the controller)
    T = robot.fk(ns["q_star"])
    assert np.abs(T - ns["target"]).max() < 1e-9
    assert ns["v"].shape == (7,) and np.all(np.abs(ns["v"]) <= robot.v_max + 1e-9)
    # the numerical IK example reached its goal inside the limits
    panda, q_ik = ns["panda"], ns["q_ik"]
    assert np.abs(panda.fk(q_ik) - ns["goal"]).max() < 1e-9 and panda.within_limits(q_ik)
    assert ns["res"].status == "ok" and np.array_equal(ns["res"].q, q_ik)
    # the planning example's plan reaches every waypoint inside the limits, and its retiming respects v_max
    arm, plan, timed = ns["arm"], ns["plan"], ns["timed"]
    assert plan.ok and np.abs(arm.fk(plan.q) - ns["way"]).max() < 1e-9 and arm.within_limits(plan.q).all()
    assert (np.abs(timed.qd) / arm.v_max).max() < 1.01
