"""qpik.plan_many: the same plans as a loop of plan_self_motion, in this process and in local processes; failures per
path (the cluster case: tests/planning/test_planning_cluster.py)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import qpik
from qpik.planning.batch import JobFailure
from qpik.robots.bundle import RobotBundle
from qpik.robots.packaged import packaged_model

ROBOT = qpik.load_robot("iiwa14")
RNG = np.random.default_rng(1)
PATHS = [ROBOT.fk(ROBOT.q_home + RNG.uniform(-0.3, 0.3, 7) + np.linspace(0, 0.15, 5)[:, None]) for _ in range(12)]
OPTIONS = qpik.PlanOptions(resolution=72, mujoco=False)


@pytest.fixture(scope="module")
def loop():
    return [qpik.plan_self_motion(ROBOT, path, options=OPTIONS) for path in PATHS]


@pytest.mark.parametrize("workers", [1, 2])
def test_plan_many_equals_a_loop(loop, workers):
    plans = qpik.plan_many(ROBOT, PATHS, workers=workers, progress=False, options=OPTIONS)
    assert len(plans) == len(PATHS)
    for plan, alone in zip(plans, loop, strict=True):
        assert plan.robot is ROBOT and plan.setup.robot is ROBOT
        assert plan.status == alone.status and plan.cost == pytest.approx(alone.cost, 1e-12)
        assert np.abs(plan.q - alone.q).max() <= 1e-12 and np.abs(ROBOT.fk(plan.q) - plan.poses).max() < 1e-9


def test_failures_are_per_path():
    bad = PATHS[1].copy()
    bad[2, 0, 0] = 5.0  # not a rotation: that path's job raises
    paths = [PATHS[0], bad, PATHS[2]]
    kept = qpik.plan_many(ROBOT, paths, workers=1, errors="keep", progress=False, options=OPTIONS)
    assert isinstance(kept[1], JobFailure) and kept[1].index == 1 and "RotationError" in kept[1].error
    assert kept[0].ok and kept[2].ok
    with pytest.raises(qpik.PlanningError, match=r"1 path\(s\) could not be planned: path 1: RotationError") as info:
        qpik.plan_many(ROBOT, paths, workers=1, progress=False, options=OPTIONS)
    assert [f.index for f in info.value.failures] == [1]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"errors": "ignore"}, "errors: expected 'raise' or 'keep'"),
        ({"workers": 0}, "workers: expected an integer >= 1"),
        ({"options": {"resolution": 72}}, "options: expected PlanOptions"),
        ({"paths": PATHS[0]}, "paths: expected a sequence of paths, got one path"),
        ({"paths": [3]}, r"paths\[0\]: expected \(N, 4, 4\) waypoints or a timed path"),
        ({"robot": "iiwa14"}, "robot: expected a qpik.Robot"),
    ],
)
def test_bad_arguments_are_named(kwargs, message):
    args = {"robot": ROBOT, "paths": PATHS[:1], "progress": False, **kwargs}
    with pytest.raises(qpik.InputError, match=message):
        qpik.plan_many(args.pop("robot"), args.pop("paths"), **args)


def test_a_loaded_robot_travels_with_its_model_files(tmp_path):
    robot = qpik.load_robot(packaged_model("pybullet/iiwa"))
    bundle = RobotBundle.of(robot)
    assert bundle.model == "model.urdf" and any(name.startswith("meshes/") for name, _ in bundle.files)
    there = pickle.loads(pickle.dumps(bundle)).robot()  # as on a worker: a temporary folder of its own
    assert there is not robot and there.model.path.parent != robot.model.path.parent
    q = robot.q_home + 0.2
    assert np.array_equal(there.fk(q), robot.fk(q))
    a, b = robot.mj_model(), there.mj_model()
    assert a.nmesh == b.nmesh > 0 and np.array_equal(a.mesh_vert, b.mesh_vert)
    assert pickle.loads(pickle.dumps(bundle)).robot() is there  # kept per process: built once per worker
