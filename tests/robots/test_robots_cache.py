"""What qpik builds for a robot lives as long as the robot: freed with it, built once, never shared by copies."""

from __future__ import annotations

import dataclasses
import gc
import pickle
import threading
import weakref

import numpy as np

import qpik
from qpik.robots.cache import RobotCache


def test_a_value_is_built_once_when_threads_ask_at_once():
    cache, calls, start = RobotCache(), [], threading.Barrier(8)

    def build(x):
        calls.append(x)
        return object()

    def ask(out):
        start.wait()
        out.append(cache.get("key", build, 1))

    out: list = []
    threads = [threading.Thread(target=ask, args=(out,)) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert calls == [1] and len({id(x) for x in out}) == 1 and len(cache) == 1


def test_what_was_built_for_a_robot_is_freed_with_it():
    """The closed-form solver, the self-motion map, the controller's kinematics and the numerical IK hold
    the robot they serve: a cache outside the robot would keep both alive."""
    robot = dataclasses.replace(qpik.load_robot("iiwa14"))
    pose = robot.fk(robot.q_home)
    qpik.ik(robot, pose, 0.3)
    qpik.solve_ik(robot, pose, robot.q_home)
    qpik.Controller.for_robot(robot, target=pose).step(robot.q_home)
    assert len(robot.cache) >= 3
    gone = weakref.ref(robot)
    del robot
    gc.collect()
    assert gone() is None


def test_copies_start_with_an_empty_cache():
    robot = qpik.load_robot("panda")
    qpik.solve_ik(robot, robot.fk(robot.q_home), robot.q_home)
    assert len(robot.cache) >= 1
    for copy in (dataclasses.replace(robot), pickle.loads(pickle.dumps(robot))):
        assert len(copy.cache) == 0
        assert np.allclose(copy.fk(copy.q_home), robot.fk(robot.q_home), atol=1e-15)
        assert np.allclose(
            copy.fk(qpik.solve_ik(copy, robot.fk(robot.q_home), copy.q_home)), robot.fk(robot.q_home), atol=1e-9
        )
        assert len(copy.cache) == 1
