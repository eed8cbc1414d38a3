"""BranchSolver.representative: a joint's value inside its limits, against every representative x + 2πk counted one
by one, and its Taylor model where the wrapped angle passes ±π, against samples."""

from __future__ import annotations

import casadi as ca
import numpy as np
from conftest import model_robot
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.algebra import symbolic as sy
from qpik.algebra.enclosure import taylor_function
from qpik.analytic import closed_form_for
from qpik.analytic.intervals import wrap

PANDA = qpik.load_robot("panda")
"""q6 in [−0.0175, 3.7525] rad: its representative changes where the wrapped angle passes π."""


@settings(max_examples=50, deadline=None)
@given(key=st.sampled_from(["panda", "robosuite_jaco"]), seed=st.integers(0, 2**16))
def test_the_representative_is_the_one_inside_the_limits_else_the_smallest_above_them(key, seed):
    robot = PANDA if key == "panda" else model_robot(key)
    solver = closed_form_for(robot)
    x = np.random.default_rng(seed).uniform(-np.pi, np.pi, 200)
    x = np.concatenate([x, wrap(np.concatenate([robot.q_min, robot.q_max]))])
    k = np.arange(-3, 4)[:, None]
    wide = (robot.q_min < -np.pi) | (robot.q_max > np.pi)
    assert wide.any()
    for j in np.flatnonzero(wide):
        lo, hi = robot.q_min[j], robot.q_max[j]
        got = solver.representative(int(j), x, sy.NUMPY)
        every = x + 2 * np.pi * k  # (7, M)
        assert np.allclose(np.cos(got), np.cos(x), atol=1e-12) and np.allclose(np.sin(got), np.sin(x), atol=1e-12)
        inside = (every >= lo) & (every <= hi)
        some = inside.any(axis=0)
        if hi - lo < 2 * np.pi:  # at most one inside; else the smallest above the lower limit
            above = np.where(every >= lo, every, np.inf).min(axis=0)
            np.testing.assert_allclose(got, np.where(some, every[inside.argmax(axis=0), np.arange(len(x))], above),
                                       atol=1e-12)  # fmt: skip
        else:
            assert ((got >= lo) & (got <= hi))[some].all()


def test_the_model_of_a_joint_whose_representative_changes_at_pi_stays_continuous():
    """The Panda's q6 at the angle t of a unit vector, over cells of t around π (where the wrapped angle jumps from
    π to −π and the representative back to π): the Taylor model's bounds are as wide as the samples' range to second
    order, not the whole turn, and hold every sample."""
    solver = closed_form_for(PANDA)
    t = ca.SX.sym("t")
    q6 = solver.representative(5, sy.CASADI.wrap(ca.atan2(ca.sin(t), ca.cos(t))), sy.CASADI)
    model = taylor_function(ca.Function("q6", [t], [q6]), [0])
    for half in (1e-1, 1e-3, 1e-6):
        for centre in (np.pi, np.pi - 0.3 * half, np.pi + 0.7 * half):
            c, s, r, lo, hi = (float(v) for v in model(centre, half, 0.0, centre - half, centre + half))
            samples = np.linspace(centre - half, centre + half, 101)
            values = solver.representative(5, wrap(samples), sy.NUMPY)
            assert np.all(values >= lo - 1e-12) and np.all(values <= hi + 1e-12)
            assert np.all(np.abs(values - (c + s * np.linspace(-1, 1, 101))) <= r + 1e-12)
            assert hi - lo <= 2 * half + 4 * half**2, (half, centre, lo, hi)  # second order
