"""DHChain: derivatives against finite differences of FK, batched vs single-q, CasADi vs numpy.

Every arm of the catalog, 10,000 configurations per arm and property (five
hypothesis seeds of 2,000 configurations, each evaluated by one batched call).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS, fd, fd_geometric_jacobian, q_within_limits, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.core.errors import InputError
from qpik.robots.dh import DHChain

BATCH = 2000
PROPERTY = settings(max_examples=5, deadline=None)


@PROPERTY
@given(seed=SEEDS)
def test_jacobian_is_fd_of_fk(robot, seed):
    q = random_q(robot, BATCH, seed)
    np.testing.assert_allclose(robot.jacobian(q), fd_geometric_jacobian(robot.fk, q), atol=1e-6, rtol=0)


@PROPERTY
@given(seed=SEEDS)
def test_hessian_is_fd_of_jacobian(robot, seed):
    q = random_q(robot, BATCH, seed)
    H = robot.hessian(q)  # (N, k, 6, j)
    H_fd = np.moveaxis(fd(robot.jacobian, q), -1, 1)  # (N, 6, j, k) -> (N, k, 6, j)
    np.testing.assert_allclose(H, H_fd, atol=1e-6, rtol=0)


@pytest.mark.parametrize("translational", [False, True])
@PROPERTY
@given(seed=SEEDS)
def test_manipulability_gradient_is_fd(robot, translational, seed):
    q = random_q(robot, BATCH, seed)
    m = robot.manipulability(q, translational)
    # sqrt(det) has unbounded slope at m = 0: compare away from singularities
    q = q[m > 1e-3]
    g = robot.manipulability_gradient(q, translational)
    g_fd = fd(lambda x: robot.manipulability(x, translational), q)
    np.testing.assert_allclose(g, g_fd, atol=1e-6, rtol=0)


@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_single_q_derivatives_are_fd(robot, data):
    """The compiled single-configuration path, one shrinkable draw at a time (edges of the limits included)."""
    q = data.draw(q_within_limits(robot))
    np.testing.assert_allclose(robot.jacobian(q), fd_geometric_jacobian(robot.fk, q), atol=1e-6, rtol=0)
    np.testing.assert_allclose(robot.hessian(q), np.moveaxis(fd(robot.jacobian, q), -1, 0), atol=1e-6, rtol=0)


@PROPERTY
@given(seed=SEEDS)
def test_manipulability_is_sqrt_det(robot, seed):
    q = random_q(robot, 200, seed)
    J = robot.jacobian(q)
    # Yoshikawa's index is the product of the singular values of J
    np.testing.assert_allclose(robot.manipulability(q), np.prod(np.linalg.svd(J)[1], axis=-1), atol=1e-12)
    np.testing.assert_allclose(
        robot.manipulability(q, translational=True), np.prod(np.linalg.svd(J[:, :3])[1], axis=-1), atol=1e-12
    )


@settings(max_examples=2, deadline=None)
@given(seed=SEEDS)
def test_single_q_path_equals_batched_path(robot, seed):
    q = random_q(robot, 500, seed)
    batched = {
        "fk": robot.fk(q),
        "frames": robot.frames(q),
        "jacobian": robot.jacobian(q),
        "hessian": robot.hessian(q),
        "manipulability": robot.manipulability(q),
        "manipulability_gradient": robot.manipulability_gradient(q),
    }
    for name, want in batched.items():
        got = np.array([getattr(robot, name)(qi) for qi in q])
        # the gradient goes through pinv(J Jᵀ): batched and single LAPACK calls differ by its conditioning
        atol = 1e-9 if name == "manipulability_gradient" else 1e-12
        np.testing.assert_allclose(got, want, atol=atol, rtol=0, err_msg=name)
    T, J = robot.fk_jacobian(q)
    T1, J1 = zip(*(robot.fk_jacobian(qi) for qi in q))
    np.testing.assert_allclose(np.array(T1), T, atol=1e-12, rtol=0)
    np.testing.assert_allclose(np.array(J1), J, atol=1e-12, rtol=0)


def test_single_q_results_are_not_shared_buffers(robot):
    q0, q1 = robot.q_home, robot.q_home + 0.3
    T0, J0 = robot.fk_jacobian(q0)
    T0_copy, J0_copy = T0.copy(), J0.copy()
    robot.fk_jacobian(q1)
    robot.fk(q1)
    np.testing.assert_array_equal(T0, T0_copy)
    np.testing.assert_array_equal(J0, J0_copy)


@settings(max_examples=2, deadline=None)
@given(seed=SEEDS)
def test_casadi_functions_equal_numpy(robot, seed):
    q = random_q(robot, 5000, seed)
    n, dof = len(q), robot.dof
    fns = robot.chain.casadi_functions
    Q = ca.DM(q.T)  # (dof, N): one column per configuration
    T = np.array(fns["fk"].map(n)(Q)).reshape(4, n, 4).transpose(1, 0, 2)
    np.testing.assert_allclose(T, robot.fk(q), atol=1e-12, rtol=0)
    J = np.array(fns["jacobian"].map(n)(Q)).reshape(6, n, dof).transpose(1, 0, 2)
    np.testing.assert_allclose(J, robot.jacobian(q), atol=1e-12, rtol=0)
    H = np.array(fns["hessian"].map(n)(Q)).reshape(dof, 6, n, dof).transpose(2, 0, 1, 3)
    np.testing.assert_allclose(H, robot.hessian(q), atol=1e-12, rtol=0)
    F = np.array(fns["frames"].map(n)(Q)).reshape(4, n, dof + 2, 4).transpose(1, 2, 0, 3)
    np.testing.assert_allclose(F, robot.frames(q), atol=1e-12, rtol=0)
    Tj, Jj = fns["fk_jacobian"].map(n)(Q)
    np.testing.assert_allclose(np.array(Tj).reshape(4, n, 4).transpose(1, 0, 2), T, atol=0)
    np.testing.assert_allclose(np.array(Jj).reshape(6, n, dof).transpose(1, 0, 2), J, atol=0)


def test_casadi_jacobian_is_exact_derivative(robot):
    """The symbolic Jacobian's linear rows are CasADi's own derivative of the FK position."""
    q = ca.SX.sym("q", robot.dof)
    p = robot.chain.casadi_functions["fk"](q)[:3, 3]
    dp = ca.Function("dp", [q], [ca.jacobian(p, q)])
    for qi in random_q(robot, 20, 0):
        np.testing.assert_allclose(np.array(dp(qi)), robot.jacobian(qi)[:3], atol=1e-12)


def test_frames_end_with_base_and_ee(robot):
    q = random_q(robot, 50, 1)
    F = robot.frames(q)
    assert F.shape == (50, robot.dof + 2, 4, 4)
    np.testing.assert_allclose(F[:, 0], np.broadcast_to(robot.chain.base, (50, 4, 4)), atol=0)
    np.testing.assert_allclose(F[:, -1], robot.fk(q), atol=1e-15)


def random_q_plain(dof: int, n: int) -> np.ndarray:
    """(n, dof) angles uniform in [-π, π) for chains that are not in the catalog."""
    return np.random.default_rng(7).uniform(-np.pi, np.pi, (n, dof))


def test_modified_and_standard_conventions_agree_on_a_shared_arm():
    """A planar 3R arm written in both conventions has the same FK (independent of qpik's tables)."""
    lengths = (0.3, 0.2, 0.1)
    std = DHChain(a=lengths, d=(0, 0, 0), alpha=(0, 0, 0))
    tool = np.eye(4)
    tool[0, 3] = lengths[2]
    mod = DHChain(a=(0, *lengths[:2]), d=(0, 0, 0), alpha=(0, 0, 0), convention="modified", tool=tool)
    q = random_q_plain(3, 100)
    np.testing.assert_allclose(std.fk(q), mod.fk(q), atol=1e-14)
    # and both equal the planar formula
    c = np.cumsum(q, axis=1)
    x = (np.array(lengths) * np.cos(c)).sum(axis=1)
    y = (np.array(lengths) * np.sin(c)).sum(axis=1)
    np.testing.assert_allclose(std.fk(q)[:, 0, 3], x, atol=1e-14)
    np.testing.assert_allclose(std.fk(q)[:, 1, 3], y, atol=1e-14)
    np.testing.assert_allclose(std.jacobian(q), fd_geometric_jacobian(std.fk, q), atol=1e-7)
    np.testing.assert_allclose(mod.jacobian(q), fd_geometric_jacobian(mod.fk, q), atol=1e-7)


def test_base_and_tool_transforms_compose():
    base, tool = np.eye(4), np.eye(4)
    base[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    base[:3, 3] = (0.1, -0.2, 0.3)
    tool[:3, 3] = (0.0, 0.05, 0.1)
    plain = DHChain(a=(0.2, 0.1), d=(0.1, 0.0), alpha=(np.pi / 2, 0.3))
    moved = DHChain(a=plain.a, d=plain.d, alpha=plain.alpha, base=base, tool=tool)
    q = random_q_plain(2, 30)
    np.testing.assert_allclose(moved.fk(q), base @ plain.fk(q) @ tool, atol=1e-14)
    np.testing.assert_allclose(moved.jacobian(q), fd_geometric_jacobian(moved.fk, q), atol=1e-7)


@pytest.mark.parametrize("method", ["fk", "jacobian", "hessian", "frames", "fk_jacobian", "manipulability"])
@pytest.mark.parametrize(
    "bad",
    [
        [0.0] * 6,
        [[0.0] * 8],
        np.zeros((2, 3, 7)),
        [0.0, np.nan, 0, 0, 0, 0, 0],
        [[0.0] * 7, [0, 0, 0, np.inf, 0, 0, 0]],
        "not numbers",
    ],
)
def test_bad_joint_vectors_raise_input_error_naming_q(method, bad):
    import qpik

    robot = qpik.load_robot("iiwa14")
    with pytest.raises(InputError, match=r"^q\b"):
        getattr(robot, method)(bad)


def test_bad_dh_tables_are_rejected():
    with pytest.raises(ValueError, match="same length"):
        DHChain(a=(0, 0), d=(0,), alpha=(0, 0))
    with pytest.raises(ValueError, match="convention"):
        DHChain(a=(0,), d=(0,), alpha=(0,), convention="craig")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"DHChain\.tool"):
        DHChain(a=(0,), d=(0,), alpha=(0,), tool=np.eye(3))
