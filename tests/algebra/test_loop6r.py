"""qpik.algebra.loop6r: the elimination of a general 6-R chain to one eigenproblem finds every configuration of a pose.

The chains are random DH tables, whose poses come from qpik's DH chain (``DHChain.fk``, not the module's own motions);
every configuration drawn must be among the candidates, and the candidate nearest to it must reach the pose. Each
window of the elimination is checked on its own, and a chain of special geometry (three parallel axes) is refused with
its reason."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import LARGE
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.algebra.loop6r import CHECKS, WINDOWS, Loop6R, Window
from qpik.robots.dh import DHChain

EXAMPLES = 40 if LARGE else 8
POSES = 10
HELD = 1e-7
"""rad: a configuration is among the candidates to this (unpolished)."""
REACH = 1e-8
"""A candidate's pose by the DH chain's FK equals the pose to this (m and rotation entries, unpolished)."""


def _chain(a, d, alpha) -> DHChain:
    return DHChain(a=tuple(a), d=tuple(d), alpha=tuple(alpha), convention="standard")


def _home_removed(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """The poses of ``q`` (K, 6) with the end's pose at q = 0 taken off: :math:`E_1 \\cdots E_6`."""
    return chain.fk(q) @ np.linalg.inv(chain.fk(np.zeros(6)))


@settings(max_examples=EXAMPLES, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_every_configuration_of_a_general_chain_is_a_candidate_and_every_candidate_reaches_the_pose(seed):
    """A DH table drawn from ``seed`` (a in [0.05, 0.5] m, d in [−0.4, 0.4] m, twists of either sign in [0.3, 2.8]
    rad: general with probability 1, where hypothesis's own floats would shrink to the special chains of equal
    entries), POSES random configurations."""
    rng = np.random.default_rng(seed)
    twist = rng.uniform(0.3, 2.8, 6) * rng.choice([-1.0, 1.0], 6)
    chain = _chain(rng.uniform(0.05, 0.5, 6), rng.uniform(-0.4, 0.4, 6), twist)
    h, o = chain.axes(np.zeros(6))
    loop, why = Loop6R.of(h, o)
    assert loop is not None, why
    q = rng.uniform(-np.pi, np.pi, (POSES, 6))
    for G, qk in zip(_home_removed(chain, q), q):
        found = loop.solve(G)
        assert len(found) <= 16
        gap = np.abs((found - qk + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
        assert gap.min() < HELD, gap.min()
        reached = _home_removed(chain, found[np.argmin(gap)][None])[0]
        assert np.abs(reached - G).max() < REACH


@pytest.mark.parametrize("start, backwards", WINDOWS)
def test_each_window_alone_finds_the_configurations_of_a_general_chain(start, backwards):
    """Every window's elimination, on one general chain: its fit has the form (to round-off) and its candidates hold
    random configurations, each reaching the pose."""
    chain = _chain(
        (0.1, 0.3, 0.2, 0.15, 0.25, 0.12), (0.2, -0.1, 0.3, 0.05, -0.2, 0.1), (1.1, -0.7, 1.9, -2.3, 0.9, -1.4)
    )
    h, o = chain.axes(np.zeros(6))
    loop = Loop6R(h, o, Window.of(start, backwards))
    assert loop.fit < 1e-12
    q = np.random.default_rng(start + 3 * backwards).uniform(-np.pi, np.pi, (CHECKS, 6))
    for G, qk in zip(_home_removed(chain, q), q):
        found = loop.solve(G)
        assert np.abs((found - qk + np.pi) % (2 * np.pi) - np.pi).max(axis=1).min() < HELD


def test_a_chain_of_three_parallel_axes_is_refused_with_its_reason():
    """A 6-R chain whose first three axes are parallel (twists 0) and last three meet: every window's eigenproblem
    is singular for every value of its variable (such chains have closed forms of their own); the reason names each
    window and how many configurations it held."""
    chain = _chain((0.3, 0.3, 0.3, 0.0, 0.0, 0.0), (0.0,) * 6, (0.0, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0))
    h, o = chain.axes(np.zeros(6))
    loop, why = Loop6R.of(h, o)
    assert loop is None
    assert why.startswith("the elimination of every window is singular") and why.count(f"/{CHECKS}") == len(WINDOWS)


@pytest.mark.parametrize(
    "a, d, alpha",
    [  # Puma 560 (Craig's standard table) and UR5 (Universal Robots' published DH): wrist-partitioned, not general
        ((0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0), (0.0, 0.0, 0.15, 0.4318, 0.0, 0.0),
         (np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0)),
        ((0.0, -0.425, -0.39225, 0.0, 0.0, 0.0), (0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823),
         (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)),
    ],
    ids=["puma560", "ur5"],
)  # fmt: skip
def test_special_industrial_chains_are_held_by_some_window(a, d, alpha):
    """Chains of special geometry that some window still solves (a spherical wrist; three parallel axes and an offset
    wrist): every configuration of 20 random ones is among the candidates, and its candidate reaches the pose."""
    chain = _chain(a, d, alpha)
    h, o = chain.axes(np.zeros(6))
    loop, why = Loop6R.of(h, o)
    assert loop is not None, why
    q = np.random.default_rng(21).uniform(-np.pi, np.pi, (20, 6))
    for G, qk in zip(_home_removed(chain, q), q):
        found = loop.solve(G)
        gap = np.abs((found - qk + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
        assert gap.min() < HELD, gap.min()
        assert np.abs(_home_removed(chain, found[np.argmin(gap)][None])[0] - G).max() < REACH
