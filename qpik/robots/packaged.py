"""Robot model files shipped inside other PyPI packages (installed with ``pip install -e '.[test]'``).

Nothing is downloaded: :func:`packaged_model` finds a file in an installed package or says
which package to install. The files are other people's, with their licences in their packages:

========================  =======================  ================================================
key                       package                  file
========================  =======================  ================================================
``pybullet/iiwa``         pybullet                 ``pybullet_data/kuka_iiwa/model.urdf`` (iiwa 14)
``pybullet/panda``        pybullet                 ``pybullet_data/franka_panda/panda.urdf``
``erd/panda``             example-robot-data       ``robots/panda_description/urdf/panda.urdf``
``erd/xarm7``             example-robot-data       ``robots/xarm_description/urdf/xarm7.urdf``
``erd/talos``             example-robot-data       ``robots/talos_data/robots/talos_reduced.urdf``
``erd/tiago_pro``         example-robot-data       ``robots/tiago_pro_description/robots/tiago_pro.urdf``
``erd/tiago``             example-robot-data       ``robots/tiago_description/robots/tiago.urdf`` (COLLADA)
``erd/baxter``            example-robot-data       ``robots/baxter_description/urdf/baxter.urdf`` (COLLADA)
``erd/pr2``               example-robot-data       ``robots/pr2_description/urdf/pr2.urdf``
========================  =======================  ================================================
"""

from __future__ import annotations

import importlib.util
import sysconfig
from pathlib import Path

from qpik.core.errors import InputError

PACKAGED = {
    "pybullet/iiwa": ("pybullet", "kuka_iiwa/model.urdf"),
    "pybullet/panda": ("pybullet", "franka_panda/panda.urdf"),
    "erd/panda": ("example-robot-data", "panda_description/urdf/panda.urdf"),
    "erd/xarm7": ("example-robot-data", "xarm_description/urdf/xarm7.urdf"),
    "erd/talos": ("example-robot-data", "talos_data/robots/talos_reduced.urdf"),
    "erd/tiago_pro": ("example-robot-data", "tiago_pro_description/robots/tiago_pro.urdf"),
    "erd/tiago": ("example-robot-data", "tiago_description/robots/tiago.urdf"),
    "erd/baxter": ("example-robot-data", "baxter_description/urdf/baxter.urdf"),
    "erd/pr2": ("example-robot-data", "pr2_description/urdf/pr2.urdf"),
}


def package_folder(package: str) -> Path | None:
    """The folder of robot files of an installed ``package`` (``pybullet``, ``example-robot-data``), or None."""
    if package == "pybullet":
        spec = importlib.util.find_spec("pybullet_data")
        return Path(spec.origin).parent if spec and spec.origin else None
    if package == "example-robot-data":  # a data-only wheel (no Python module), under cmeel.prefix
        folder = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
        return folder if folder.is_dir() else None
    raise InputError(f"package: unknown package {package!r}")


def packaged_model(key: str) -> Path:
    """The model file of :data:`PACKAGED` ``key``.

    Raises:
        InputError: unknown key, or its package is not installed (the message names it).
    """
    if key not in PACKAGED:
        raise InputError(f"key: unknown packaged model {key!r}; known: {', '.join(PACKAGED)}")
    package, file = PACKAGED[key]
    folder = package_folder(package)
    if folder is None or not (folder / file).is_file():
        raise InputError(f"{key}: the package {package} is not installed (pip install {package}, or qpik[test])")
    return folder / file
