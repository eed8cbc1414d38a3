"""``qpik plan``: one file prints its report and writes its files; a folder plans every plan file in it (local
processes); errors are one line with exit code 2."""

from __future__ import annotations

import shutil

import numpy as np

from qpik.cli import main
from qpik.problems import find_problem, load


def test_plan_one_file_prints_the_report_and_writes_the_plan(capsys, tmp_path):
    assert main(["plan", "nammoto2012_obstacle_plan", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "Overall: PASS" in out and "| NLP |" in out and "| QP controller (online) |" in out
    folder = tmp_path / "nammoto2012_obstacle_plan"
    assert (folder / "report.md").read_text().strip() == out.split("\nreport written to")[0].strip()
    q = np.load(folder / "nammoto2012_obstacle_plan_plan.npz")["q"]
    problem = load(find_problem("nammoto2012_obstacle_plan"))
    assert np.abs(problem.robot.fk(q) - problem.poses).max() < 1e-9


def test_plan_a_folder_in_local_processes(capsys, tmp_path):
    folder = tmp_path / "files"
    folder.mkdir()
    for name in ("nammoto2012_joint_limits_plan", "zheng7_plan", "nammoto2012_table4"):  # the ik file is skipped
        shutil.copy(find_problem(name), folder)
    assert main(["plan", str(folder), "-o", str(tmp_path / "out"), "--workers", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sorted(ln.split(":")[0] for ln in lines if ": PASS: " in ln) == ["nammoto2012_joint_limits_plan",
                                                                         "zheng7_plan"]  # fmt: skip
    assert (tmp_path / "out" / "zheng7_plan" / "report.md").is_file()


def test_plan_errors_are_one_line(capsys, tmp_path):
    assert main(["plan", "nammoto2012_table4"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("qpik plan:") and "not a planning problem" in err[0]
    assert main(["plan", str(tmp_path)]) == 2
    assert "no problem file of kind 'plan'" in capsys.readouterr().err
    assert main(["plan", "nammoto2012_joint_limits_plan", "--scheduler", "no-such-address"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("qpik plan: scheduler: cannot reach the Dask scheduler")
