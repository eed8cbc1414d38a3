"""Hostile and broken model files: each gives exactly one qpik error, never a dependency's exception.

Every case writes one file (or a small folder) and loads it; the error must be a
:class:`~qpik.core.errors.QpikError` with no exception chained from a dependency (``from None``), and
its message must say what is wrong.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import qpik
from qpik.core.errors import InputError, QpikError
from qpik.robots.model_files import MeshOptions

LINK = '<link name="{0}"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>'


def urdf(joint: str = "", extra: str = "", links: str = "", name: str = "hostile") -> str:
    """A two-link URDF whose joint j1 carries ``joint`` (attributes and elements), plus ``extra`` elements."""
    links = links or LINK.format("base") + LINK.format("l1")
    body = joint or '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
    return (
        f'<robot name="{name}">{links}'
        f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{body}</joint>{extra}</robot>'
    )


def mesh_urdf(filename: str) -> str:
    links = (
        LINK.format("base")
        + f'<link name="l1"><collision><geometry><mesh filename="{filename}"/></geometry></collision></link>'
    )
    return urdf(links=links)


LAUGHS = (
    '<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
    + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(8))
    + ']><robot name="&i;"><link name="base"/></robot>'
)
MJCF = "<mujoco{attrs}><worldbody><body name='b'>{body}<geom size='.1'/></body></worldbody></mujoco>"
OK_JOINT = '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'

# key: (file name, text or bytes, load options, the message's expected part)
CASES: dict[str, tuple[str, str | bytes, dict, str]] = {
    "billion_laughs": ("a.urdf", LAUGHS, {}, "declares a document type"),
    "external_entity": (
        "a.urdf",
        '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><robot name="&x;"/>',
        {},
        "declares a document type",
    ),
    "doctype_only": ("a.urdf", '<!DOCTYPE robot><robot name="r"><link name="b"/></robot>', {}, "document type"),
    "unclosed_tag": ("a.urdf", '<robot name="r"><link name="b">', {}, "not well-formed XML"),
    "empty_file": ("a.urdf", "", {}, "not well-formed XML"),
    "binary_garbage": ("a.urdf", bytes(range(256)) * 4, {}, "not well-formed XML"),
    "png_as_urdf": ("a.urdf", b"\x89PNG\r\n\x1a\n" + b"\x00" * 64, {}, "not well-formed XML"),
    "bad_utf8": ("a.urdf", b'<robot name="\xff\xfe"><link name="b"/></robot>', {}, "not well-formed XML"),
    "no_joints": ("a.urdf", f'<robot name="r">{LINK.format("base")}</robot>', {}, "no joints"),
    "missing_parent": (
        "a.urdf",
        urdf().replace('<parent link="base"/>', '<parent link="nowhere"/>'),
        {},
        "hostile.urdf|a.urdf",
    ),
    "link_cycle": (
        "a.urdf",
        urdf(extra='<joint name="j2" type="revolute"><parent link="l1"/><child link="base"/>' + OK_JOINT + "</joint>"),
        {},
        "a.urdf",
    ),
    "duplicate_links": ("a.urdf", urdf(links=LINK.format("base") + LINK.format("l1") * 2), {}, "a.urdf"),
    "zero_axis": ("a.urdf", urdf('<axis xyz="0 0 0"/><limit lower="-1" upper="1" velocity="1"/>'), {}, "a.urdf"),
    "nan_axis": (
        "a.urdf",
        urdf('<axis xyz="nan 0 1"/><limit lower="-1" upper="1" velocity="1"/>'),
        {},
        "joint 'j1' has a NaN or infinite anchor, axis",
    ),
    "nan_origin": ("a.urdf", urdf('<origin xyz="nan 0 0"/>' + OK_JOINT), {}, "body 'l1' has a NaN or infinite"),
    "huge_origin": ("a.urdf", urdf('<origin xyz="1e400 0 0"/>' + OK_JOINT), {}, "a.urdf"),
    "limit_not_a_number": (
        "a.urdf",
        urdf('<axis xyz="0 0 1"/><limit lower="abc" upper="1" velocity="1"/>'),
        {},
        "joint 'j1': limit lower='abc' is not a number",
    ),
    "limit_nan": ("a.urdf", urdf('<axis xyz="0 0 1"/><limit lower="nan" upper="1" velocity="1"/>'), {}, "lower is NaN"),
    "velocity_negative": (
        "a.urdf",
        urdf('<axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="-1"/>'),
        {},
        "limit velocity -1.0",
    ),
    "package_dotdot": ("pkg/urdf/a.urdf", mesh_urdf("package://pkg/../secret.stl"), {}, "outside its root"),
    "absolute_mesh": ("a.urdf", mesh_urdf("/etc/passwd"), {}, "is an absolute path"),
    "relative_dotdot": ("deep/er/a.urdf", mesh_urdf("../../secret.stl"), {}, "outside its root"),
    "missing_mesh": ("a.urdf", mesh_urdf("nowhere.stl"), {}, "mesh 'nowhere.stl' not found"),
    "garbage_stl": ("a.urdf", mesh_urdf("garbage.stl"), {}, "a.urdf"),
    "broken_collada": ("a.urdf", mesh_urdf("broken.dae"), {}, "cannot read it as COLLADA"),
    "floating_joint": ("a.urdf", urdf().replace('type="revolute"', 'type="floating"'), {}, "free joint"),
    "mimic_unknown": (
        "a.urdf",
        urdf(OK_JOINT + '<mimic joint="ghost"/>'),
        {},
        "joint 'j1' mimics 'ghost', which is not a joint of the file",
    ),
    "mjcf_include_etc": ("a.xml", "<mujoco><include file='/etc/passwd'/></mujoco>", {}, "a.xml"),
    "mjcf_nan_ref": (
        "a.xml",
        MJCF.format(attrs="", body="<joint ref='nan'/>"),
        {},
        "NaN or infinite anchor, axis or ref",
    ),
    "mjcf_nan_range": (
        "a.xml",
        MJCF.format(attrs="", body="<joint limited='true' range='nan 1'/>"),
        {},
        "joint 'qpik_joint0': limit lower is NaN",
    ),
    "mjcf_locked": (
        "a.xml",
        MJCF.format(attrs="", body="<joint name='lk' limited='true' range='0.3 0.3'/>"),
        {},
        "'lk'",
    ),
    "mjcf_absolute_mesh": (
        "a.xml",
        "<mujoco><asset><mesh name='m' file='/etc/hostname.stl'/></asset><worldbody><body><joint/>"
        "<geom type='mesh' mesh='m'/></body></worldbody></mujoco>",
        {},
        "is an absolute path",
    ),
    "base_unknown": ("a.urdf", urdf(), {"base": "ghost"}, "base: no body or site 'ghost'"),
}
_FILES = {"garbage.stl": b"solid x\nthis is not an stl\n" * 3, "broken.dae": b"<COLLADA><library_geometries>"}


def write(folder: Path, key: str) -> Path:
    """The case's file (and the meshes it names) under ``folder``."""
    name, text, _, _ = CASES[key]
    path = folder / key / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    for mesh, data in _FILES.items():
        (path.parent / mesh).write_bytes(data)
    (folder / key / "secret.stl").write_bytes(b"secret")
    return path


@pytest.mark.parametrize("key", list(CASES))
def test_hostile_file_gives_one_qpik_error(tmp_path, key, monkeypatch):
    """... and writes nothing where it runs (MuJoCo's own warnings would append MUJOCO_LOG.TXT there)."""
    path = write(tmp_path, key)
    monkeypatch.chdir(tmp_path)
    before = set(tmp_path.rglob("*"))
    with pytest.raises(QpikError) as info:
        qpik.load_robot(path, **CASES[key][2])
    assert set(tmp_path.rglob("*")) == before
    assert isinstance(info.value, InputError)
    assert info.value.__cause__ is None and (info.value.__context__ is None or info.value.__suppress_context__)
    assert any(part in str(info.value) for part in CASES[key][3].split("|")), str(info.value)


def test_outside_meshes_load_with_the_flag(tmp_path):
    """The confinement is a default: ``allow_outside=True`` reads a mesh outside the package root."""
    import trimesh

    trimesh.creation.box((0.1, 0.1, 0.2)).export(tmp_path / "shared.stl")
    folder = tmp_path / "pkg" / "urdf"
    folder.mkdir(parents=True)
    (tmp_path / "pkg" / "package.xml").write_text("<package/>")
    for i, name in enumerate(("../../shared.stl", str(tmp_path / "shared.stl"))):
        path = folder / f"arm{i}.urdf"
        path.write_text(mesh_urdf(name))
        with pytest.raises(InputError, match="allow_outside=True"):
            qpik.load_robot(path)
        robot = qpik.load_robot(path, meshes=MeshOptions(allow_outside=True))
        assert robot.capsules[0].radius == pytest.approx(0.5 * float(np.linalg.norm((0.1, 0.1))), rel=0.05)
    (tmp_path / "pkg" / "meshes").mkdir()
    trimesh.creation.box((0.1, 0.1, 0.2)).export(tmp_path / "pkg" / "meshes" / "inside.stl")
    path = folder / "inside.urdf"
    path.write_text(mesh_urdf("../meshes/inside.stl"))  # up from urdf/ but inside the package: allowed
    assert qpik.load_robot(path).dof == 1
    (tmp_path / "pkg" / "meshes" / "linked.stl").symlink_to(tmp_path / "shared.stl")  # a --symlink-install tree
    path.write_text(mesh_urdf("package://pkg/meshes/linked.stl"))
    assert qpik.load_robot(path).dof == 1
