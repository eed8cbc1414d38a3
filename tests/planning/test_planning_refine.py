"""qpik.planning.refine: the objective's gradient, the constraints' Jacobian and the Lagrangian's Hessian
assembled from the per-waypoint curvature functions equal CasADi's derivatives of the same NLP through its graph
(peers), on a path with an obstacle near some waypoints, an epigraph objective, acceleration rows and a
reconfiguration; and a plan with acceleration limits keeps them."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.geometry import Sphere
from qpik.geometry.distance import ObstacleSet
from qpik.objectives import resolve
from qpik.planning import path_problem
from qpik.planning.dp import Transitions
from qpik.planning.grid import Grid
from qpik.planning.refine import PathNLP

IIWA = qpik.load_robot("iiwa14")
N = 9


CASES = [(None, True), ("clearance", True), ("clearance", False), ("smooth-margin", False)]
"""(objective, per-waypoint curvature as machine code)"""


@pytest.fixture(scope="module", params=CASES)
def peers(request):
    """The assembled ``hess_lag`` (its per-waypoint curvature as machine code or on CasADi's virtual machine) and
    CasADi's own ``triu(∇²(σ f + λᵀ g))`` of one NLP, and the number of epigraph variables per waypoint."""
    name, compiled = request.param
    T = IIWA.fk(IIWA.q_home + np.linspace(0.0, 1.0, N)[:, None] * np.full(7, 0.15))
    obstacles = ObstacleSet([Sphere(T[N // 2, :3, 3] + (0.0, 0.0, 0.25), 0.05)])
    objective = None if name is None else resolve(name)
    scene = qpik.Scene.of(IIWA, obstacles, d_safe=0.01, objective=objective, q_ref=IIWA.q_home)
    grid = Grid(scene, T, 64)
    dt = np.linspace(0.08, 0.12, N - 1)  # uneven: the acceleration rows weigh their two steps differently
    tr = Transitions(np.full((N - 1, 7), 0.5), 1.0 / dt, np.full(N, 0.1), dt, np.full(7, 10.0))
    continuous = np.ones(N - 1, bool)
    continuous[5] = False  # a reconfiguration: no motion term, no step or acceleration bound there
    rows = np.array([0, 0, 0, 0, 0, 0, 2, 2, 2])
    nlp = PathNLP(scene, T, tr, continuous, grid, rows)
    near = np.array([0, 1, 1, 0, 1, 1, 1, 0, 0], bool)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(path_problem, "NATIVE_WAYPOINTS", 0 if compiled else N + 1)
        problem = nlp.problem(near)
    sigma, lam = ca.MX.sym("sigma"), ca.MX.sym("lam", problem.g.numel())
    x = problem.x
    auto = ca.Function("auto", [problem.z, problem.t, sigma, lam],
                       [ca.triu(ca.hessian(sigma * problem.f + ca.dot(lam, problem.g), x)[0]), problem.f,
                        ca.gradient(problem.f, x), problem.g, ca.jacobian(problem.g, x)])  # fmt: skip
    return problem, auto, nlp.n_t


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_assembled_derivatives_equal_casadis(peers, seed):
    problem, auto, n_t = peers
    rng = np.random.default_rng(seed)
    z = rng.uniform(-np.pi, np.pi, (1, N))
    t = rng.normal(size=(n_t, N))
    sigma = rng.uniform(0.1, 2.0)
    lam = rng.normal(size=problem.g.numel())
    x = np.concatenate([z.ravel(), t.T.ravel()])
    hess, f, grad, g, jac = (np.asarray(ca.densify(v)) for v in auto(z, t, sigma, lam))
    p = np.zeros(0)
    mine = [problem.hess_lag(x, p, sigma, lam), *problem.grad_f(x, p), *problem.jac_g(x, p)]
    for a, b in zip(mine, (hess, f, grad, g, jac)):
        a = np.asarray(ca.densify(a))
        assert a.shape == b.shape and np.isfinite(b).all() and np.abs(b).max() > 0
        assert np.allclose(a, b, rtol=1e-8, atol=1e-8 * np.abs(b).max())


def test_a_plan_with_acceleration_limits_keeps_them():
    T = IIWA.fk(IIWA.q_home + np.linspace(0.0, 1.0, 12)[:, None] * np.full(7, 0.2))
    times = np.linspace(0.0, 3.0, 12)
    a_max = np.full(7, 2.0)
    plan = qpik.plan_self_motion(IIWA, T, times=times, options=qpik.PlanOptions(a_max=a_max, mujoco=False))
    assert plan.ok and plan.status in ("optimal", "dp")
    dt = np.diff(times)
    v = np.diff(plan.q, axis=0) / dt[:, None]
    assert (np.abs(np.diff(v, axis=0)) <= a_max * 0.5 * (dt[1:] + dt[:-1])[:, None] + 1e-9).all()
