"""``qpik ik`` and ``qpik plot``: the printed branches are checked by forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import model_robot

import qpik
from qpik.cli import main

TABLE4_ROT = "0.18 0.63 0.76 -0.16 0.78 -0.61 -0.97 -0.01 0.25"  # eqs. (33)-(35) as rows (n, t, b columns)


def _rows(text: str) -> list[list[str]]:
    """The branch rows of the table: lines whose first field is an integer branch id."""
    return [ln.split() for ln in text.splitlines() if ln.split() and ln.split()[0].isdigit()]


def _q(row: list[str]) -> np.ndarray:
    return np.array([float(v) for v in row[1:8]])


@pytest.mark.parametrize("name, count", [("nammoto7", 16), ("iiwa14", 8)])
def test_ik_prints_every_branch_with_fk_residual(capsys, name: str, count: int) -> None:
    robot = qpik.load_robot(name)
    q = np.random.default_rng(7).uniform(0.7 * robot.q_min, 0.7 * robot.q_max)
    code = main(["ik", "--robot", name, "--q", " ".join(repr(float(v)) for v in q)])
    assert code == 0
    out = capsys.readouterr().out
    rows = _rows(out)
    assert len(rows) == count
    valid = [r for r in rows if r[8] == "yes"]
    assert valid
    T = robot.fk(q)
    for r in valid:
        pos, rot = float(r[-2]), float(r[-1])
        assert pos < 1e-9 and rot < 1e-9
        # the printed angles (3 decimals) land within rounding of the pose: an independent FK check
        assert np.linalg.norm(robot.fk(_q(r))[:3, 3] - T[:3, 3]) < 5e-3
    # the parameter of q was used, so one printed branch is q itself (to the printed precision)
    assert min(np.abs(_q(r) - q).max() for r in valid) < 1e-3


@pytest.mark.parametrize("key, count, last", [
    ("erd_xarm7", 8, "branches with a feasible q7 range inside the limits: "),
    ("erd_baxter", 16, "branches with a feasible q1 range inside the limits: "),
])  # fmt: skip
def test_ik_on_model_files_prints_branches_on_the_pose_and_what_it_knows_of_the_sets(capsys, key, count, last):
    """A near member (the xArm7) and an arm of the 1-D search (Baxter's right arm, its sets sampled): their sets are
    not proved, and the line says so; q is among the printed branches, which reach the pose by the file's FK."""
    robot = model_robot(key)
    files = ["--base", "right_arm_mount", "--tip", "right_wrist"] if key == "erd_baxter" else []
    q = np.random.default_rng(7).uniform(0.7 * robot.q_min, 0.7 * robot.q_max)
    assert main(["ik", "-r", str(robot.model.path), *files, "--q", " ".join(repr(float(v)) for v in q)]) == 0
    out = capsys.readouterr().out
    rows = _rows(out)
    valid = [r for r in rows if r[8] == "yes"]
    assert len(rows) == count and valid
    T = robot.fk(q)
    assert all(np.linalg.norm(robot.fk(_q(r))[:3, 3] - T[:3, 3]) < 5e-3 for r in valid)
    assert min(np.abs(np.angle(np.exp(1j * (_q(r) - q)))).max() for r in valid) < 1e-3  # modulo 2π: limits past ±π
    tail = out.strip().splitlines()[-1]
    assert tail.startswith(last)
    assert ("not proved" in tail) == (key in ("erd_xarm7", "erd_baxter"))


def test_ik_position_rotation_with_projection(capsys) -> None:
    code = main(
        ["ik", "-r", "nammoto7", "--position=-0.18,0.41,0.41", "--rotation", TABLE4_ROT, "--param", "-0.8", "--project"]
    )
    assert code == 0
    rows = _rows(capsys.readouterr().out)
    assert len(rows) == 16
    # Table 4 of Nammoto & Kosuge 2012, row 1 (2 decimals)
    assert np.abs(_q(rows[0]) - [1.12, -0.77, 1.40, -0.61, -0.28, 0.60, 0.96]).max() < 0.05


def test_ik_pose_of_16_numbers(capsys) -> None:
    robot = qpik.load_robot("iiwa14")
    T = robot.fk(robot.q_home)
    assert main(["ik", "-r", "iiwa14", "--pose", " ".join(repr(float(v)) for v in T.ravel()), "-p", "0.2"]) == 0
    rows = _rows(capsys.readouterr().out)
    assert len(rows) == 8
    for r in rows:
        if r[8] == "yes":
            assert float(r[-2]) < 1e-9


def test_ik_rejects_a_rotation_that_is_not_orthonormal(capsys) -> None:
    code = main(["ik", "-r", "nammoto7", "--position=-0.18,0.41,0.41", "--rotation", TABLE4_ROT, "--param", "-0.8"])
    assert code == 2
    assert "project" in capsys.readouterr().err


def test_ik_needs_a_param_without_q(capsys) -> None:
    assert main(["ik", "-r", "iiwa14", "--position", "0.5 0 0.5"]) == 2
    err = capsys.readouterr().err
    assert err == "qpik ik: --param is required (unless --q is given: then the parameter of q is used)\n"


def test_plot_selfmotion_and_branches_write_pngs(tmp_path, capsys) -> None:
    a, b = tmp_path / "sm.png", tmp_path / "br.png"
    assert main(["plot", "selfmotion", "--problem", "nammoto2012_table4", "-o", str(a)]) == 0
    assert (
        main(["plot", "branches", "-r", "iiwa14", "--q", "0.3 0.5 -0.2 -1.2 0.4 0.9 0.1", "-p", "0.5", "-o", str(b)])
        == 0
    )
    assert a.stat().st_size > 10_000 and b.stat().st_size > 10_000


def test_plot_branches_with_q_and_no_param_draws_them_at_qs_own_parameter(tmp_path, capsys) -> None:
    """As ``qpik ik``: without ``--param`` the parameter of ``--q`` is used, and the line says which."""
    q = np.array([0.3, 0.5, -0.2, -1.2, 0.4, 0.9, 0.1])
    out = tmp_path / "br.png"
    assert main(["plot", "branches", "-r", "iiwa14", "--q", " ".join(map(str, q)), "-o", str(out)]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    psi = float(qpik.redundancy_parameter(qpik.load_robot("iiwa14"), q)[0])
    assert f"at {psi:.4f} rad" in line and out.stat().st_size > 10_000
    assert main(["plot", "branches", "-r", "iiwa14", "--position", "0.4 0.2 0.5", "-o", str(out)]) == 2
    assert "--param is required" in capsys.readouterr().err
