"""Obstacle shapes: validation, problem-file specs, MJCF rendering (checked by MuJoCo)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from qpik.core.errors import InputError, RotationError
from qpik.geometry import Box, Capsule, HalfSpace, Sphere, obstacles_from_specs, shape_from_spec


def _rot_z(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_specs_build_the_shapes():
    shapes = obstacles_from_specs(
        [
            {"type": "sphere", "center": [0.5, 0.0, 0.4], "radius": 0.1, "name": "ball"},
            {"type": "capsule", "p0": [0, 0.5, 0], "p1": [0, 0.5, 1], "radius": 0.05},
            {"type": "box", "center": [0.3, 0.3, 0.2], "half_extents": [0.1, 0.2, 0.05], "rotation": _rot_z(0.3)},
            {"type": "halfspace", "normal": [0, 0, 2.0], "offset": 0.1},
        ]
    )
    sphere, capsule, box, plane = shapes
    assert isinstance(sphere, Sphere) and sphere.name == "ball" and sphere.radius == 0.1
    assert isinstance(capsule, Capsule) and np.array_equal(capsule.p1, [0, 0.5, 1])
    assert isinstance(box, Box) and np.allclose(box.rotation, _rot_z(0.3))
    assert isinstance(plane, HalfSpace) and np.array_equal(plane.normal, [0, 0, 1]) and plane.offset == 0.05
    assert np.array_equal(Box([0, 0, 0], [1, 1, 1]).rotation, np.eye(3))
    with pytest.raises(ValueError):
        sphere.center[0] = 1.0  # stored read-only


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ({"type": "cone"}, "obstacle type"),
        ({"type": "sphere", "center": [0, 0, 0]}, "missing"),
        ({"type": "sphere", "center": [0, 0, 0], "radius": 1, "colour": "red"}, "unknown"),
        ({"type": "sphere", "center": [0, 0], "radius": 1}, "center"),
        ({"type": "sphere", "center": [0, 0, np.nan], "radius": 1}, "center"),
        ({"type": "sphere", "center": [0, 0, 0], "radius": 0.0}, "radius"),
        ({"type": "capsule", "p0": [0, 0, 0], "p1": [0, 0, np.inf], "radius": 1}, "p1"),
        ({"type": "capsule", "p0": [0, 0, 0], "p1": [0, 0, 1], "radius": -1}, "radius"),
        ({"type": "box", "center": [0, 0, 0], "half_extents": [1, 0, 1]}, "half_extents"),
        ({"type": "box", "center": [0, 0, 0], "half_extents": [1, 1, 1], "rotation": np.eye(2)}, "rotation"),
        ({"type": "halfspace", "normal": [0, 0, 0], "offset": 0.0}, "normal"),
        ({"type": "halfspace", "normal": [0, 0, 1], "offset": np.nan}, "offset"),
        ({"type": "sphere", "center": [0, 0, 0], "radius": 1, "name": 3}, "name"),
    ],
)
def test_bad_specs_raise_input_error(spec, match):
    with pytest.raises(InputError, match=match):
        obstacles_from_specs([{"type": "sphere", "center": [0, 0, 0], "radius": 1}, spec])
    with pytest.raises(InputError, match=r"obstacles\[1\]"):
        obstacles_from_specs([{"type": "sphere", "center": [0, 0, 0], "radius": 1}, spec])


def test_box_rotation_must_be_orthonormal_unless_projected():
    R = np.round(_rot_z(0.7), 3)  # hand-typed rows: not orthonormal within 1e-6
    spec = {"type": "box", "center": [0, 0, 0], "half_extents": [1, 1, 1], "rotation": R.tolist()}
    with pytest.raises(RotationError):
        shape_from_spec(spec)
    with pytest.raises(RotationError):
        Box([0, 0, 0], [1, 1, 1], -np.eye(3))  # det -1
    box = shape_from_spec({**spec, "project": True})
    assert np.allclose(box.rotation.T @ box.rotation, np.eye(3), atol=1e-12)
    assert np.allclose(box.rotation, _rot_z(0.7), atol=1e-3)


def test_mjcf_geoms_compile_to_the_same_shapes():
    R = _rot_z(0.4) @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    shapes = [
        Sphere([0.5, 0.0, 0.4], 0.1, name="ball"),
        Capsule([0, 0.5, 0], [0.2, 0.5, 1], 0.05, name="pole"),
        Capsule([0.1, 0.1, 0.1], [0.1, 0.1, 0.1], 0.05),  # zero length: drawn as a sphere
        Box([0.3, 0.3, 0.2], [0.1, 0.2, 0.05], R, name='odd "name"'),
        HalfSpace([0.0, 0.6, 0.8], 0.1),
    ]
    xml = "<mujoco><worldbody>" + "".join(s.to_mjcf_geom() for s in shapes) + "</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    G = mujoco.mjtGeom
    assert list(model.geom_type) == [G.mjGEOM_SPHERE, G.mjGEOM_CAPSULE, G.mjGEOM_SPHERE, G.mjGEOM_BOX, G.mjGEOM_PLANE]
    assert model.geom("ball").size[0] == 0.1 and model.geom('odd "name"').id == 3
    assert np.allclose(data.geom_xpos[1], [0.1, 0.5, 0.5]) and np.isclose(model.geom_size[1, 1], np.sqrt(0.04 + 1) / 2)
    assert np.allclose(data.geom_xpos[3], [0.3, 0.3, 0.2]) and np.allclose(model.geom_size[3], [0.1, 0.2, 0.05])
    assert np.allclose(data.geom_xmat[3].reshape(3, 3), R, atol=1e-12)
    plane_z = data.geom_xmat[4].reshape(3, 3)[:, 2]
    assert np.allclose(plane_z, [0.0, 0.6, 0.8]) and np.isclose(plane_z @ data.geom_xpos[4], 0.1)
    assert all('rgba="1 0 0 0.35"' in s.to_mjcf_geom() for s in shapes)


def test_box_rotation_that_is_not_one():
    """A reflection is refused with or without project=True, and its message does not suggest projection."""
    with pytest.raises(RotationError, match="det = -1") as info:
        Box((0, 0, 0), (1, 1, 1), rotation=-np.eye(3))
    assert "project=True" not in str(info.value)
    for R in (-np.eye(3), np.zeros((3, 3)), np.diag([1.0, 1.0, 0.0])):
        with pytest.raises(RotationError, match="cannot be projected"):
            Box((0, 0, 0), (1, 1, 1), rotation=R, project=True)
    with pytest.raises(InputError, match="project"):
        Box((0, 0, 0), (1, 1, 1), rotation=np.eye(3) * 1.001, project="no")
    rounded = Box((0, 0, 0), (1, 1, 1), rotation=np.eye(3) * 1.001, project=True).rotation
    np.testing.assert_allclose(rounded, np.eye(3), atol=1e-12)


@pytest.mark.parametrize(
    "make",
    [
        lambda: Sphere((1e7, 0, 0), 0.1),
        lambda: Sphere((0, 0, 0), 1e155),
        lambda: Capsule((0, 0, 0), (0, 0, 1e200), 0.1),
        lambda: Box((0, 0, 0), (1e9, 1, 1)),
        lambda: HalfSpace((0, 0, 1), 1e300),
        lambda: Sphere((0, 0, 0), 0.1 + 0.1j),
        lambda: Sphere("abc", 0.1),
    ],
)
def test_huge_or_non_real_shape_data_is_refused(make):
    with pytest.raises(InputError):
        make()
