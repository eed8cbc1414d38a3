"""Input checking: shapes, NaN/inf, orthonormality and projection onto SO(3)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEEDS
from hypothesis import given, settings
from hypothesis import strategies as st

from qpik.core.errors import InputError, RotationError
from qpik.core.validate import check_projectable, finite_array, joint_vector, pose, project_to_so3


def random_rotations(n: int, seed: int) -> np.ndarray:
    """(n, 3, 3) rotations from random unit quaternions (an independent construction)."""
    w, x, y, z = np.random.default_rng(seed).normal(size=(4, n)) / 1.0
    s = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / s, x / s, y / s, z / s
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def homogeneous(R: np.ndarray, p: np.ndarray | None = None) -> np.ndarray:
    T = np.zeros((*R.shape[:-2], 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = 0.0 if p is None else p
    T[..., 3, 3] = 1.0
    return T


# ---- finite_array / joint_vector ---------------------------------------------


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("shape", [(7,), (3, 7), (2, 4, 4), ()])
def test_nan_and_inf_are_rejected_by_name(bad, shape):
    x = np.zeros(shape)
    x[(0,) * len(shape)] = bad
    with pytest.raises(InputError, match=r"^speed: contains NaN or inf"):
        finite_array(x, "speed")
    with pytest.raises(ValueError):  # InputError is a ValueError for callers that do not know qpik
        finite_array(x.tolist() if shape else float(x), "speed")


def test_huge_finite_values_are_accepted():
    with np.errstate(over="ignore"):
        np.testing.assert_array_equal(finite_array([1e200, -1e200], "x"), [1e200, -1e200])


def test_shapes_are_checked_with_free_dimensions():
    assert finite_array([[1, 2, 3]] * 4, "pts", (None, 3)).shape == (4, 3)
    with pytest.raises(InputError, match=r"pts: expected shape \(N, 3\), got \(4, 2\)"):
        finite_array([[1, 2]] * 4, "pts", (None, 3))
    with pytest.raises(InputError, match="pts: cannot be read as a float array"):
        finite_array([[1, 2], [3]], "pts")
    with pytest.raises(InputError, match="pts: cannot be read"):
        finite_array("abc", "pts")


def test_finite_array_converts_without_aliasing_foreign_input():
    lst = [1, 2, 3]
    arr = finite_array(lst, "x")
    assert arr.dtype == np.float64 and arr.tolist() == [1.0, 2.0, 3.0]
    ints = np.arange(3)
    assert finite_array(ints, "x").dtype == np.float64


def test_joint_vector_single_and_batched():
    q, batched = joint_vector(np.zeros(7), 7)
    assert not batched and q.shape == (7,)
    q, batched = joint_vector(np.zeros((5, 7)), 7)
    assert batched and q.shape == (5, 7)
    for bad in (np.zeros(6), np.zeros((5, 6)), np.zeros((2, 5, 7)), np.zeros(())):
        with pytest.raises(InputError, match=r"^q0: expected shape \(7,\) or \(N, 7\)"):
            joint_vector(bad, 7, "q0")


# ---- pose --------------------------------------------------------------------


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_exact_rotations_pass_unchanged(seed):
    T = homogeneous(random_rotations(1000, seed), np.random.default_rng(seed).normal(size=(1000, 3)))
    out, batched = pose(T)
    assert batched and out is not T
    np.testing.assert_array_equal(out, T)
    out1, batched1 = pose(T[0])
    assert not batched1
    np.testing.assert_array_equal(out1, T[0])


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS, scale=st.floats(1e-5, 0.05))
def test_non_orthonormal_rotations_raise_unless_projected(seed, scale):
    rng = np.random.default_rng(seed)
    R = random_rotations(200, seed)
    noisy = R + scale * rng.normal(size=R.shape)
    T = homogeneous(noisy)
    with pytest.raises(RotationError, match=r"target: rotation is not orthonormal .*project=True"):
        pose(T, "target")
    with pytest.raises(RotationError, match="first bad index 0"):
        pose(T, "target")
    out, _ = pose(T, "target", project=True)
    P = out[:, :3, :3]
    np.testing.assert_allclose(np.swapaxes(P, 1, 2) @ P, np.broadcast_to(np.eye(3), P.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(P), 1.0, atol=1e-12)
    # the projection is the nearest rotation: no closer than the true R, which is also a candidate
    d_proj = np.linalg.norm(P - noisy, axis=(1, 2))
    d_true = np.linalg.norm(R - noisy, axis=(1, 2))
    assert np.all(d_proj <= d_true + 1e-12)


@pytest.mark.parametrize(
    "M",
    [
        np.diag([1.0, 1.0, -1.0]),  # orthonormal but det -1
        -random_rotations(1, 4)[0],  # -R: det -1
        np.zeros((3, 3)),
        np.outer([1.0, 0.0, 0.0], [1.0, 0.0, 0.0]),  # rank 1
        np.diag([1.0, 1.0, 1e-9]),  # det > 0 but (numerically) singular
        3.0 * np.eye(3),  # full rank, det > 0, far from orthonormal
    ],
)
def test_what_is_not_a_rotation_is_not_projected(M):
    """Projection is for rounding error: a reflection, a singular matrix or a far from orthonormal one raises."""
    with pytest.raises(RotationError, match="cannot be projected"):
        pose(homogeneous(M), project=True)
    with pytest.raises(RotationError, match="cannot be projected"):
        pose(homogeneous(np.stack([random_rotations(1, 1)[0], M])), project=True)
    with pytest.raises(RotationError) as info:
        pose(homogeneous(M))
    if np.linalg.det(M) <= 0.0:  # no projection could fix it: the message must not suggest one
        assert "project=True" not in str(info.value) and "det" in str(info.value)
    with pytest.raises(RotationError):
        check_projectable(M)


def test_project_must_be_a_bool():
    T = homogeneous(np.eye(3) * 1.001)
    for bad in ("no", "yes", 1, 0.0, None):
        with pytest.raises(InputError, match="project"):
            pose(T, project=bad)
    assert pose(T, project=np.bool_(True))[0][0, 0] == pytest.approx(1.0)


def test_projection_is_idempotent_and_does_not_touch_position():
    rng = np.random.default_rng(3)
    T = homogeneous(random_rotations(10, 3) + 0.03 * rng.normal(size=(10, 3, 3)), rng.normal(size=(10, 3)))
    out, _ = pose(T, project=True)
    np.testing.assert_array_equal(out[:, :3, 3], T[:, :3, 3])
    np.testing.assert_allclose(project_to_so3(out[:, :3, :3]), out[:, :3, :3], atol=1e-12)
    assert not np.shares_memory(out, T)


def test_empty_batch_and_huge_positions():
    out, batched = pose(np.zeros((0, 4, 4)))
    assert out.shape == (0, 4, 4) and batched
    T = homogeneous(np.eye(3), np.array([1e7, 0.0, 0.0]))
    for arg in (T, T[None]):
        with pytest.raises(InputError, match="goal: position magnitude"):
            pose(arg, "goal")
    assert pose(homogeneous(np.eye(3), np.array([0.0, -9e5, 0.0])))[0][1, 3] == -9e5


def test_complex_and_text_are_not_numbers():
    for bad in (np.array([1.0 + 1e-3j, 2.0]), [1j, 0.0], "abc", ["a", "b"], None, object()):
        with pytest.raises(InputError, match="q: cannot be read"):
            finite_array(bad, "q")


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (np.eye(3), r"goal: expected shape \(4, 4\) or \(N, 4, 4\)"),
        (np.zeros((2, 2, 4, 4)), r"goal: expected shape"),
        (np.diag([1.0, 1, 1, 2]), r"goal: last row must be \[0, 0, 0, 1\]"),
        (np.where(np.eye(4) > 0, np.nan, 0.0), "goal: contains NaN or inf"),
    ],
)
def test_bad_poses_name_the_argument(bad, message):
    with pytest.raises(InputError, match=message):
        pose(bad, "goal")
    with pytest.raises(InputError, match=message):
        pose(bad, "goal", project=True)
