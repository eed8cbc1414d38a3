"""qpik.problems.control: the ``reach`` and ``track`` runners, judged on MuJoCo's measurements.

The reach run is checked on its log (MuJoCo clearances, DH forward kinematics of
the final q); the NLP's posture reference by forward kinematics and against an
independent grid of arm angles; the track runner on the drift of velocity-only
feedback; both runners end to end through ``qpik run``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import qpik
import qpik.problems.control as report
from qpik.cli import main
from qpik.geometry import distances
from qpik.problems import find_problem, load
from qpik.scene.evaluator import Evaluator

# --dist loadgroup: one worker runs the whole module, so its module- and session-scoped fixtures are built once
pytestmark = pytest.mark.xdist_group("problems_control")

REACH = find_problem("iiwa_obstacle_reach")
TRACK = find_problem("zheng2019_clik")


def shortened(src: Path, folder: Path, duration: float, dt: float) -> Path:
    """A copy of a problem file with ``[solver] duration`` and ``dt`` replaced (a shorter run)."""
    lines = [ln for ln in src.read_text().splitlines() if ln.split("=")[0].strip() not in ("duration", "dt")]
    text = "\n".join(lines) + "\n"
    if "[solver]" not in text:
        text += "\n[solver]\n"
    text = text.replace("[solver]\n", f"[solver]\nduration = {duration}\ndt = {dt}\n", 1)
    out = folder / src.name
    out.write_text(text)
    return out


@pytest.fixture(scope="module")
def reach():
    problem = load(REACH)
    return problem, report.reach_runs(problem)


def test_reach_keeps_limits_and_clearance_and_reaches(reach):
    problem, runs = reach
    log, robot = runs.log, problem.robot
    # clearance measured by MuJoCo never below d_s (1e-4 m of discretisation allowed)
    assert log.clearance.min() >= runs.d_safe - 1e-4
    # joint position and velocity limits
    assert np.all(log.q >= robot.q_min - 1e-9) and np.all(log.q <= robot.q_max + 1e-9)
    assert np.all(np.abs(log.v) <= robot.v_max * (1 + 1e-6))
    # reached: the DH forward kinematics of the final q is the target pose
    T = robot.fk(log.q[-1])
    goal = problem.poses[0]
    assert np.linalg.norm(T[:3, 3] - goal[:3, 3]) < 1e-3
    assert np.abs(T[:3, :3] - goal[:3, :3]).max() < 1e-2


def test_obstacle_limit_is_needed(reach):
    """The same controller without the obstacle limit gets closer than d_s on the same scene."""
    _, runs = reach
    assert runs.free.clearance.min() < runs.d_safe
    assert runs.log.clearance.min() >= runs.d_safe - 1e-4


def test_nlp_reference(reach):
    """q_ref reaches the pose (FK), keeps the limits and d_s, no arm angle of its branch does better
    (dense samples of the closed form), and the run ends on that branch near that arm angle."""
    problem, runs = reach
    robot, ref, pose = problem.robot, runs.reference, problem.poses[0]
    np.testing.assert_allclose(robot.fk(ref.q), pose, atol=1e-9)
    assert robot.within_limits(ref.q)
    obstacles = problem.obstacles
    assert distances(robot.capsule_segments(ref.q), robot.capsule_radii, obstacles).d.min() >= runs.d_safe - 1e-9
    assert ref.branch == runs.start_branch == qpik.redundancy_parameter(robot, robot.q_home)[1]
    psi = np.linspace(-np.pi, np.pi, 2000)
    sols = qpik.ik(robot, np.broadcast_to(pose, (len(psi), 4, 4)), psi)
    col = int(np.flatnonzero(sols.branch == ref.branch)[0])
    q = sols.q[sols.within_limits[:, col], col]
    f, _, d, _ = Evaluator(robot, report.reach_objective(runs.d_influence), obstacles)(q)
    clear = d.min(axis=1) >= runs.d_safe
    assert ref.objective <= f[clear].min() + 1e-8
    # the final configuration of the run keeps the chosen branch, near the chosen arm angle
    psi_end, branch = qpik.redundancy_parameter(robot, runs.log.q[-1])
    assert branch == ref.branch
    assert abs(np.angle(np.exp(1j * (psi_end - ref.param)))) < problem.expected["psi_tolerance"]


def test_track_velocity_only_drifts_more_than_pd(tmp_path):
    problem = load(shortened(TRACK, tmp_path, duration=4.0, dt=0.002))
    qp, pd, vel = report.track_runs(problem)
    after = pd.t >= 1.0
    e_qp, e_pd, e_vel = (log.errors[0][after] for log in (qp, pd, vel))
    assert e_vel.max() > 5 * e_pd.max()
    assert e_vel[-1] > e_vel[0]  # drift: the velocity-only error grows
    assert e_qp.max() < 1e-3 and e_pd.max() < 1e-3


def _non_blank(path: Path) -> bool:
    return np.asarray(Image.open(path).convert("L"), dtype=float).std() > 5.0


@pytest.mark.parametrize("src, duration", [(TRACK, 2.0), (REACH, 2.5)])
def test_runners_through_the_cli(tmp_path, src, duration):
    file = shortened(src, tmp_path, duration=duration, dt=0.002)
    out = tmp_path / "out"
    assert main(["run", str(file), "-o", str(out)]) == 0
    text = (out / "report.md").read_text()
    assert "Overall: " in text and "| QP" in text
    pngs = sorted(out.glob("*.png"))
    assert len(pngs) >= 2 and all(_non_blank(p) for p in pngs)
