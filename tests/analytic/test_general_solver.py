"""qpik.analytic.general_solver: the arms of no other family (example-robot-data's TIAGo Pro arm; ssik's ABB YuMi and
Kassow KR810, written as MJCF files from ssik's kinematics and loaded as a user's file) get every configuration back
from ``qpik.ik`` at its own locked angle, each valid slot reaching the pose by MuJoCo's FK of the file, in the
documented order, with q7 or q1 locked; bad input gets qpik's errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, model_robot, mujoco_poses

import qpik
from qpik.analytic.api import closed_form_for
from qpik.analytic.intervals import wrap

arms = pytest.importorskip("qpik.bench.ssik_arms")
NAMES = ("ABB YuMi (IRB 14000) left", "erd_tiago_pro") + (
    ("ABB YuMi (IRB 14000) right", "Kassow KR810") if LARGE else ()
)
POSES = 2000 if LARGE else 30
FOUND = 1e-9
"""rad: the configuration is among the slots to this."""
REACHED = 1e-10
"""Every valid slot's pose by MuJoCo's FK equals the pose to this (m and rotation entries)."""


def _arm(name: str, tmp_path, **options) -> qpik.Robot:
    if name == "erd_tiago_pro":
        return model_robot(name)
    (arm,) = [a for a in arms.seven_r_arms() if a.name == name]
    if not options:
        return arms.load_arm(arm, tmp_path)
    path = tmp_path / "arm.xml"
    path.write_text(arms.mjcf(arm))
    return qpik.load_robot(path, tip=arms.TIP, name=name, **options)


def _check(robot: qpik.Robot, q: np.ndarray) -> None:
    """``qpik.ik`` at each configuration's own locked angle holds it (FOUND) in the slot that
    ``qpik.redundancy_parameter`` names, every valid slot reaches the pose (REACHED, MuJoCo), and the valid slots are
    the first ones, in increasing order of the eigenproblem's joint."""
    solver = closed_form_for(robot)
    T = mujoco_poses(robot, q)
    param, branch = qpik.redundancy_parameter(robot, q)
    for i in range(len(q)):
        sol = qpik.ik(robot, T[i], float(param[i]))
        err = np.abs(wrap(sol.q[sol.valid] - q[i])).max(axis=1)
        assert err.size and err.min() < FOUND, (i, err.min() if err.size else None)
        assert branch[i] >= 0 and np.abs(wrap(sol.q[branch[i]] - q[i])).max() < FOUND
        assert np.abs(mujoco_poses(robot, sol.q[sol.valid]) - T[i]).max() < REACHED
        k = int(sol.valid.sum())
        assert sol.valid[:k].all() and not sol.valid[k:].any()
        assert np.all(np.diff(wrap(sol.q[:k, solver.ranked_joint])) > 0)


@pytest.mark.parametrize("name", NAMES)
def test_a_general_arm_gets_every_configuration_back_with_q7_locked(name, tmp_path):
    robot = _arm(name, tmp_path)
    assert robot.closed_form == "locked_general"
    assert robot.notes.startswith("served with q7 locked by elimination of the 6-R chain left to one eigenproblem")
    assert "no closed form: " in robot.notes
    q = np.random.default_rng(8).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    _check(robot, q)


def test_asked_for_q1_the_arm_is_read_from_the_flange(tmp_path):
    """``redundancy="q1"``: the chain read from the flange, q1 locked (the parameter's name says it)."""
    robot = _arm(NAMES[0], tmp_path, redundancy="q1")
    assert robot.closed_form == "locked_general" and robot.notes.startswith("served with q1 locked")
    assert closed_form_for(robot).param_name == "q1"
    q = np.random.default_rng(9).uniform(robot.q_min, robot.q_max, (10, robot.dof))
    _check(robot, q)


def test_bad_input_gets_qpiks_errors_and_an_unreachable_pose_no_slot(tmp_path):
    robot = _arm(NAMES[0], tmp_path)
    T = robot.fk(robot.q_home)
    with pytest.raises(qpik.InputError, match="param"):
        qpik.ik(robot, T, float("nan"))
    with pytest.raises(qpik.InputError, match="pose"):
        qpik.ik(robot, np.eye(3), 0.0)
    far = T.copy()
    far[:3, 3] += 10.0  # 10 m away: beyond the arm's reach
    assert not qpik.ik(robot, far, 0.0).valid.any()


def test_the_sampled_sets_are_not_proved_and_hold_the_configurations_own_parameter(tmp_path):
    """One pose (the sets are sampled: a search per sample): not proved, and the configuration's own slot holds its
    locked angle."""
    robot = _arm(NAMES[0], tmp_path)
    q = np.random.default_rng(4).uniform(robot.q_min, robot.q_max, (1, robot.dof))
    param, branch = qpik.redundancy_parameter(robot, q)
    fi = qpik.feasible_intervals(robot, robot.fk(q[0]))
    assert not fi.proved and fi.contains(int(branch[0]), float(param[0]))
