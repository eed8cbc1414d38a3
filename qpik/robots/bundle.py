"""A robot as data, for a worker process or machine that shares no folder with the client: :class:`RobotBundle`.

A bundle holds either a catalog arm's name, or the pickled :class:`~qpik.robots.robot.Robot` (its chain,
limits, capsules: the numbers, not its compiled code) and, for an arm loaded from a model file, the bytes of the
model and of every mesh and texture it reads, with their layout relative to one common folder.

On a worker, :meth:`RobotBundle.robot` turns it back into a Robot. A model's files are written into a temporary
folder of the worker's own (never its working folder), which lives as long as the worker process and is
deleted when it ends. The robot is kept per process, keyed by the bundle's content hash (:attr:`RobotBundle.key`):
every task of one worker on the same arm uses the same Robot object, so the robot's CasADi functions, compiled
code and closed-form solver (cached per Robot object) are built once per worker process, not once per task; the
native libraries themselves are cached on disk per machine (:func:`qpik.native.compiled.cache_dir`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pickle
import tempfile
import threading
from pathlib import Path

from qpik.core.errors import InputError
from qpik.robots.catalog import CATALOG, catalog_robot
from qpik.robots.model_files import PACKAGE, resolve_mesh
from qpik.robots.model_source import ModelSource
from qpik.robots.robot import Robot, as_robot

_ROBOTS: dict[str, Robot] = {}
"""This process's robots by bundle key."""
_FOLDERS: list[tempfile.TemporaryDirectory] = []
"""The temporary folders of this process's model files (deleted when the process ends)."""
_LOCK = threading.Lock()


class RobotBundle:
    """A robot as picklable data (see the module docstring); build one with :meth:`of`.

    Attributes:
        name: the catalog name of a catalog arm as the catalog gives it, else "".
        data: the pickled Robot without its model source (b"" for a catalog arm).
        files: ``(relative path, bytes)`` of the model file and every file it reads (empty without a model).
        model: the model file's relative path in ``files`` ("" without one).
        packages: ``(package name, relative folder)`` of the model's ``package://`` paths.
        source: the model source's other fields: collision_only, joint names, tip body, site.
        key: SHA-256 of all of the above (hex).
    """

    def __init__(self, name: str, data: bytes, files: tuple[tuple[str, bytes], ...], model: str,
                 packages: tuple[tuple[str, str], ...], source: tuple, local: Robot | None = None) -> None:  # fmt: skip
        self.name, self.data, self.files, self.model, self.packages, self.source = (
            name, data, files, model, packages, source,
        )  # fmt: skip
        digest = hashlib.sha256(pickle.dumps((name, model, packages, source)) + data)
        for rel, blob in files:
            digest.update(rel.encode() + b"\0" + hashlib.sha256(blob).digest())
        self.key = digest.hexdigest()
        self._local = local  # the robot it was made from, in the process that made it (not pickled)

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "_local"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state, _local=None)

    @property
    def size(self) -> int:
        """Bytes of data the bundle carries (the pickled robot and its files)."""
        return len(self.data) + sum(len(b) for _, b in self.files)

    @classmethod
    def of(cls, robot: Robot) -> RobotBundle:
        """The bundle of ``robot``: read its model's files now (on the client).

        Raises:
            InputError: ``robot`` is not a Robot, or a file of its model cannot be read.
        """
        robot = as_robot(robot)
        if robot.name in CATALOG and robot.model is None and robot is catalog_robot(robot.name):
            return cls(robot.name, b"", (), "", (), (), local=robot)
        data = pickle.dumps(dataclasses.replace(robot, model=None), protocol=pickle.HIGHEST_PROTOCOL)
        files = _model_files(robot.model) if robot.model else ((), "", (), ())
        return cls("", data, *files, local=robot)

    def robot(self) -> Robot:
        """The Robot: in the process that made the bundle the robot itself, elsewhere the one this process keeps
        for :attr:`key` (made on first use)."""
        if self._local is not None:
            return self._local
        with _LOCK:
            robot = _ROBOTS.get(self.key)
            if robot is None:
                robot = _ROBOTS[self.key] = self._rebuild()
        return robot

    def _rebuild(self) -> Robot:
        if self.name:
            return catalog_robot(self.name)
        robot = pickle.loads(self.data)
        if not self.files:
            return robot
        folder = tempfile.TemporaryDirectory(prefix="qpik-robot-")
        _FOLDERS.append(folder)
        root = Path(folder.name)
        for rel, blob in self.files:
            path = root / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(blob)
        collision_only, joint_names, tip_body, site = self.source
        packages = {name: str(root / rel) for name, rel in self.packages}
        return dataclasses.replace(
            robot, model=ModelSource(root / self.model, packages, collision_only, joint_names, tip_body, site)
        )


def _model_files(source: ModelSource) -> tuple:
    """``(files, model, packages, source)`` of :class:`RobotBundle` for a model source: the model file, its meshes
    (as :meth:`ModelSource.spec` resolves them), its textures and height fields, relative to their common folder."""
    import mujoco

    path = Path(source.path)
    try:
        raw = mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise InputError(f"{path.name}: MuJoCo cannot read it ({' '.join(str(exc).split())})") from None
    meshdir = Path(raw.compiler.meshdir or "")
    kept = {m.name for m in source.spec().meshes}
    files = [path.resolve()]
    folders: dict[str, Path] = {}
    for mesh in raw.meshes:
        if mesh.name not in kept or not mesh.file:
            continue
        found = resolve_mesh(mesh.file, path, meshdir, source.package_map).resolve()
        files.append(found)
        if mesh.file.startswith(PACKAGE):
            name, _, rest = mesh.file[len(PACKAGE) :].partition("/")
            folders[name] = found.parents[len(Path(rest).parts) - 1]
    texturedir = Path(raw.compiler.texturedir or "")
    for item in (*raw.textures, *raw.hfields):
        if getattr(item, "file", ""):
            candidates = [path.parent / texturedir / item.file, path.parent / item.file]
            files += [next((c.resolve() for c in candidates if c.is_file()), candidates[0])]
    root = Path(os.path.commonpath([str(f.parent) for f in files] + [str(f.parent) for f in folders.values()]))
    out = []
    for f in dict.fromkeys(files):
        try:
            out.append((f.relative_to(root).as_posix(), f.read_bytes()))
        except OSError as exc:
            raise InputError(f"{path.name}: cannot read {f} ({exc.strerror})") from None
    packages = tuple((name, folder.relative_to(root).as_posix()) for name, folder in sorted(folders.items()))
    extra = (source.collision_only, tuple(source.joint_names), source.tip_body, source.site)
    return tuple(out), path.resolve().relative_to(root).as_posix(), packages, extra
