"""``--robot FILE`` and the model-file options of every subcommand that takes a robot, and problem files naming a
model: the CLI's answers against the library's on the same loaded arm."""

from __future__ import annotations

import re

import numpy as np
from conftest import MODEL_DIR, model_robot
from PIL import Image

import qpik
from qpik.cli import main

IIWA = str(MODEL_DIR / "robosuite_iiwa/robot.xml")
Q = "0.1 0.5 0.2 -1.2 0.3 0.9 0.4"


def test_fk_of_a_model_file(capsys):
    assert main(["fk", "-r", IIWA, "--collision-only", "--q", Q]) == 0
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.startswith("position (m):"))
    position = np.array([float(x) for x in re.findall(r"-?\d+\.\d+", line)])
    np.testing.assert_allclose(position, model_robot("robosuite_iiwa").fk(np.fromstring(Q, sep=" "))[:3, 3], atol=1e-6)


def test_ik_of_a_model_file_gives_back_q(capsys):
    assert main(["ik", "-r", IIWA, "--collision-only", "--q", Q]) == 0
    out = capsys.readouterr().out
    branch = int(re.search(r"branch (\d+)\)", out).group(1))
    row = next(ln for ln in out.splitlines() if ln.split() and ln.split()[0] == str(branch))
    np.testing.assert_allclose([float(x) for x in row.split()[1:8]], np.fromstring(Q, sep=" "), atol=1e-3)


def test_model_errors_are_one_line(capsys):
    assert main(["fk", "-r", IIWA, "--q", Q]) == 2  # its visual meshes are not shipped
    err = capsys.readouterr().err.strip()
    assert err.startswith("qpik fk: robot.xml: mesh") and "\n" not in err
    assert main(["ik", "-r", str(MODEL_DIR / "gymnasium_pusher/pusher_v5.xml"), "--q", Q]) == 2
    assert "branched chain" in capsys.readouterr().err
    pusher = ["-r", str(MODEL_DIR / "gymnasium_pusher/pusher_v5.xml"), "--tip", "tips_arm"]
    assert main(["fk", *pusher, "--q", "0 0 0 -0.5 0 -0.5 0"]) == 0
    assert main(["ik", "-r", model_robot("erd_panda").model.path.as_posix(), "--q", "0 0 0 -1 0 1 0", "-p", "0"]) == 2
    assert "not srs: axes 3-4-5 do not intersect" in capsys.readouterr().err


def test_render_a_model_file(tmp_path):
    out = tmp_path / "iiwa.png"
    assert main(["render", "-r", IIWA, "--collision-only", "--q", Q, "--size", "64,48", "-o", str(out)]) == 0
    if out.exists():  # no GL: the command says so and draws nothing
        assert Image.open(out).size == (64, 48)


def test_problem_file_naming_a_model(tmp_path, capsys):
    problem = tmp_path / "iiwa7_ik.toml"
    problem.write_text(
        f"""kind = "ik"
[robot]
model = "{IIWA}"
collision_only = true
[target]
q = [{Q.replace(" ", ", ")}]
[parameter]
value = 0.3
"""
    )
    loaded = qpik.problems.load(problem)
    assert loaded.robot.closed_form == "srs" and loaded.robot.joint_names[0] == "joint_1"
    assert main(["run", str(problem), "-o", str(tmp_path / "out")]) == 0
    assert "iiwa7" in capsys.readouterr().out
    problem.write_text(problem.read_text().replace("collision_only = true", "tip = 5"))
    assert main(["run", str(problem)]) == 2
    assert "robot.tip: expected a string" in capsys.readouterr().err
