"""Reading MJCF and URDF files with MuJoCo: mesh paths, visual geoms and what MuJoCo does not keep.

- ``package://NAME/rest`` mesh paths (ROS packages) cannot be opened by MuJoCo (it rewrites
  them to ``package:/NAME/rest`` and fails when it compiles): :func:`resolve_meshes` turns
  each into an absolute path, from a user's package map or from the file's own folders
  (an ancestor folder called NAME, or an ancestor holding NAME/rest).
- ``collision_only``: geoms that cannot collide (``contype = conaffinity = 0``: visual
  geoms) are removed before compiling, with every mesh only they used, so that a model
  whose visual meshes are not shipped still loads. (MuJoCo drops a URDF's visual
  elements while parsing already.)
- COLLADA (``.dae``) meshes, which MuJoCo cannot decode, are converted to cached STL files
  (:mod:`qpik.robots.collada`).
- Mesh paths stay inside their root: a ``package://`` path inside its package's folder, any
  other inside the model's package (the nearest folder above the model holding a ``package.xml``,
  else the model's own folder); absolute paths and ``..`` steps out of it are refused unless
  ``MeshOptions(allow_outside=True)`` (symbolic links inside the package are followed).
- The XML is read without a document type: a file declaring entities (``<!DOCTYPE ... [<!ENTITY``,
  the "billion laughs") is refused before any parser expands them (:func:`parse_xml`).
- URDF ``<limit velocity=...>`` is not kept by MuJoCo, and it silently drops invalid limits:
  :func:`urdf_joints` reads the limits from the XML.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from qpik.core.errors import InputError
from qpik.robots.collada import as_stl, is_collada

if TYPE_CHECKING:
    import mujoco

PACKAGE = "package://"
MIN_MASS = 1e-9
"""Mass (kg) and inertia (kg m²) given to bodies with less (MuJoCo rejects massless moving bodies; qpik
uses the kinematics only)."""


@dataclass(frozen=True)
class MeshOptions:
    """How :func:`qpik.load_robot` reads a model file's meshes.

    Attributes:
        package_map: ``{package: folder}`` for ``package://`` mesh paths (None: found from the file's own folders).
        collision_only: leave out visual geoms and their meshes (for models shipped without them).
        allow_outside: read mesh files outside their package root (absolute paths, ``..`` out of it).
    """

    package_map: Mapping[str, str | os.PathLike] | None = None
    collision_only: bool = False
    allow_outside: bool = False


def is_urdf(path: Path) -> bool:
    """Whether ``path`` is a URDF file (by suffix, else by its root element)."""
    if path.suffix.lower() == ".urdf":
        return True
    if path.suffix.lower() == ".xml":
        return False
    try:
        return parse_xml(path).tag == "robot"
    except InputError:
        return False


def parse_xml(path: Path) -> ET.Element:
    """The root element of the XML file ``path``; a document type declaration (DTD, entities) is refused.

    Raises:
        InputError: unreadable, not well-formed XML, or declaring a document type.
    """
    from xml.parsers import expat

    def refuse(*_args) -> None:
        raise _DoctypeError

    scan = expat.ParserCreate()
    scan.StartDoctypeDeclHandler = refuse  # before any entity is declared or expanded
    scan.EntityDeclHandler = refuse
    try:
        data = path.read_bytes()
        scan.Parse(data, True)
        return ET.fromstring(data)
    except _DoctypeError:
        raise InputError(f"{path.name}: declares a document type (<!DOCTYPE>, entities); qpik refuses those") from None
    except (expat.ExpatError, ET.ParseError) as exc:
        raise InputError(f"{path.name}: not well-formed XML ({exc})") from None
    except (OSError, ValueError, RecursionError) as exc:
        raise InputError(f"{path.name}: cannot read it ({type(exc).__name__}: {exc})") from None


class _DoctypeError(Exception):
    """Raised inside the XML parser at a document type declaration."""


@contextmanager
def captured_warnings() -> Iterator[list[str]]:
    """MuJoCo's warnings inside the block, as a list of their texts, instead of MuJoCo's default (a line on stderr
    and ``MUJOCO_LOG.TXT`` appended in the current folder, which is not the user's to write to); the previous
    handler is restored after the block."""
    import mujoco

    previous = mujoco.get_mju_user_warning()
    said: list[str] = []
    mujoco.set_mju_user_warning(said.append)
    try:
        yield said
    finally:
        mujoco.set_mju_user_warning(previous)


def read_spec(
    path: Path,
    package_map: Mapping[str, str | os.PathLike] | None,
    collision_only: bool,
    allow_outside: bool = False,
    repaired: list[str] | None = None,
) -> mujoco.MjSpec:
    """The model at ``path`` as a MuJoCo spec with every mesh file resolved to an absolute path.

    Static bodies are kept (``fusestatic`` off), so every URDF link can be named as a base or tip,
    and geoms without contacts are kept (``discardvisual`` off) once parsed; massless links get
    :data:`MIN_MASS`; unnamed joints are named ``qpik_joint{k}`` (k: their place in the spec). COLLADA meshes are
    replaced by their cached STL conversion. Invalid inertias
    are replaced (:func:`repair_inertias`), their bodies' names appended to ``repaired``.

    Raises:
        InputError: the file is missing, declares a document type, or MuJoCo cannot parse it; a mesh
            file is not found, or lies outside its root (without ``allow_outside``).
    """
    import mujoco

    if not path.is_file():
        raise InputError(f"path: no such file {str(path)!r}")
    parse_xml(path)  # refuses entity declarations before MuJoCo's parser sees the file
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except (ValueError, RuntimeError) as exc:
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
        file = resolve_mesh(mesh.file, path, meshdir, package_map, allow_outside)
        mesh.file = str(as_stl(file) if is_collada(file) else file)
    taken = {j.name for j in spec.joints}
    for k, joint in enumerate(spec.joints):  # qpik refers to joints by name (MjKinematics, the twin's sim)
        if not joint.name:
            joint.name = next(
                n for n in (f"qpik_joint{k}", *(f"qpik_joint{k}_{i}" for i in range(99))) if n not in taken
            )
    names = repair_inertias(spec)
    if repaired is not None:
        repaired += names
    return spec


def repair_inertias(spec: mujoco.MjSpec) -> list[str]:
    """Replace every explicit inertial MuJoCo would refuse or keep as NaN by a valid one; the bodies changed.

    An inertia tensor needs positive principal moments A ≤ B ≤ C with A + B ≥ C (PR2's and TIAGo's
    files break these; a zero tensor is left to ``boundinertia``), a finite mass ≥ 0 and a finite
    centre of mass. qpik uses the kinematics only, so a bad tensor becomes the isotropic one of its
    largest principal moment (at least :data:`MIN_MASS`), a bad mass :data:`MIN_MASS`, a bad centre
    the body's origin.
    """
    import numpy as np

    out = []
    for body in spec.bodies:
        if not body.explicitinertial:
            continue
        bad = False
        if not math.isfinite(body.mass) or body.mass < 0:
            body.mass, bad = MIN_MASS, True
        if not (np.all(np.isfinite(body.ipos)) and np.all(np.isfinite(body.iquat)) and np.any(body.iquat != 0)):
            body.ipos, body.iquat, bad = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], True
        full = np.asarray(body.fullinertia, float)
        if math.isfinite(full[0]):  # (NaN in the first entry: no full tensor given)
            xx, yy, zz, xy, xz, yz = full
            moments = (
                np.linalg.eigvalsh([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) if np.all(np.isfinite(full)) else full
            )
            positive = bool(np.all(np.isfinite(moments)) and moments[0] > 0)
        else:
            moments = np.sort(np.asarray(body.inertia, float))
            positive = bool(np.all(np.isfinite(moments)) and (moments[0] >= 0 or np.all(moments == 0)))
        if not (positive and moments[0] + moments[1] >= moments[2]) and not np.all(moments == 0):
            finite = np.abs(moments[np.isfinite(moments)])
            big = max(float(finite.max()) if finite.size else 0.0, MIN_MASS)
            body.fullinertia = [math.nan] * 6
            body.inertia, body.iquat, bad = [big] * 3, [1.0, 0.0, 0.0, 0.0], True
        if bad:
            out.append(body.name)
    return out


def resolve_mesh(
    file: str,
    model: Path,
    meshdir: Path,
    package_map: Mapping[str, str | os.PathLike] | None = None,
    allow_outside: bool = False,
) -> Path:
    """The absolute path of a mesh ``file`` named in the model file ``model``.

    ``package://NAME/rest``: ``package_map[NAME]/rest``, else the first ancestor folder A of
    the model file with ``A.name == NAME`` and ``A/rest`` present, or with ``A/NAME/rest`` present;
    it must lie inside that package folder. Other names: relative to the model's folder and its
    ``meshdir``, as MuJoCo reads them; they must lie inside :func:`package_root` of the model.
    ``MeshOptions(allow_outside=True)`` lifts both confinements (and allows absolute paths).

    Raises:
        InputError: the file is not found (the message says where it was looked for), or it is
            outside its root.
    """
    folder = model.resolve().parent
    if file.startswith(PACKAGE):
        name, _, rest = file[len(PACKAGE) :].partition("/")
        candidates = [(Path(package_map[name]), rest)] if package_map and name in package_map else []
        for up in (folder, *folder.parents):
            candidates += [(up, rest)] if up.name == name else []
            candidates.append((up / name, rest))
    else:
        if os.path.isabs(file) and not allow_outside:
            raise InputError(
                f"{model.name}: mesh {file!r} is an absolute path;"
                " pass meshes=MeshOptions(allow_outside=True) to read it"
            )
        root = package_root(model)
        candidates = [
            (root, os.path.relpath(folder / meshdir / file, root)),
            (root, os.path.relpath(folder / file, root)),
        ]
    for root, rest in candidates:
        c = root / rest
        if c.is_file():
            if not allow_outside and not _lexically_inside(c, root):
                raise InputError(
                    f"{model.name}: mesh {file!r} lies outside its root {str(root)!r};"
                    " meshes=MeshOptions(allow_outside=True) reads it"
                )
            return c
    hint = f"; give meshes=MeshOptions(package_map={{{name!r}: folder}})" if file.startswith(PACKAGE) else ""
    first = candidates[0][0] / candidates[0][1]
    where = f" (looked in {first.parent}" + (f" and {len(candidates) - 1} more places" if len(candidates) > 1 else "")
    raise InputError(
        f"{model.name}: mesh {file!r} not found{where}){hint}; or load with meshes=MeshOptions(collision_only=True)"
    )


def _lexically_inside(path: Path, root: Path) -> bool:
    """Whether ``path`` names a place inside ``root`` once ``..`` steps are taken (symbolic links inside the
    package are the package's own, as in a ROS workspace built with ``--symlink-install``, and are followed)."""
    return Path(os.path.normpath(os.path.abspath(path))).is_relative_to(os.path.normpath(os.path.abspath(root)))


def package_root(model: Path) -> Path:
    """The folder a model's relative mesh paths must stay in: the nearest folder above the model file holding
    a ROS ``package.xml``, else the model's own folder."""
    folder = model.resolve().parent
    return next((up for up in (folder, *folder.parents) if (up / "package.xml").is_file()), folder)


@dataclass(frozen=True)
class UrdfJoint:
    """What a URDF says about one joint that MuJoCo does not keep (or drops when invalid).

    Attributes:
        name: the joint's name.
        kind: its ``type`` attribute (``revolute``, ``continuous``, ``prismatic``, ...).
        lower, upper, velocity: the ``<limit>`` attributes (rad, m, rad/s or m/s), None where absent;
            parsed as given (NaN, inf and signs kept, for :mod:`qpik.robots.limits` to judge).
        mimic: the joint a ``<mimic>`` element names (MuJoCo reads the coupling itself), else None.
    """

    name: str
    kind: str
    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None
    mimic: str | None = None


def urdf_joints(path: Path) -> dict[str, UrdfJoint]:
    """``{name: UrdfJoint}`` of every joint of the URDF at ``path``.

    Raises:
        InputError: an attribute that is not a number, naming the joint and the attribute.
    """
    out = {}
    for joint in parse_xml(path).findall("joint"):  # not the <transmission> elements' <joint>
        name = joint.get("name", "")

        def number(element: ET.Element | None, attr: str, default: float | None, name: str = name) -> float | None:
            text = None if element is None else element.get(attr)
            if text is None:
                return default
            try:
                return float(text)
            except ValueError:
                raise InputError(
                    f"{path.name}: joint {name!r}: {element.tag} {attr}={text!r} is not a number"
                ) from None

        limit, mimic = joint.find("limit"), joint.find("mimic")
        out[name] = UrdfJoint(
            name,
            joint.get("type", ""),
            number(limit, "lower", None),
            number(limit, "upper", None),
            number(limit, "velocity", None),
            None if mimic is None else mimic.get("joint", ""),
        )
    return out


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())
