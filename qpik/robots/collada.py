"""COLLADA (``.dae``) meshes, which MuJoCo cannot read, converted to STL once and cached.

A ROS description package often ships its meshes as COLLADA. :func:`as_stl` reads one with
trimesh (through pycollada), applies every node's transform and the file's ``<unit meter=...>``
scale (so the STL is in metres, as ROS tools such as RViz and assimp read it), and writes a
binary STL under ``cache_dir()/meshes``, named by the SHA-256 of the COLLADA file's bytes (and
of :data:`VERSION`): an unchanged file is converted once per cache, a changed one again.
"""

from __future__ import annotations

import hashlib
import io
import os
from pathlib import Path

from qpik.core.errors import InputError

SUFFIXES = (".dae",)
"""Mesh file suffixes (any case) converted by :func:`as_stl`."""
VERSION = b"qpik-collada-1"
"""Part of the cache key: a new conversion rule gets new file names."""


def is_collada(path: str | os.PathLike) -> bool:
    """Whether a mesh file is COLLADA (by its suffix, any case)."""
    return Path(path).suffix.lower() in SUFFIXES


def as_stl(path: Path) -> Path:
    """The cached binary STL (metres) of the COLLADA file ``path``, converted on the first call.

    Raises:
        InputError: the file cannot be read as COLLADA or holds no triangles, or the cache cannot be written.
    """
    from qpik.native.build import cache_dir, keep

    data = path.read_bytes()
    key = hashlib.sha256(VERSION + data).hexdigest()[:40]
    out = cache_dir() / "meshes" / f"{key}.stl"
    if out.is_file():
        return out
    mesh = _triangles(data, path.name)
    try:
        keep(out, mesh.export(file_type="stl"))
    except OSError as exc:
        where = f"cannot write its conversion to {out.parent} ({exc}); set QPIK_CACHE"
        raise InputError(f"mesh {path.name!r}: {where}") from None
    return out


def _triangles(data: bytes, name: str):
    """The file's triangles in one trimesh.Trimesh, in metres."""
    import collada
    import trimesh

    try:
        doc = collada.Collada(
            io.BytesIO(data), ignore=[collada.common.DaeUnsupportedError, collada.common.DaeBrokenRefError]
        )
        scene = trimesh.load(io.BytesIO(data), file_type="dae", force="scene")
        mesh = scene.to_mesh() if hasattr(scene, "to_mesh") else scene.dump(concatenate=True)
    except Exception as exc:  # trimesh and pycollada raise many types on a bad file
        raise InputError(f"mesh {name!r}: cannot read it as COLLADA ({type(exc).__name__}: {exc})") from None
    if mesh is None or len(getattr(mesh, "faces", ())) == 0:
        raise InputError(f"mesh {name!r}: the COLLADA file holds no triangles")
    unit = doc.assetInfo.unitmeter if doc.assetInfo is not None else None
    if unit is not None and unit > 0 and unit != 1.0:
        mesh.apply_scale(float(unit))
    return mesh
