"""The ``ik`` runner: reports checked against FK and the paper's tables, never against the runner itself."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import qpik
from qpik.problems import load
from qpik.problems.ik import branch_table, fk_residual, run_ik

PROBLEMS = Path(__file__).resolve().parents[2] / "problems"


def _read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    return lines[0].split(","), np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])


def _wrap(x: np.ndarray) -> np.ndarray:
    return (x + np.pi) % (2 * np.pi) - np.pi


def _projected_pose(file: Path) -> np.ndarray:
    """The target pose of a rotation+position file, projected onto SO(3) here (SVD), not by qpik."""
    data = tomllib.loads(file.read_text())["target"]
    U, _, Vt = np.linalg.svd(np.array(data["rotation"], float))
    T = np.eye(4)
    T[:3, :3] = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    T[:3, 3] = data["position"]
    return T


@pytest.fixture(scope="module")
def table4(tmp_path_factory) -> tuple[str, Path]:
    out = tmp_path_factory.mktemp("table4")
    return run_ik(load(PROBLEMS / "nammoto2012_table4.toml"), out), out


def test_table4_report_passes_and_max_difference_is_recomputed(table4) -> None:
    report, out = table4
    assert "**PASS**" in report and "FAIL" not in report
    reported = float(re.search(r"Max difference: ([0-9.]+) rad", report).group(1))
    head, rows = _read_csv(out / "nammoto2012_table4_solutions.csv")
    qcols = [head.index(f"q{j}") for j in range(1, 8)]
    q = rows[:, qcols][np.argsort(rows[:, head.index("branch")])]
    # each reported solution reaches the (independently projected) pose
    robot = qpik.load_robot("nammoto7")
    T = _projected_pose(PROBLEMS / "nammoto2012_table4.toml")
    np.testing.assert_allclose(robot.fk(q), np.broadcast_to(T, (16, 4, 4)), atol=1e-9)
    # the printed max difference is the wrapped max against Table 4 of the file
    paper = np.array(tomllib.loads((PROBLEMS / "nammoto2012_table4.toml").read_text())["expected"]["q"])
    assert np.abs(_wrap(q - paper)).max() == pytest.approx(reported, abs=1e-4)
    assert reported <= 0.05
    assert (out / "nammoto2012_table4_branches.png").is_file()
    assert (out / "nammoto2012_table4_selfmotion.png").is_file()


def _run_branch1(file: Path, out: Path, figure: str) -> tuple[str, list[str], np.ndarray]:
    """Run the ik runner on ``file``; check PASS and the figure; return (report, CSV header, branch-1 rows)."""
    report = run_ik(load(file), out)
    assert "**PASS**" in report
    assert (out / f"{file.stem}_{figure}.png").is_file()
    head, rows = _read_csv(out / f"{file.stem}_solutions.csv")
    return report, head, rows[rows[:, head.index("branch")] == 1]


def test_joint_limit_sweep_reproduces_the_papers_observation(tmp_path) -> None:
    """Nammoto & Kosuge 2012 Figs. 15/16: θ6 grows as p_z falls at δ = 0, stays bounded at δ = 0.70."""
    file = PROBLEMS / "nammoto2012_joint_limits.toml"
    _, head, b1 = _run_branch1(file, tmp_path, "sweep")
    assert np.all(b1[:, head.index("valid")] == 1)
    robot = qpik.load_robot("nammoto7")
    R = np.array(tomllib.loads(file.read_text())["target"]["rotation"], float)
    q = b1[:, [head.index(f"q{j}") for j in range(1, 8)]]
    F = robot.fk(q)
    np.testing.assert_allclose(F[:, :3, :3], np.broadcast_to(R, (len(q), 3, 3)), atol=1e-9)
    np.testing.assert_allclose(F[:, :2, 3], np.broadcast_to([-0.18, 0.41], (len(q), 2)), atol=1e-9)
    pz = F[:, 2, 3]
    delta = b1[:, head.index("delta")]
    for d in (0.0, 0.70):
        sel = np.isclose(delta, d)
        order = np.argsort(pz[sel])
        np.testing.assert_allclose(pz[sel][order], np.linspace(0.3, 0.9, 31), atol=1e-9)
        th6 = np.abs(q[sel][order, 5])
        if d == 0.0:
            assert np.all(np.diff(th6) < 0)  # |θ6| grows as p_z falls
            big0 = th6[0]
        else:
            assert th6.max() < big0 - 0.5  # saturates well below the δ = 0 value


def test_obstacle_sweep_keeps_the_hand_and_moves_the_elbow(tmp_path) -> None:
    file = PROBLEMS / "nammoto2012_obstacle.toml"
    report, head, b1 = _run_branch1(file, tmp_path, "overlay")
    assert len(b1) == 7
    valid = b1[:, head.index("valid")] == 1
    assert valid[1:-1].all()  # |δ| <= 0.55: branch 1 reaches the pose
    robot = qpik.load_robot("nammoto7")
    T = _projected_pose(file)
    q = b1[:, [head.index(f"q{j}") for j in range(1, 8)]]
    F = robot.fk(q)
    np.testing.assert_allclose(F[valid], np.broadcast_to(T, (int(valid.sum()), 4, 4)), atol=1e-9)
    # a row flagged invalid really misses the pose (checked by FK, not by the flag)
    miss = np.linalg.norm(F[~valid, :3, 3] - T[:3, 3], axis=1)
    assert np.all(miss > 1e-6)
    if (~valid).any():
        assert "does not reach the pose" in report
    elbow = robot.frames(q[valid])[:, 3, :3, 3]
    assert np.ptp(elbow, axis=0).max() > 0.05  # the self-motion moves the elbow


def test_q_target_problem_recovers_the_configuration(tmp_path) -> None:
    report = run_ik(load(PROBLEMS / "shimizu2008_iiwa.toml"), tmp_path)
    assert "**PASS**" in report
    head, rows = _read_csv(tmp_path / "shimizu2008_iiwa_solutions.csv")
    assert len(rows) == 73 * 8
    robot = qpik.load_robot("iiwa14")
    q_target = np.array(tomllib.loads((PROBLEMS / "shimizu2008_iiwa.toml").read_text())["target"]["q"])
    ok = rows[:, head.index("valid")] == 1
    q = rows[ok][:, [head.index(f"q{j}") for j in range(1, 8)]]
    np.testing.assert_allclose(robot.fk(q), np.broadcast_to(robot.fk(q_target), (len(q), 4, 4)), atol=1e-9)


def test_branch_table_residuals_match_fk() -> None:
    robot = qpik.load_robot("iiwa14")
    q = np.array([0.3, -0.6, 0.4, 1.1, -0.2, 0.7, 0.1])
    T = robot.fk(q)
    psi, _ = qpik.redundancy_parameter(robot, q)
    sols = qpik.ik(robot, T, psi)
    lines = branch_table(robot, sols, T).splitlines()
    assert len(lines) == 1 + 8
    for line, ok in zip(lines[1:], sols.valid):
        if ok:
            pos, rot = (float(v) for v in line.split()[-2:])
            assert pos < 1e-9 and rot < 1e-9


def test_fk_residual_measures_a_known_offset() -> None:
    """A pose moved by 1 cm and turned by 0.1 rad about z gives those residuals."""
    robot = qpik.load_robot("nammoto7")
    q = robot.q_home
    T = robot.fk(q).copy()
    c, s = np.cos(0.1), np.sin(0.1)
    T[:3, :3] = T[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    T[:3, 3] += [0.01, 0.0, 0.0]
    pos, rot = fk_residual(robot, q, T)
    assert float(pos) == pytest.approx(0.01, abs=1e-12)
    assert float(rot) == pytest.approx(0.1, abs=1e-12)
