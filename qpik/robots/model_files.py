"""Reading MJCF and URDF files with MuJoCo: mesh paths, visual geoms and what MuJoCo does not keep.

- ``package://NAME/rest`` mesh paths (ROS packages) cannot be opened by MuJoCo (it rewrites
  them to ``package:/NAME/rest`` and fails when it compiles): :func:`resolve_meshes` turns
  each into an absolute path, from a user's package map or from the file's own folders
  (an ancestor folder called NAME, or an ancestor holding NAME/rest).
- ``collision_only``: geoms that cannot collide (``contype = conaffinity = 0``: visual
  geoms) are removed before compiling, with every mesh only they used, so that a model
  whose visual meshes are not shipped still loads. (MuJoCo drops a URDF's visual
  elements while parsing already.)
- URDF ``<limit velocity=...>`` is not kept by MuJoCo: :func:`urdf_velocity_limits` reads it
  from the XML.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from qpik.errors import InputError

if TYPE_CHECKING:
    import mujoco

PACKAGE = "package://"
MIN_MASS = 1e-9
"""Mass (kg) and inertia (kg m²) given to bodies with less (MuJoCo rejects massless moving bodies; qpik
uses the kinematics only)."""


def is_urdf(path: Path) -> bool:
    """Whether ``path`` is a URDF file (by suffix, else by its root element)."""
    if path.suffix.lower() == ".urdf":
        return True
    if path.suffix.lower() == ".xml":
        return False
    try:
        return ET.parse(path).getroot().tag == "robot"
    except (ET.ParseError, OSError):
        return False


def read_spec(path: Path, package_map: Mapping[str, str | os.PathLike] | None, collision_only: bool) -> mujoco.MjSpec:
    """The model at ``path`` as a MuJoCo spec with every mesh file resolved to an absolute path.

    Static bodies are kept (``fusestatic`` off), so every URDF link can be named as a base or tip,
    and geoms without contacts are kept (``discardvisual`` off) once parsed; massless links get
    :data:`MIN_MASS`.

    Raises:
        InputError: the file is missing or MuJoCo cannot parse it; a mesh file is not found.
    """
    import mujoco

    if not path.is_file():
        raise InputError(f"path: no such file {str(path)!r}")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise InputError(f"{path.name}: MuJoCo cannot read it ({_one_line(exc)})") from None
    spec.compiler.fusestatic = False
    spec.compiler.discardvisual = False  # (a URDF's visual elements are gone already; this keeps geoms added later)
    spec.compiler.boundmass = max(spec.compiler.boundmass, MIN_MASS)  # links without <inertial> still compile
    spec.compiler.boundinertia = max(spec.compiler.boundinertia, MIN_MASS)
    if collision_only:
        for geom in list(spec.geoms):
            if geom.contype == 0 and geom.conaffinity == 0:
                spec.delete(geom)
    used = {g.meshname for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH}
    meshdir = Path(spec.compiler.meshdir or "")
    for mesh in list(spec.meshes):
        if collision_only and mesh.name not in used:
            spec.delete(mesh)
            continue
        mesh.file = str(resolve_mesh(mesh.file, path, meshdir, package_map))
    return spec


def resolve_mesh(
    file: str, model: Path, meshdir: Path, package_map: Mapping[str, str | os.PathLike] | None = None
) -> Path:
    """The absolute path of a mesh ``file`` named in the model file ``model``.

    ``package://NAME/rest``: ``package_map[NAME]/rest``, else the first ancestor folder A of
    the model file with ``A.name == NAME`` and ``A/rest`` present, or with ``A/NAME/rest`` present.
    Other names: relative to the model's folder and its ``meshdir``, as MuJoCo reads them.

    Raises:
        InputError: the file is not found (the message says where it was looked for).
    """
    folder = model.resolve().parent
    if file.startswith(PACKAGE):
        name, _, rest = file[len(PACKAGE) :].partition("/")
        candidates = [Path(package_map[name]) / rest] if package_map and name in package_map else []
        for up in (folder, *folder.parents):
            candidates += [up / rest] if up.name == name else []
            candidates.append(up / name / rest)
    else:
        candidates = [Path(file)] if os.path.isabs(file) else [folder / meshdir / file, folder / file]
    for c in candidates:
        if c.is_file():
            return c
    hint = f"; give package_map={{{name!r}: folder}}" if file.startswith(PACKAGE) else ""
    where = f" (looked in {candidates[0].parent}" + (
        f" and {len(candidates) - 1} more places" if len(candidates) > 1 else ""
    )
    raise InputError(f"{model.name}: mesh {file!r} not found{where}){hint}; or load with collision_only=True")


def urdf_velocity_limits(path: Path) -> dict[str, float]:
    """``{joint name: velocity limit}`` of the URDF joints that give one (rad/s or m/s)."""
    out = {}
    for joint in ET.parse(path).getroot().iter("joint"):
        limit = joint.find("limit")
        if limit is not None and limit.get("velocity") is not None:
            try:
                out[joint.get("name", "")] = abs(float(limit.get("velocity")))
            except ValueError:
                raise InputError(
                    f"{path.name}: joint {joint.get('name')!r} has velocity {limit.get('velocity')!r}"
                ) from None
    return out


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())
