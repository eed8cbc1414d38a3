"""``--robot FILE`` and the model-file options of every subcommand that takes a robot, and problem files naming a
model: the CLI's answers against the library's on the same loaded arm."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import MODEL_DIR, model_robot, packaged
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
    offset = model_robot("xarm7_offset").model.path.as_posix()  # example-robot-data's xArm7, axis 3 moved 1 mm
    package = f"example-robot-data={packaged('erd/xarm7').parents[3]}"  # the made file lies outside the package
    assert main(["ik", "-r", offset, "--package", package, "--q", "0 0 0 -1 0 1 0", "-p", "0"]) == 0  # the search's
    captured = capsys.readouterr()  # branches, then a line on its sampled feasible sets, not proved
    last = captured.out.strip().splitlines()[-1]
    assert last.startswith("branches with a feasible q7 range inside the limits: ") and last.endswith(
        "(not proved: qpik.feasible_intervals)"
    )


def test_render_a_model_file(tmp_path, capsys):
    out = tmp_path / "iiwa.png"
    code = main(["render", "-r", IIWA, "--collision-only", "--q", Q, "--size", "64,48", "-o", str(out)])
    err = capsys.readouterr().err
    if code == 2 and "nothing drawn, no OpenGL" in err:  # no GL: the command says so and draws nothing
        assert not out.exists()
        pytest.skip(err.strip())
    assert code == 0 and Image.open(out).size == (64, 48)


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


@pytest.mark.parametrize(
    "text, field",
    [("0,0.5,,-1.2,0.3,0.9,0.4", 3), (",0,0.5,0.2,-1.2,0.3,0.9", 1), ("0,0.5,0.2,-1.2,0.3,0.9,0.4,", 8)],
)
def test_an_empty_field_is_named(capsys, text, field):
    """An empty field of a list option is refused and named (not dropped, which left 6 numbers for --q)."""
    for argv in (
        ["fk", "-r", "iiwa14", "--q", text],
        ["ik", "-r", "iiwa14", "--q", text],
        ["ik", "-r", "iiwa14", "--position", text, "-p", "0"],
    ):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        assert f"field {field} of {text!r} is empty" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["fk", "-r", IIWA, "--joints", "joint_1,,joint_3", "--q", Q])
    assert "field 2 of 'joint_1,,joint_3' is empty" in capsys.readouterr().err


def test_lists_read_with_commas_spaces_or_both(capsys):
    """The same seven angles written three ways give the same pose (against the library's FK)."""
    want = qpik.load_robot("iiwa14").fk(np.array([0.1, 0.5, 0.2, -1.2, 0.3, 0.9, 0.4]))[:3, 3]
    for text in ("0.1,0.5,0.2,-1.2,0.3,0.9,0.4", " 0.1 0.5 0.2 -1.2 0.3 0.9 0.4 ", "0.1, 0.5 ,0.2, -1.2,0.3 0.9,0.4"):
        assert main(["fk", "-r", "iiwa14", "--q", text]) == 0
        line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("position (m):"))
        np.testing.assert_allclose([float(x) for x in re.findall(r"-?\d+\.\d+", line)], want, atol=1e-6)
    with pytest.raises(SystemExit):
        main(["fk", "-r", "iiwa14", "--q", "0,0.5,x,0,0,0,0"])
    assert "field 3 of '0,0.5,x,0,0,0,0' is not a number: 'x'" in capsys.readouterr().err


@pytest.mark.parametrize("robot", ["./nosuch.urdf", "nosuch.xml", "arms/nosuch", "NOSUCH.MJCF"])
def test_a_missing_model_file_is_no_such_file(tmp_path, monkeypatch, capsys, robot):
    """A robot named like a file (a folder in it or a model suffix) is a path: missing, it says "no such file"."""
    monkeypatch.chdir(tmp_path)
    assert main(["ik", "-r", robot, "--q", Q]) == 2
    err = capsys.readouterr().err
    assert err == f"qpik ik: {robot!r}: no such file (the catalog's arms: nammoto7, iiwa14, zheng7, panda)\n"
    assert main(["fk", "-r", str(tmp_path), "--q", Q]) == 2
    assert "is a folder, not a model file" in capsys.readouterr().err
    assert main(["fk", "-r", "ur5", "--q", Q]) == 2
    assert capsys.readouterr().err.startswith("qpik fk: unknown robot 'ur5'; known: nammoto7, iiwa14")


def test_allow_outside_reads_a_mesh_outside_the_package(tmp_path, capsys):
    """``--allow-outside``: a mesh path leaving the model's folder is refused by default, read with the flag."""
    import trimesh

    trimesh.creation.box((0.1, 0.1, 0.2)).export(tmp_path / "shared.stl")
    (tmp_path / "arm").mkdir()
    path = tmp_path / "arm" / "arm.urdf"
    path.write_text(
        '<robot name="one"><link name="b"/><link name="l"><collision><geometry><mesh filename="../shared.stl"/>'
        '</geometry></collision></link><joint name="j" type="revolute"><parent link="b"/><child link="l"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>'
    )
    assert main(["fk", "-r", str(path), "--q", "0.3"]) != 0
    assert "allow_outside=True" in capsys.readouterr().err
    assert main(["fk", "-r", str(path), "--allow-outside", "--q", "0.3"]) == 0
