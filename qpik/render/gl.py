"""The OpenGL backend MuJoCo renders with, chosen before ``mujoco`` is first imported.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is imported, and (from mujoco 4)
imports that backend with it: naming a backend whose library is missing makes
``import mujoco`` itself fail. So :func:`choose_backend` names one only where its
library can actually be loaded, and otherwise leaves ``MUJOCO_GL`` unset: then
``import mujoco`` works on any machine, and rendering alone reports that it cannot
start (:class:`qpik.render.pictures.RenderUnavailable`, one line).

``import qpik`` calls :func:`choose_backend` on a Linux machine without a display:

1. ``osmesa`` (software rendering, Debian ``libosmesa6``) if ``libOSMesa`` loads;
2. else ``egl`` (headless, Mesa or a GPU driver) if ``libEGL`` and ``libOpenGL``
   or ``libGL`` load;
3. else nothing.

A ``MUJOCO_GL`` set by the user, a display, another platform or a ``mujoco``
imported before qpik are left alone.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from collections.abc import Callable, Container, MutableMapping

BACKENDS: tuple[tuple[str, tuple[tuple[str, ...], ...]], ...] = (
    ("osmesa", (("OSMesa",),)),
    ("egl", (("EGL",), ("OpenGL", "GL"))),
)
"""In order of preference: a backend and the libraries it needs (each entry: any one of these names)."""


def library_loads(name: str) -> bool:
    """Whether the shared library ``name`` (as for ``ctypes.util.find_library``: "GL", "EGL") loads here."""
    path = ctypes.util.find_library(name)
    if path is None:
        return False
    try:
        ctypes.CDLL(path)
    except OSError:
        return False
    return True


def choose_backend(
    environ: MutableMapping[str, str] | None = None,
    *,
    platform: str = sys.platform,
    imported: Container[str] = sys.modules,
    loads: Callable[[str], bool] = library_loads,
) -> str | None:
    """Set ``MUJOCO_GL`` in ``environ`` (default ``os.environ``) to a backend that can start; return it.

    Returns None, and changes nothing, when ``MUJOCO_GL`` is already set, ``mujoco`` is in
    ``imported``, the platform is not Linux, a display is set (MuJoCo's default, glfw, then
    works) or no backend's libraries load (``loads(name)``).
    """
    env = os.environ if environ is None else environ
    if "MUJOCO_GL" in env or "mujoco" in imported or not platform.startswith("linux"):
        return None
    if env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return None
    for backend, needs in BACKENDS:
        if all(any(loads(name) for name in options) for options in needs):
            env["MUJOCO_GL"] = backend
            return backend
    return None
