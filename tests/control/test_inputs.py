"""The inputs of the controller's compiled step: each written into its own block of one buffer, constants once,
the others as they are at every call; a controller's step reads the parameters as they are when it runs."""

from __future__ import annotations

import casadi as ca
import numpy as np

import qpik
from qpik.control import Controller, PostureTask, State
from qpik.control.inputs import Constant, Filler, Input, Owned
from qpik.core.layout import Layout


class _Owner:
    """A task-like owner of parameters: a gain (scalar) and a reference (3,)."""

    def __init__(self):
        self.gain, self.ref = 2.0, np.array([1.0, 2.0, 3.0])

    def param_values(self) -> dict[str, object]:
        return {"ref": self.ref, "gain": self.gain}


def test_filler_writes_each_input_into_its_block():
    owner, moving, fixed = _Owner(), np.array([5.0, 6.0]), np.array([7.0])
    layout = Layout(gain=(), ref=3)  # the owner's layout: gain first, whatever the order of param_values
    inputs = [Input(ca.SX.sym("a", 2), lambda state: moving), Constant(ca.SX.sym("b", 1), fixed),
              Owned(ca.SX.sym("c", 4), owner, layout)]  # fmt: skip
    fill = Filler(inputs)
    assert fill().tolist() == [5.0, 6.0, 7.0, 2.0, 1.0, 2.0, 3.0]
    moving[:] = (-5.0, -6.0)
    fixed[0] = -7.0  # a constant was copied when declared
    owner.gain, owner.ref = 3.0, np.array([4.0, 5.0, 6.0])  # read at the next call, the object replaced
    assert fill().tolist() == [-5.0, -6.0, 7.0, 3.0, 4.0, 5.0, 6.0]
    assert [inp.value(None).tolist() for inp in inputs] == [[-5.0, -6.0], [7.0], [3.0, 4.0, 5.0, 6.0]]


def test_the_step_reads_the_parameters_as_they_are_when_it_runs():
    """A posture task's weight and reference changed between steps are in the next step's QP: its cost is the
    tasks' costs on the numeric state of that q (plus the regularisation ε I)."""
    robot = qpik.load_robot("iiwa14")
    q = robot.q_home + 0.1
    ctrl = Controller.for_robot(robot, robot.fk(robot.q_home))
    ctrl.step(q)
    posture = next(t for t in ctrl.tasks if isinstance(t, PostureTask))
    assert posture.weight != 0.37
    posture.weight = 0.37
    posture.set_target(robot.q_home - 0.2)
    ctrl.step(q)
    state = State(robot, q, ctrl.dt)
    costs = [task.compute(state) for task in ctrl.tasks]
    P, c = sum(P for P, _ in costs), sum(c for _, c in costs)
    qp = ctrl.assembler.qp
    np.testing.assert_allclose(qp.P, P + 1e-12 * np.eye(robot.dof), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(qp.c, c, rtol=1e-12, atol=1e-12)
