"""qpik.analytic.api: the public closed-form calls reject bad input clearly, on both arms."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEEDS, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.errors import InputError, NoClosedFormError, QpikError, RotationError

CLOSED_FORM = ("nammoto7", "iiwa14")


@pytest.fixture(params=CLOSED_FORM)
def robot(request):
    return qpik.load_robot(request.param)


def test_nan_and_shapes_name_the_argument(robot) -> None:
    T = robot.fk(robot.q_home)
    bad = T.copy()
    bad[0, 3] = np.nan
    with pytest.raises(InputError, match=r"^pose"):
        qpik.ik(robot, bad, 0.0)
    with pytest.raises(InputError, match=r"^pose"):
        qpik.ik(robot, T[:3], 0.0)
    with pytest.raises(InputError, match=r"^param"):
        qpik.ik(robot, T, np.nan)
    with pytest.raises(InputError, match=r"^param"):
        qpik.ik(robot, T, [0.0, 1.0])
    with pytest.raises(InputError, match=r"^param"):
        qpik.ik(robot, np.stack([T, T]), np.zeros(3))
    with pytest.raises(InputError, match=r"^q"):
        qpik.redundancy_parameter(robot, np.zeros(6))
    with pytest.raises(InputError, match=r"^pose"):
        qpik.feasible_intervals(robot, np.stack([T, T]))


def test_non_orthonormal_rotation_needs_project(robot) -> None:
    T = robot.fk(robot.q_home)
    skew = T.copy()
    skew[:3, :3] *= 1.01
    with pytest.raises(RotationError):
        qpik.ik(robot, skew, 0.0)
    with pytest.raises(RotationError):
        qpik.feasible_intervals(robot, skew)
    sols = qpik.ik(robot, skew, 0.3, project=True)
    assert sols.valid.any()
    # projecting a uniformly scaled rotation gives the rotation back: every valid branch reaches T by FK
    F = robot.fk(sols.q[sols.valid])
    assert np.abs(F - T).max() < 1e-9


@pytest.mark.parametrize("name", ["zheng7", "panda"])
def test_arms_without_closed_form_say_so(name: str) -> None:
    robot = qpik.load_robot(name)
    with pytest.raises(NoClosedFormError, match=r"qpik\.solve_ik"):
        qpik.ik(robot, robot.fk(robot.q_home), 0.0)


def test_batched_param_broadcasts_a_float(robot) -> None:
    T = robot.fk(np.stack([robot.q_home, robot.q_home * 0.5]))
    both = qpik.ik(robot, T, 0.2)
    assert both.q.shape == (2, len(both.branch), 7)
    np.testing.assert_array_equal(both.param, [0.2, 0.2])
    one = qpik.ik(robot, T[1], 0.2)
    np.testing.assert_allclose(both.q[1], one.q, atol=1e-12)


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS, name=st.sampled_from(CLOSED_FORM))
def test_redundancy_parameter_of_one_configuration_inverts_ik(seed: int, name: str) -> None:
    """One configuration goes through the compiled parameter: ik(fk(q), param(q)) holds q in branch(q), and it
    agrees with the numpy path of a batch."""
    robot = qpik.load_robot(name)
    Q = random_q(robot, 50, seed)
    batch = qpik.redundancy_parameter(robot, Q)
    for i, q in enumerate(Q):
        param, branch = qpik.redundancy_parameter(robot, q)
        assert isinstance(param, float) and isinstance(branch, int)
        assert branch == batch[1][i] and param == pytest.approx(batch[0][i], abs=1e-12)
        sols = qpik.ik(robot, robot.fk(q), param)
        k = list(sols.branch).index(branch)
        assert np.abs(robot.fk(sols.q[k]) - robot.fk(q)).max() < 1e-9
        assert np.abs(np.remainder(sols.q[k] - q + np.pi, 2 * np.pi) - np.pi).max() < 1e-8  # the same joints


def test_every_error_type_is_exported() -> None:
    import inspect

    import qpik.errors

    types = {name for name, obj in inspect.getmembers(qpik.errors, inspect.isclass) if issubclass(obj, QpikError)}
    assert types >= {"SolverError", "ProblemFileError", "RenderUnavailable", "InfeasibleError"}
    assert types <= set(qpik.__all__)
    assert all(getattr(qpik, name) is getattr(qpik.errors, name) for name in types)


@pytest.mark.parametrize("solver, arm", [("OffsetShoulderSolver", "iiwa14"), ("SRSSolver", "nammoto7")])
def test_a_chain_of_the_wrong_kind_raises_no_closed_form_error(solver: str, arm: str) -> None:
    """The same situation (this chain is not this kind of arm) gives the same error type from both solvers."""
    from qpik.analytic.offset_shoulder import OffsetShoulderSolver
    from qpik.analytic.srs import SRSSolver

    cls = {"OffsetShoulderSolver": OffsetShoulderSolver, "SRSSolver": SRSSolver}[solver]
    with pytest.raises(NoClosedFormError):
        cls(qpik.load_robot(arm))
