"""qpik.robots.locked_joint: the gap between a chain and its translated twin (ChainGap), checked against the two
chains' own forward kinematics."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import model_robot, random_q, random_robot
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.algebra import symbolic as sy
from qpik.analytic.api import closed_form_for
from qpik.robots.chain import SerialChain
from qpik.robots.locked_joint import ChainGap


def moved(chain: SerialChain, rng: np.random.Generator, scale: float) -> SerialChain:
    """``chain`` with the translations of some joints' pre and post transforms, its base and its tool moved."""
    joints = []
    for joint in chain.joints:
        pre, post = joint.pre.copy(), joint.post.copy()
        if rng.random() < 0.5:
            pre[:3, 3] += rng.normal(scale=scale, size=3)
        if rng.random() < 0.5:
            post[:3, 3] += rng.normal(scale=scale, size=3)
        joints.append(replace(joint, pre=pre, post=post))
    base, tool = chain.base.copy(), chain.tool.copy()
    base[:3, 3] += rng.normal(scale=scale, size=3)
    tool[:3, 3] += rng.normal(scale=scale, size=3)
    return SerialChain(joints, base, tool)


def gap_by_fk(chain: SerialChain, other: SerialChain, q: np.ndarray) -> np.ndarray:
    """(N, 3) m: the end's position on ``chain`` less that on ``other`` at q (N, 7), by their own FK."""
    return chain.frames(q)[..., -1, :3, 3] - other.frames(q)[..., -1, :3, 3]


def gap_expr(gap: ChainGap, chain: SerialChain, q: np.ndarray) -> np.ndarray:
    """(N, 3) m: ``gap.expr`` of ``chain``'s frames at q (N, 7), through the numpy ops."""
    return np.stack(gap.expr(chain.frames_expr(list(q.T), sy.NUMPY)), axis=-1)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from(["standard", "modified"]), st.floats(1e-6, 0.05))
def test_the_gap_of_translated_twins_is_the_difference_of_their_fk(seed, convention, scale):
    """Pre, post, base and tool translations moved at random on a random DH arm: the gap's formula, from the first
    chain's frames alone, is the difference of the two chains' FK, and its bound holds."""
    chain = random_robot(seed, convention).chain
    rng = np.random.default_rng(seed)
    other = moved(chain, rng, scale)
    gap = ChainGap.between(chain, other)
    q = rng.uniform(-np.pi, np.pi, (64, 7))
    want = gap_by_fk(chain, other, q)
    np.testing.assert_allclose(gap_expr(gap, chain, q), want, atol=1e-13, rtol=0)
    assert np.linalg.norm(want, axis=1).max() <= gap.bound * (1 + 1e-12)


@pytest.mark.parametrize("key", ["erd_xarm7", "robosuite_gen3"])
def test_a_near_members_gap_to_its_ideal_chain_is_the_difference_of_their_fk(key):
    """The model files served by a closed form polished onto them: the gap of the file's chain (read as the solver
    reads it) over its ideal chain, against both chains' FK."""
    robot = model_robot(key)
    inner = getattr(closed_form_for(robot), "inner", closed_form_for(robot))  # the Gen3 is read from the flange
    assert inner.gap is not None
    q = random_q(robot, 256, 4)
    want = gap_by_fk(inner.polished, inner.table, q)
    np.testing.assert_allclose(gap_expr(inner.gap, inner.polished, q), want, atol=1e-15, rtol=0)
    assert 0 < np.linalg.norm(want, axis=1).max() <= inner.gap.bound
