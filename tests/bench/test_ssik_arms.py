"""qpik.bench.ssik_arms: the 7-R arms that ssik ships, written as MJCF files from ssik's own kinematics and loaded as a
user's file: MuJoCo's FK of the file is ssik's ``fk``; an arm of a family gets every configuration back from
``qpik.ik`` at its own parameter, each valid branch reaching the pose by MuJoCo's FK; one without says why. Three arms
by default (an S-R-S, a locked-q7 and the YuMi, of the general 6-R family), all of them in the large run."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, mujoco_poses

import qpik
from qpik.analytic.intervals import wrap

arms = pytest.importorskip("qpik.bench.ssik_arms")
DEFAULT = ("KUKA iiwa LBR 7", "Franka Research 3", "ABB YuMi (IRB 14000) left")
ARMS = [arm for arm in arms.seven_r_arms() if LARGE or arm.name in DEFAULT]
POSES = 40 if LARGE else 12


@pytest.mark.skipif(not ARMS, reason="ssik (the test extra) is not installed")
@pytest.mark.parametrize("ssik_arm", ARMS, ids=lambda arm: arm.name)
def test_ssiks_arms_load_with_its_fk_and_their_closed_forms_find_every_configuration(ssik_arm, tmp_path):
    robot = arms.load_arm(ssik_arm, tmp_path)
    q = np.random.default_rng(5).uniform(robot.q_min, robot.q_max, (POSES, robot.dof))
    T = mujoco_poses(robot, q)
    ssik = np.array([ssik_arm.arm.fk(x) for x in q])
    np.testing.assert_allclose(T, ssik, atol=1e-9)  # the file is ssik's arm (MuJoCo's FK)
    if robot.closed_form is None:
        assert robot.notes.startswith("no closed form: ")
        with pytest.raises(qpik.NoClosedFormError):
            qpik.ik(robot, T[0], 0.0)
        return
    param = np.asarray(qpik.redundancy_parameter(robot, q)[0], float)
    sigma = np.linalg.svd(robot.jacobian(q), compute_uv=False)[:, -1]
    for i in range(POSES):
        sol = qpik.ik(robot, T[i], float(param[i]))
        err = np.abs(wrap(sol.q[sol.valid] - q[i])).max(axis=1)
        assert err.size and (err.min() < 1e-9 or err.min() * sigma[i] < 1e-14), (i, err.min(), sigma[i])
        reached = mujoco_poses(robot, sol.q[sol.valid])
        assert np.abs(reached - T[i]).max() < 1e-9
