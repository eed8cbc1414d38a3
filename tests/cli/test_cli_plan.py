"""``qpik plan``: one file prints its report and writes its files; a folder plans every plan file in it (local
processes); usage errors are one line with exit code 2; names are checked before anything runs, a bad file
is reported while the others run, and a FAIL or a failed job gives exit code 1."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

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


# ---- qpik plan DIR loses nothing: names checked before anything runs, a bad file reported, exit 1 on FAIL --------

SMALL = find_problem("nammoto2012_joint_limits_plan").read_text().replace("num = 61", "num = 11")


def _folder(tmp_path, files: dict[str, str]):
    folder = tmp_path / "files"
    folder.mkdir()
    for stem, text in files.items():
        (folder / f"{stem}.toml").write_text(text)
    return folder


def _named(name: str, extra: str = "") -> str:
    return SMALL.replace('name = "nammoto2012_joint_limits_plan"', f"name = {name!r}".replace("'", '"')) + extra


def test_two_files_of_one_name_are_an_error_before_anything_runs(capsys, tmp_path):
    folder = _folder(tmp_path, {"a": _named("same"), "b": _named("Same")})
    assert main(["plan", str(folder), "-o", str(tmp_path / "out"), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "a.toml and" in err and "b.toml both have the name 'Same'" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["../../x", "..", ".", "", "a/b", "a\\\\b", "tab\\there"])
def test_a_name_that_leaves_the_output_folder_is_an_error(capsys, tmp_path, name):
    folder = _folder(tmp_path, {"a": _named(name)})
    out = tmp_path / "deep" / "out"
    assert main(["plan", str(folder), "-o", str(out), "--workers", "0"]) == 2
    assert "cannot be an output folder's name" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.toml", "files"]  # nothing written anywhere


def test_a_bad_file_is_reported_and_the_others_run_a_fail_and_a_raising_job_exit_1(capsys, tmp_path):
    files = {
        "good": _named("good"),
        "broken": 'kind = "plan\n',  # not TOML
        "fails": _named("fails").replace("max_joint_step = 0.2", "max_joint_step = 0.001"),
        "raises": _named(
            "raises",
        ).replace("[solver]\n", "[solver]\nresolution = 9\n"),  # odd: the planner refuses
    }
    folder = _folder(tmp_path, files)
    out = tmp_path / "out"
    assert main(["plan", str(folder), "-o", str(out), "--workers", "0"]) == 1
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    assert any(ln.startswith("good: PASS: ") for ln in lines) and any(
        ln.startswith("fails: FAIL: failed") for ln in lines
    )
    assert any(ln.startswith("raises: error: InputError: resolution: expected an even integer in [8, ") for ln in lines)
    assert "broken.toml: not valid TOML" in captured.err and "raises.toml: InputError: resolution" in captured.err
    assert "2 file(s) not planned" in captured.err
    assert sorted(p.name for p in out.iterdir()) == ["fails", "good"]
    assert "Overall: PASS" in (out / "good" / "report.md").read_text()
    assert "Overall: FAIL" in (out / "fails" / "report.md").read_text()


def test_exit_codes_of_one_file(capsys, tmp_path):
    folder = _folder(tmp_path, {"fails": _named("fails").replace("max_joint_step = 0.2", "max_joint_step = 0.001")})
    assert main(["plan", str(folder / "fails.toml"), "-o", str(tmp_path / "out")]) == 1
    assert "Overall: FAIL" in capsys.readouterr().out
    assert main(["plan", str(folder / "nope.toml")]) == 2
    assert main(["plan", str(folder), "--workers", "-1"]) == 2
