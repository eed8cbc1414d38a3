"""The sampled feasible sets of the slot solvers (the 1-D search: robosuite's Sawyer file, read from the flange, and
example-robot-data's Baxter arm; the general 6-R: example-robot-data's TIAGo Pro arm): not proved, checked against
the solver's own answers at dense random values of the locked joint and beside every end, and the span of a locked
joint's limits on the circle against its definition."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE, model_robot
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.analytic.api import closed_form_for
from qpik.analytic.intervals import shrunk_limits
from qpik.analytic.sampled_sets import locked_span

DENSE = 2000
END = 1e-9
"""rad: a sample this close to an end of its slot's set may fall on either side..."""
FOLD_END = 1e-6
"""rad: ... this close where the slot stops being valid at the end (two roots meet at a fold, where the polish's
residual decides whether they are one, two or none)."""
BESIDE = 1e-8
"""rad: the samples either side of every end."""


@pytest.mark.parametrize(
    "key, margin",
    [("erd_baxter", 0.3), ("erd_tiago_pro", 0.2)]
    + ([("erd_baxter", 0.0), ("robosuite_sawyer", 0.0), ("erd_tiago_pro", 0.0)] if LARGE else []),
)  # each case takes 10 to 40 s with the tests' unoptimised libraries: Baxter's at margin 0.3 in the default run
def test_the_sampled_sets_are_not_proved_and_match_the_solvers_answers(key, margin):
    """At DENSE random values of the locked joint and BESIDE either side of every end of every slot's set, a slot is
    in its set iff the solver finds it valid with every joint inside the limits shrunk by ``margin``, except within
    END of an end of its own set (FOLD_END where the slot's validity differs FOLD_END either side); the
    configuration's own slot holds its locked angle. One pose per case (six in the large run)."""
    robot = model_robot(key)
    solver = closed_form_for(robot)
    assert not solver.sets_proved
    lo, hi = shrunk_limits(robot.q_min, robot.q_max, margin)
    q = np.random.default_rng(20).uniform(lo, hi, (6 if LARGE else 1, 7))
    for T, param, branch in zip(robot.fk(q), *qpik.redundancy_parameter(robot, q)):
        fi = qpik.feasible_intervals(robot, T, margin=margin)
        assert not fi.proved and fi.contains(int(branch), param)
        ends = np.array([x for iv in fi.intervals for lohi in iv for x in lohi])
        x = np.concatenate([np.random.default_rng(3).uniform(-np.pi, np.pi, DENSE), ends - BESIDE, ends + BESIDE])
        x = x[np.abs(x) < np.pi]
        sols = solver.solve_many(T, x)
        inside = sols.valid & np.all((lo <= sols.q) & (sols.q <= hi), axis=-1)
        for k in range(len(fi.branch)):
            own = np.array([v for iv in fi[k] for v in iv])
            if not own.size:
                assert not inside[:, k].any(), f"slot {k}: no set, in at {x[inside[:, k]][:5]}"
                continue
            fold = solver.solve_many(T, own - FOLD_END).valid[:, k] != solver.solve_many(T, own + FOLD_END).valid[:, k]
            near = (np.abs(x[:, None] - own[None, :]) < np.where(fold, FOLD_END, END)[None, :]).any(axis=1)
            wrong = (fi.contains(k, x) != inside[:, k]) & ~near
            assert not wrong.any(), f"slot {k}: {fi[k]} at {x[wrong][:5]}"


@settings(max_examples=200, deadline=None)
@given(lo=st.floats(-9.0, 9.0), width=st.floats(0.0, 7.0))
def test_the_span_of_a_locked_joints_limits_holds_the_angles_with_a_representative_inside(lo, width):
    """A value of the circle is in the span iff one of its representatives x + 2πk lies in [lo, lo + width]."""
    hi = lo + width
    span = locked_span(lo, hi)
    assert all(-np.pi <= a <= b <= np.pi for a, b in span)
    x = np.linspace(-np.pi, np.pi, 2001)[1:-1]
    k = np.arange(-3, 4)[:, None]
    inside = ((x + 2 * np.pi * k >= lo + 1e-9) & (x + 2 * np.pi * k <= hi - 1e-9)).any(axis=0)
    outside = ~((x + 2 * np.pi * k >= lo - 1e-9) & (x + 2 * np.pi * k <= hi + 1e-9)).any(axis=0)
    held = np.zeros(len(x), bool)
    for a, b in span:
        held |= (a <= x) & (x <= b)
    assert held[inside].all() and not held[outside].any()
