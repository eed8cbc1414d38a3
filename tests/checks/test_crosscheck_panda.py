"""qpik.checks.crosscheck on the Panda's locked-q7 closed form: (a) closed form + 1-D search in q7, (b) the
full-joint NLP and (c) the QP controller agree on seeded random poses (same bounds as tests/checks/test_crosscheck.py
for the S-R-S and offset-shoulder arms)."""

from __future__ import annotations

import pytest
from conftest import random_q

import qpik
from qpik.checks.crosscheck import crosscheck
from qpik.geometry import Sphere


@pytest.mark.parametrize("objective, obstacles", [("smooth-margin", ()), ("distance", ()),
                                                  ("smooth-margin", [Sphere((0.4, 0.3, 0.5), 0.08)])])  # fmt: skip
def test_three_way_agreement_on_the_panda(objective, obstacles):
    robot = qpik.load_robot("panda")
    T = robot.fk(random_q(robot, 10, 41))
    checks = [crosscheck(robot, pose, objective, obstacles, q_ref=robot.q_home) for pose in T]
    applicable = [c for c in checks if c.applicable]
    assert len(applicable) >= 8
    for c in applicable:
        assert c.passed, c.report()
        assert c.q_gap <= 1e-6 and c.f_gap <= 1e-8 and c.kkt <= 1e-8 and c.speed <= 1e-6
