"""SerialChain: random chains of revolute and prismatic joints with arbitrary fixed transforms.

Derivatives against finite differences of FK, the compiled single-q path against the numpy
batch, the point Jacobian against finite differences of a point carried by a link.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from conftest import SEEDS, fd, fd_geometric_jacobian
from hypothesis import given, settings

import qpik
from qpik.core.errors import InputError
from qpik.robots.chain import SerialChain
from qpik.robots.joint import Joint

PROPERTY = settings(max_examples=4, deadline=None)


def random_transform(rng: np.random.Generator, scale: float = 0.3) -> np.ndarray:
    A = rng.normal(size=(3, 3))
    Q, R = np.linalg.qr(A)
    Q *= np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Q, rng.normal(scale=scale, size=3)
    return T


def random_chain(seed: int, n: int = 6) -> SerialChain:
    """Joints with random pre (and every other one a random post), one in three prismatic."""
    rng = np.random.default_rng(seed)
    joints = [
        Joint(
            pre=random_transform(rng),
            post=random_transform(rng) if k % 2 else np.eye(4),
            kind="prismatic" if k % 3 == 2 else "revolute",
            offset=rng.uniform(-1, 1),
        )
        for k in range(n)
    ]
    return SerialChain(joints, base=random_transform(rng), tool=random_transform(rng))


@PROPERTY
@given(seed=SEEDS)
def test_derivatives_are_fd_and_batch_is_single(seed):
    chain = random_chain(seed % 1000)
    q = np.random.default_rng(seed).uniform(-2, 2, size=(200, chain.dof))
    J = chain.jacobian(q)
    np.testing.assert_allclose(J, fd_geometric_jacobian(chain.fk, q), atol=1e-6, rtol=0)
    np.testing.assert_allclose(chain.hessian(q), np.moveaxis(fd(chain.jacobian, q), -1, 1), atol=1e-6, rtol=0)
    for qi, Ji in zip(q[:5], J[:5]):
        np.testing.assert_allclose(chain.jacobian(qi), Ji, atol=1e-12, rtol=0)
        np.testing.assert_allclose(chain.fk(qi), chain.fk(qi[None])[0], atol=1e-12, rtol=0)
        np.testing.assert_allclose(chain.frames(qi), chain.frames(qi[None])[0], atol=1e-12, rtol=0)
        np.testing.assert_allclose(
            chain.manipulability_gradient(qi), chain.manipulability_gradient(qi[None])[0], atol=1e-10, rtol=0
        )


def test_prismatic_joint_has_no_angular_part_and_moves_along_its_axis():
    chain = random_chain(3)
    q = np.random.default_rng(1).uniform(-1, 1, chain.dof)
    J = chain.jacobian(q)
    z, _ = chain.axes(q)
    for k in np.flatnonzero(chain.prismatic):
        np.testing.assert_allclose(J[3:, k], 0.0, atol=1e-15)
        np.testing.assert_allclose(J[:3, k], z[k], atol=1e-12)


def test_point_jacobian_is_fd_of_a_carried_point():
    import casadi as ca

    from qpik.algebra import symbolic as sy

    chain = random_chain(11)
    link, local = 4, np.array([0.1, -0.05, 0.2])
    q = ca.SX.sym("q", chain.dof)
    frames = chain.frames_expr([q[i] for i in range(chain.dof)], sy.CASADI)
    R, t = frames[link]
    p = sy.vadd(sy.matvec(R, tuple(local)), t)
    cols = chain.point_jacobian_expr(frames, p, link)
    f = ca.Function("f", [q], [ca.horzcat(*[ca.vertcat(*c) for c in cols]), ca.vertcat(*p)])
    q0 = np.random.default_rng(2).uniform(-1, 1, chain.dof)
    Jp = np.array(f(q0)[0])
    Jfd = fd(lambda x: np.array(f(x)[1]).ravel(), q0)
    np.testing.assert_allclose(Jp, Jfd[:, :link], atol=1e-7, rtol=0)
    np.testing.assert_allclose(Jfd[:, link:], 0.0, atol=1e-9)


def test_bad_chains_are_rejected():
    with pytest.raises(InputError, match="at least one joint"):
        SerialChain([])
    with pytest.raises(InputError, match=r"Joint\.kind"):
        Joint(kind="ball")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"Joint\.pre"):
        Joint(pre=np.eye(3))
    with pytest.raises(InputError, match=r"SerialChain\.base"):
        SerialChain([Joint()], base=np.full((4, 4), np.nan))


def test_threads_sharing_an_arm_get_the_answers_of_one_thread() -> None:
    """Four threads evaluating one arm at once get exactly what one thread gets, on the compiled single-q path
    (lists take the general path: the compiled function's call and copies under its lock) and the fast one."""
    robot = qpik.load_robot("iiwa14")
    Q = np.random.default_rng(11).uniform(robot.q_min, robot.q_max, (40, robot.dof))

    def answers(k: int) -> list:
        out = []
        for q in Q[k::4]:
            T, J = robot.fk_jacobian(q.tolist())
            out += [robot.fk(q.tolist()), T, J, robot.hessian(q), robot.chain.frames(q), robot.fk(q)]
            out += [robot.manipulability_gradient(q.tolist()), robot.jacobian(q.tolist())]
        return [x.tolist() for x in out]

    serial = [answers(k) for k in range(4)]
    with ThreadPoolExecutor(4) as pool:
        for _ in range(3):
            assert list(pool.map(answers, range(4))) == serial
