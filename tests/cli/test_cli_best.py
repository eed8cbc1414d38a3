"""``qpik best``: the printed configuration reaches the pose (FK), the table lists every branch, errors are one line."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import model_robot
from PIL import Image

import qpik
from qpik.cli import main


def _q_star(out: str) -> np.ndarray:
    line = next(ln for ln in out.splitlines() if ln.startswith("q* = "))
    return np.array([float(v) for v in line[line.index("[") + 1 : line.index("]")].split()])


@pytest.mark.parametrize("name, count", [("iiwa14", 8), ("nammoto7", 16)])
def test_best_prints_the_table_and_a_configuration_on_the_pose(capsys, tmp_path, name, count):
    robot = qpik.load_robot(name)
    q = np.random.default_rng(4).uniform(0.7 * robot.q_min, 0.7 * robot.q_max)
    T = robot.fk(q)
    args = ["best", "-r", name, "--position", " ".join(repr(float(v)) for v in T[:3, 3]),
            "--rotation", " ".join(repr(float(v)) for v in T[:3, :3].ravel()), "--objective", "margin",
            "--sphere", "0.5,0.5,1.5,0.05", "--plot", str(tmp_path / "best.png")]  # fmt: skip
    assert main(args) == 0
    out = capsys.readouterr().out
    rows = [ln.split() for ln in out.splitlines() if ln.split() and ln.split()[0].isdigit()]
    assert len(rows) == count and sum(r[-1] == "*" for r in rows) == 1
    qs = _q_star(out)
    assert np.abs(robot.fk(qs) - T).max() < 1e-5  # printed to 6 decimals
    assert robot.within_limits(qs, tol=1e-6)
    assert "best: branch" in out
    img = np.asarray(Image.open(tmp_path / "best.png").convert("L"), dtype=float)
    assert img.std() > 5


def test_best_errors_are_one_line_with_exit_2(capsys):
    assert main(["best", "-r", "iiwa14", "--position", "0.4 0.2 nan"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("qpik best: pose")
    assert main(["best", "-r", "iiwa14", "--position", "0.4 0.2 0.5", "--objective", "distance"]) == 2
    assert "q_ref" in capsys.readouterr().err
    assert main(["best", "-r", "iiwa14", "--position", "0.4 0.2 0.5", "--sphere", "1,2,3"]) == 2
    assert "--sphere" in capsys.readouterr().err


def test_unreachable_pose_is_a_status_not_an_error(capsys):
    assert main(["best", "-r", "iiwa14", "--position", "3 0 0"]) == 0
    assert "unreachable" in capsys.readouterr().out


def test_method_levelset_prints_its_table_and_refuses_obstacles(capsys):
    """``--method levelset`` (the default for the margin alone) says what its table holds; with an obstacle it is a
    one-line error."""
    robot = qpik.load_robot("iiwa14")
    T = robot.fk(np.random.default_rng(5).uniform(0.7 * robot.q_min, 0.7 * robot.q_max))
    pose = ["--position", " ".join(repr(float(v)) for v in T[:3, 3]),
            "--rotation", " ".join(repr(float(v)) for v in T[:3, :3].ravel())]  # fmt: skip
    assert main(["best", "-r", "iiwa14", *pose, "--method", "levelset"]) == 0
    out = capsys.readouterr().out
    assert "(level sets:" in out and "certified" in out
    assert np.abs(robot.fk(_q_star(out)) - T).max() < 1e-5
    assert main(["best", "-r", "iiwa14", *pose, "--method", "levelset", "--sphere", "0.5,0.5,1.5,0.05"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "method" in err[0]


def test_best_prints_the_margin_itself_and_says_what_is_minimised(capsys):
    """The margin objective's table and summary show the margin (positive, the smallest distance to a limit over the
    half range of the printed q, computed here), and the header says that qpik minimises −margin."""
    robot = qpik.load_robot("iiwa14")
    T = robot.fk(np.random.default_rng(6).uniform(0.7 * robot.q_min, 0.7 * robot.q_max))
    pose = ["--position", " ".join(repr(float(v)) for v in T[:3, 3]),
            "--rotation", " ".join(repr(float(v)) for v in T[:3, :3].ravel())]  # fmt: skip
    assert main(["best", "-r", "iiwa14", *pose]) == 0
    out = capsys.readouterr().out
    assert "maximise the margin" in out.splitlines()[0] and "qpik minimises −margin" in out.splitlines()[0]
    q = _q_star(out)
    half = 0.5 * (robot.q_max - robot.q_min)
    margin = np.minimum((q - robot.q_min) / half, (robot.q_max - q) / half).min()
    summary = next(ln for ln in out.splitlines() if ln.startswith("best: branch"))
    printed = float(summary.split("margin ")[1].split(",")[0])
    assert printed > 0 and printed == pytest.approx(margin, abs=1e-6)  # q printed to 6 decimals
    rows = [ln.split() for ln in out.splitlines() if ln.split() and ln.split()[0].isdigit() and ln.split()[1] == "yes"]
    assert all(float(r[3]) > 0 for r in rows) and max(float(r[3]) for r in rows) == pytest.approx(printed, rel=1e-7)


def test_best_on_an_arm_without_a_closed_form_runs_the_joint_space_nlp_and_says_it_is_not_certified(capsys, tmp_path):
    """zheng7 (no closed form): the joint-space NLP's answer reaches the pose inside the limits, and the margin printed
    is the margin of the printed q (computed here from the limits)."""
    robot, model = qpik.load_robot("zheng7"), ["-r", "zheng7"]
    q = np.random.default_rng(6).uniform(0.7 * robot.q_min, 0.7 * robot.q_max)
    T = robot.fk(q)
    pose = ["--position", " ".join(repr(float(v)) for v in T[:3, 3]),
            "--rotation", " ".join(repr(float(v)) for v in T[:3, :3].ravel())]  # fmt: skip
    assert main(["best", *model, *pose, "--plot", str(tmp_path / "ignored.png")]) == 0
    out = capsys.readouterr().out
    assert "no search over the redundancy parameter" in out and "not certified" in out and "ignored here: --plot" in out
    assert not (tmp_path / "ignored.png").exists()
    qs = _q_star(out)
    assert np.abs(robot.fk(qs) - T).max() < 1e-5  # printed to 6 decimals
    assert robot.within_limits(qs, tol=1e-6)
    half = 0.5 * (robot.q_max - robot.q_min)
    margin = float(np.min(np.minimum(qs - robot.q_min, robot.q_max - qs) / half))
    shown = float(next(ln for ln in out.splitlines() if ln.startswith("best: margin")).split()[2].rstrip(","))
    assert abs(shown - margin) < 1e-5


def test_best_on_an_arm_of_the_1d_search_samples_its_slots_and_says_it_is_not_certified(capsys):
    """Baxter's right arm (the 1-D search, q1 locked): the slots' table, a summary that says "not certified", and a
    printed q that reaches the pose inside the limits with the printed margin (computed here from the limits)."""
    robot = model_robot("erd_baxter")
    model = ["-r", str(robot.model.path), "--base", "right_arm_mount", "--tip", "right_wrist"]
    T = robot.fk(np.random.default_rng(6).uniform(0.7 * robot.q_min, 0.7 * robot.q_max))
    pose = ["--position", " ".join(repr(float(v)) for v in T[:3, 3]),
            "--rotation", " ".join(repr(float(v)) for v in T[:3, :3].ravel())]  # fmt: skip
    assert main(["best", *model, *pose]) == 0
    out = capsys.readouterr().out
    assert "q1* [rad]" in out and "not certified (sampled" in out and "no search over" not in out
    qs = _q_star(out)
    assert np.abs(robot.fk(qs) - T).max() < 1e-5  # printed to 6 decimals
    assert robot.within_limits(qs, tol=1e-6)
    half = 0.5 * (robot.q_max - robot.q_min)
    summary = next(ln for ln in out.splitlines() if ln.startswith("best: branch"))
    assert float(summary.split("margin ")[1].split(",")[0]) == pytest.approx(
        np.min(np.minimum(qs - robot.q_min, robot.q_max - qs) / half), abs=1e-5
    )
