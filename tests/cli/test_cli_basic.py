"""``qpik fk``, ``qpik problems`` and ``qpik run`` through ``qpik.cli.main``."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import MODEL_DIR

import qpik
from qpik.cli import build_parser, main
from qpik.cli.fk import roll_pitch_yaw
from qpik.problems import problems_folder
from qpik.problems import runners as runners_module


def numbers_after(label: str, text: str) -> np.ndarray:
    line = next(ln for ln in text.splitlines() if ln.startswith(label))
    return np.array([float(x) for x in re.findall(r"-?\d+\.\d+", line[len(label) :])])


def test_fk_prints_pose_position_and_rpy(capsys):
    q = np.array([0.16, 1.2, 0.5, -1.0, 0.6, 0.5, 0.3])
    assert main(["fk", "--robot", "iiwa14", "--q", " ".join(map(str, q))]) == 0
    out = capsys.readouterr().out
    T = qpik.load_robot("iiwa14").fk(q)
    np.testing.assert_allclose(numbers_after("position (m):", out), T[:3, 3], atol=1e-6)
    roll, pitch, yaw = numbers_after("roll, pitch, yaw (rad):", out)
    Rz = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    Ry = np.array([[np.cos(pitch), 0, np.sin(pitch)], [0, 1, 0], [-np.sin(pitch), 0, np.cos(pitch)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(roll), -np.sin(roll)], [0, np.sin(roll), np.cos(roll)]])
    np.testing.assert_allclose(Rz @ Ry @ Rx, T[:3, :3], atol=1e-5)
    assert "outside the joint limits" not in out


def test_roll_pitch_yaw_round_trip():
    rng = np.random.default_rng(0)
    for R in np.linalg.qr(rng.normal(size=(50, 3, 3)))[0]:
        R = R * np.sign(np.linalg.det(R))
        r, p, y = roll_pitch_yaw(R)
        cz, sz, cy, sy, cx, sx = np.cos(y), np.sin(y), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
        back = np.array(
            [
                [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
                [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
                [-sy, cy * sx, cy * cx],
            ]
        )
        np.testing.assert_allclose(back, R, atol=1e-12)


def test_fk_in_degrees_and_outside_limits(capsys):
    assert main(["fk", "-r", "panda", "--q=0,0,0,-90,0,90,45", "--deg"]) == 0
    out = capsys.readouterr().out
    T = qpik.load_robot("panda").fk(np.deg2rad([0, 0, 0, -90, 0, 90, 45]))
    np.testing.assert_allclose(numbers_after("position (m):", out), T[:3, 3], atol=1e-6)
    assert main(["fk", "-r", "panda", "--q", "0 0 0 0 0 0 0"]) == 0  # q4 = 0 is past panda's -0.07 limit
    assert "outside the joint limits" in capsys.readouterr().out


def test_fk_rejects_wrong_length_naming_q(capsys):
    assert main(["fk", "-r", "iiwa14", "--q", "0 0 0"]) == 2
    assert re.search(r"qpik fk: q: expected shape \(7,\)", capsys.readouterr().err)
    with pytest.raises(SystemExit):
        main(["fk", "-r", "iiwa14", "--q", "a b c"])


def test_problems_lists_the_shipped_files(capsys):
    assert main(["problems"]) == 0
    out = capsys.readouterr().out
    for name, kind, robot in [
        ("nammoto2012_table4", "ik", "nammoto7"),
        ("shimizu2008_iiwa", "ik", "iiwa14"),
        ("zheng2019_clik", "track", "zheng7"),
    ]:
        assert re.search(rf"^{name}\s+{kind}\s+{robot}\s+\S", out, re.M), name


def test_problems_reports_bad_files(tmp_path, capsys):
    good = 'kind = "reach"\n[robot]\nname = "panda"\n[target]\nrandom = {seed = 0, count = 3}\n'
    (tmp_path / "good.toml").write_text(good)
    (tmp_path / "bad.toml").write_text('kind = "reach"\n[robot]\nname = "ur5"\n')
    assert main(["problems", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert re.search(r"^good\s+reach\s+panda", out, re.M)
    assert re.search(r"^bad\s+!.*cannot load: .*bad\.toml: top level: missing target", out, re.M)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["problems", str(empty)]) == 1
    assert "no problem files" in capsys.readouterr().out


def test_run_calls_the_runner_of_the_kind_and_writes_the_report(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(runners_module, "RUNNER_MODULES", ())
    monkeypatch.setattr(runners_module, "RUNNERS", {})
    calls = []

    @runners_module.runner("track")
    def fake(problem, out):
        calls.append((problem.name, out))
        return f"# {problem.name}\nduration {problem.path.duration} s"

    out = tmp_path / "out"
    assert main(["run", "zheng2019_clik", "-o", str(out)]) == 0
    assert calls == [("zheng2019_clik", out)]
    printed = capsys.readouterr().out
    assert "# zheng2019_clik" in printed and "duration 6.0 s" in printed
    assert (out / "report.md").read_text() == "# zheng2019_clik\nduration 6.0 s\n"
    # by path too
    assert main(["run", str(problems_folder() / "zheng2019_clik.toml"), "-o", str(out)]) == 0


def test_run_without_a_runner_fails_cleanly(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(runners_module, "RUNNER_MODULES", ())
    monkeypatch.setattr(runners_module, "RUNNERS", {})
    assert main(["run", "nammoto2012_table4", "-o", str(tmp_path)]) == 2
    assert "no runner for kind 'ik' yet" in capsys.readouterr().err
    assert main(["run", "no_such_problem"]) == 2
    assert "no such file" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ["problems"],
        ["fk", "-r", "iiwa14", "--q", "0 0.5 0 -1 0 1 0"],
        ["--help"],
        ["bench", "-h"],
        ["fk", "-r", "ur5", "--q", "0 0 0 0 0 0 0"],
    ],
)
def test_a_closed_output_ends_quietly(argv):
    """Standard output is a pipe whose reader has gone (``qpik problems | head -1``): no message, exit code 141 as a
    program ended by SIGPIPE gives (help: argparse drops what it cannot write, exit 0); an error still prints its
    one line on stderr."""
    read, write = os.pipe()
    os.close(read)
    code = f"import sys; from qpik.cli import main; sys.exit(main({argv!r}))"
    try:
        out = subprocess.run([sys.executable, "-c", code], stdout=write, stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(write)
    if "ur5" in argv:  # nothing written to stdout: the error's line, as always
        assert out.returncode == 2 and out.stderr.startswith("qpik fk: unknown robot 'ur5'")
        assert out.stderr.count("\n") == 1
    else:
        assert out.stderr == "" and out.returncode in ((0, 141) if "-h" in argv or "--help" in argv else (141,))


def test_every_default_is_stated_as_it_is():
    """The help of every option with a default says ``default: X``, and X is the value the parser uses."""
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    seen = 0
    for name, parser in sub.choices.items():
        for action in parser._actions:
            if action.default in (None, False, [], argparse.SUPPRESS) or action.help is None:
                continue
            stated = re.search(r"default: ([^);]+)", action.help)
            assert stated, (name, action.dest, action.help)
            value = stated.group(1)
            assert (
                float(value) == action.default
                if isinstance(action.default, float | int)
                else value == str(action.default)
            ), (name, action.dest, value, action.default)
            seen += 1
    assert seen >= 8  # --repeat, --objective, --d-safe, --tol, --method and three output paths


def test_best_reads_the_model_file_options(capsys):
    """``qpik best -r FILE`` takes the model file options as the other commands do (an unknown --tip is named)."""
    iiwa = str(MODEL_DIR / "robosuite_iiwa/robot.xml")
    assert main(["best", "-r", iiwa, "--collision-only", "--tip", "no_such_body", "--q", "0 0.5 0 -1 0 1 0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("qpik best: ") and "no_such_body" in err and err.count("\n") == 1
