"""qpik.analytic.api: the public closed-form calls reject bad input clearly, on both arms."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from conftest import SEEDS, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.analytic.api import closed_form_for
from qpik.core.errors import InputError, NoClosedFormError, QpikError, RotationError
from qpik.native.fastcall import extension

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
    for margin in (np.nan, np.inf, -0.1, "a", None, True):
        with pytest.raises(InputError, match=r"^margin"):
            qpik.feasible_intervals(robot, T, margin=margin)


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


@pytest.mark.parametrize("name", ["zheng7"])
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
        if np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1] > 1e-4:  # the joints are unique off singularities
            assert np.abs(np.remainder(sols.q[k] - q + np.pi, 2 * np.pi) - np.pi).max() < 1e-8  # the same joints


def test_every_error_type_is_exported() -> None:
    import inspect

    import qpik.core.errors

    types = {name for name, obj in inspect.getmembers(qpik.core.errors, inspect.isclass) if issubclass(obj, QpikError)}
    assert types >= {"SolverError", "ProblemFileError", "RenderUnavailable", "InfeasibleError"}
    assert types <= set(qpik.__all__)
    assert all(getattr(qpik, name) is getattr(qpik.core.errors, name) for name in types)


@pytest.mark.parametrize("solver, arm", [("OffsetShoulderSolver", "iiwa14"), ("SRSSolver", "nammoto7")])
def test_a_chain_of_the_wrong_kind_raises_no_closed_form_error(solver: str, arm: str) -> None:
    """The same situation (this chain is not this kind of arm) gives the same error type from both solvers."""
    from qpik.analytic.offset_shoulder import OffsetShoulderSolver
    from qpik.analytic.srs import SRSSolver

    cls = {"OffsetShoulderSolver": OffsetShoulderSolver, "SRSSolver": SRSSolver}[solver]
    with pytest.raises(NoClosedFormError):
        cls(qpik.load_robot(arm))


def test_unwrapped_q_gives_the_same_parameter_and_branch(robot) -> None:
    """redundancy_parameter wraps q first: q + 2πk on any joints is the same configuration (θ2 − 2π used to give
    another branch number)."""
    rng = np.random.default_rng(4)
    Q = rng.uniform(robot.q_min, robot.q_max, size=(500, robot.dof))
    shifted = Q + 2.0 * np.pi * rng.integers(-3, 4, size=Q.shape)
    p0, b0 = qpik.redundancy_parameter(robot, Q)
    p1, b1 = qpik.redundancy_parameter(robot, shifted)
    np.testing.assert_array_equal(b1, b0)
    np.testing.assert_allclose(np.angle(np.exp(1j * (p1 - p0))), 0.0, atol=1e-9)
    q = Q[0].copy()
    q[1] -= 2.0 * np.pi
    assert qpik.redundancy_parameter(robot, q)[1] == b0[0]


def test_robot_names_and_other_objects_are_not_robots(robot) -> None:
    T = robot.fk(robot.q_home)
    for bad in (robot.name, None, 7):
        with pytest.raises(InputError, match=r"^robot: expected a qpik\.Robot"):
            qpik.ik(bad, T, 0.0)
        with pytest.raises(InputError, match=r"^robot"):
            qpik.feasible_intervals(bad, T)
        with pytest.raises(InputError, match=r"^robot"):
            qpik.redundancy_parameter(bad, robot.q_home)
    with pytest.raises(InputError, match=r"load_robot\('iiwa14'\)"):
        qpik.ik("iiwa14", T, 0.0)


def test_empty_batches(robot) -> None:
    sols = qpik.ik(robot, np.zeros((0, 4, 4)), 0.3)
    B = len(sols.branch)
    assert sols.q.shape == (0, B, robot.dof) and sols.valid.shape == sols.singular.shape == (0, B)
    param, branch = qpik.redundancy_parameter(robot, np.zeros((0, robot.dof)))
    assert param.shape == branch.shape == (0,)


def test_huge_positions_are_refused_not_overflowed(robot) -> None:
    """A position of 1e155 m made every nammoto7 branch valid with FK at (0, 0, 0.6) and 11.9 rad of feasible δ:
    squares overflowed. Positions beyond 1e6 m are refused; far but finite ones are unreachable."""
    T = robot.fk(robot.q_home)
    for mag in (1e155, 1e300, 2e6):
        far = T.copy()
        far[0, 3] = mag
        with pytest.raises(InputError, match=r"^pose: position"):
            qpik.ik(robot, far, 0.0)
        with pytest.raises(InputError, match=r"^pose: position"):
            qpik.feasible_intervals(robot, far)
    far = T.copy()
    far[:3, 3] = (1e6, -1e6, 1e6)
    sols = qpik.ik(robot, far, 0.3)
    assert not sols.valid.any() and np.isfinite(sols.q).all()
    fi = qpik.feasible_intervals(robot, far)
    assert sum(fi.measure(int(b)) for b in fi.branch) == 0.0


def test_complex_and_text_inputs_are_refused(robot) -> None:
    T = robot.fk(robot.q_home)
    with pytest.raises(InputError, match=r"^q: .*complex"):
        robot.fk(robot.q_home + 1e-3j)
    with pytest.raises(InputError, match=r"^q"):
        qpik.redundancy_parameter(robot, robot.q_home.astype(complex))
    with pytest.raises(InputError, match=r"^param"):
        qpik.ik(robot, T, 0.3 + 0.1j)
    with pytest.raises(InputError, match=r"^pose"):
        qpik.ik(robot, T.astype(complex), 0.3)
    with pytest.raises(InputError, match=r"^param"):
        qpik.ik(robot, T, "0.3")


def test_projection_is_only_for_rounded_rotations(robot) -> None:
    """project=True used to accept −R (8 or 16 "valid" branches of another orientation), the zero matrix and a rank-1
    matrix; and project="no" projected."""
    T = robot.fk(robot.q_home)
    for R in (-T[:3, :3], np.zeros((3, 3)), np.outer(T[:3, 0], T[:3, 0])):
        bad = T.copy()
        bad[:3, :3] = R
        with pytest.raises(RotationError, match="cannot be projected"):
            qpik.ik(robot, bad, 0.0, project=True)
        with pytest.raises(RotationError, match="cannot be projected"):
            qpik.feasible_intervals(robot, bad, project=True)
    skew = T.copy()
    skew[:3, :3] *= 1.01
    with pytest.raises(InputError, match=r"^project"):
        qpik.ik(robot, skew, 0.0, project="no")


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7"])
def test_threads_sharing_an_arm_get_the_answers_of_one_thread(name: str) -> None:
    """Four threads calling ``feasible_intervals``, ``ik`` (one pose and a batch, the compiled and the general
    path) and ``redundancy_parameter`` on one robot at once get exactly what one thread gets (the solver's
    compiled calls share buffers: the public functions hold its lock around them)."""
    robot = qpik.load_robot(name)
    rng = np.random.default_rng(3)
    Q = rng.uniform(robot.q_min, robot.q_max, (48, robot.dof))
    T = robot.fk(Q)

    def answers(k: int) -> list:
        out = []
        for i in range(k, len(T), 4):
            out.append(qpik.feasible_intervals(robot, T[i]).intervals)
            out.append(qpik.ik(robot, T[i], 0.3).q.tolist())
            out.append(qpik.ik(robot, T[i], 0.3, project=True).q.tolist())  # projection: the general path
            out.append(qpik.redundancy_parameter(robot, Q[i]))
        out.append(qpik.ik(robot, T[k::4], 0.3).q.tolist())
        return out

    serial = [answers(k) for k in range(4)]
    with ThreadPoolExecutor(4) as pool:
        for _ in range(5):
            assert list(pool.map(answers, range(4))) == serial


def test_branch_ids_are_read_only(robot) -> None:
    """The branch ids of a result are shared by every result of the arm, so they cannot be written to."""
    T = robot.fk(np.zeros(robot.dof) + 0.2)
    for sol in (qpik.ik(robot, T, 0.3), qpik.ik(robot, T[None], 0.3)):
        with pytest.raises(ValueError, match="read-only"):
            sol.branch[0] = -1
    assert qpik.ik(robot, T, 0.3).branch.tolist() == list(qpik.feasible_intervals(robot, T).branch)


# Every real number a user may pass as δ/ψ, made from a float v: numpy floating and integer scalars, 0-d arrays,
# Python ints (the integer kinds take round(v), an unsigned one |round(v)|).
SCALAR_KINDS = {
    "float64": np.float64,
    "float32": np.float32,
    "float16": np.float16,
    "longdouble": np.longdouble,
    "0-d float64": np.array,
    "0-d float32": lambda v: np.array(v, dtype=np.float32),
    "int": lambda v: round(v),
    "int64": lambda v: np.int64(round(v)),
    "int32": lambda v: np.int32(round(v)),
    "uint8": lambda v: np.uint8(abs(round(v))),
    "0-d int64": lambda v: np.array(round(v)),
}


@settings(max_examples=30, deadline=None)
@given(
    seed=SEEDS,
    name=st.sampled_from(CLOSED_FORM),
    kind=st.sampled_from(sorted(SCALAR_KINDS)),
    v=st.floats(-3.1, 3.1),
)
def test_every_scalar_type_gives_the_float_answer_through_one_path(seed: int, name: str, kind: str, v: float) -> None:
    """A numpy scalar, a 0-d array or an int as δ/ψ gives exactly the answer of the same value as a float, through
    the same compiled call (the extension's ``fresh``: counted, and the general path made to fail); with the
    extension left out, the general path gives the same answer."""
    robot = qpik.load_robot(name)
    q = random_q(robot, 1, seed)[0]
    T = robot.fk(q)
    x = SCALAR_KINDS[kind](v)
    want = qpik.ik(robot, T, float(x))
    assert np.abs(robot.fk(want.q[want.valid]) - T).max(initial=0.0) < 1e-9  # the reference reaches the pose
    solver = closed_form_for(robot)
    fresh = solver.fresh_one
    calls = []

    def counted(*args):
        out = fresh(*args)
        calls.append(out is not None)
        return out

    def general(*args):
        raise AssertionError("the general path was taken")

    answers = []
    with pytest.MonkeyPatch.context() as mp:
        if fresh is not None:
            mp.setitem(solver.__dict__, "fresh_one", counted)
            mp.setattr(solver, "solve_one", general)
        answers.append(qpik.ik(robot, T, x))
    assert calls == ([True] if fresh is not None else [])
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(solver.__dict__, "fresh_one", None)  # as without the extension: the general path
        answers.append(qpik.ik(robot, T, x))
    for got in answers:
        for field in ("q", "valid", "within_limits", "singular", "branch"):
            np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
        assert type(got.param) is float and got.param == want.param == float(x)


@pytest.mark.skipif(extension() is None, reason="no compiled extension (QPIK_NATIVE=0 or no compiler)")
def test_what_the_compiled_call_does_not_take_gets_the_general_error(robot) -> None:
    """Bools, complex numbers, text, None, arrays of one entry, non-finite and out-of-range numbers fall through to
    the general path and its InputError naming ``param``."""
    T = robot.fk(robot.q_home)
    bad = (np.nan, np.float32("inf"), np.array(np.inf), 1 + 2j, np.complex64(1), "0.1", None, np.ones(1), 10**400)
    for x in (*bad, True, np.True_, np.array(False)):
        with pytest.raises(InputError, match="param"):
            qpik.ik(robot, T, x)
    with pytest.raises(InputError, match="param"):
        qpik.ik(robot, T[None], np.array([True]))


@pytest.mark.parametrize("param", [[0.1, [0.2]], [[0.1], [0.2, 0.3]]])
def test_a_ragged_parameter_is_named(param):
    robot = qpik.load_robot("iiwa14")
    with pytest.raises(qpik.InputError, match="param"):
        qpik.ik(robot, robot.fk(robot.q_home), param)
