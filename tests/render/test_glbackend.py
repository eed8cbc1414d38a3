"""The GL backend is chosen only where its library loads; without one, ``import qpik, mujoco`` still works."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from qpik.render.gl import BACKENDS, choose_backend, library_loads

HEADLESS = {"PATH": "/usr/bin:/bin"}


def _loads(*present: str):
    return lambda name: name in present


@pytest.mark.parametrize(
    "present, expected",
    [
        (("OSMesa", "EGL", "GL"), "osmesa"),
        (("OSMesa",), "osmesa"),
        (("EGL", "OpenGL"), "egl"),
        (("EGL", "GL"), "egl"),
        (("EGL",), None),  # EGL without a GL library cannot render
        (("GL",), None),
        ((), None),
    ],
)
def test_backend_only_where_its_libraries_load(present: tuple[str, ...], expected: str | None) -> None:
    env = dict(HEADLESS)
    assert choose_backend(env, platform="linux", imported=(), loads=_loads(*present)) == expected
    assert env.get("MUJOCO_GL") == expected  # absent when nothing loads: mujoco's own default


@pytest.mark.parametrize(
    "env, platform, imported",
    [
        ({"MUJOCO_GL": "glfw"}, "linux", ()),  # the user's choice
        ({"DISPLAY": ":0"}, "linux", ()),  # a display: mujoco's default (glfw) works
        ({"WAYLAND_DISPLAY": "wayland-0"}, "linux", ()),
        ({}, "darwin", ()),
        ({}, "linux", ("mujoco",)),  # too late: mujoco has read MUJOCO_GL already
    ],
)
def test_left_alone(env: dict[str, str], platform: str, imported: tuple[str, ...]) -> None:
    before = dict(env)
    assert choose_backend(env, platform=platform, imported=imported, loads=_loads("OSMesa", "EGL", "GL")) is None
    assert env == before


def test_library_loads_is_false_for_a_missing_library() -> None:
    assert not library_loads("qpik-no-such-library")
    assert {name for _, needs in BACKENDS for options in needs for name in options} >= {"OSMesa", "EGL"}


# The whole no-GL path in a fresh interpreter: every GL library is made unfindable
# (ctypes.util.find_library answers None, as on a machine without them), so qpik sets
# no backend; mujoco then imports with its default, and rendering fails in one line.
_NO_GL = """
import ctypes.util
ctypes.util.find_library = lambda name: None
import os, io, contextlib
import qpik, mujoco
print("MUJOCO_GL", os.environ.get("MUJOCO_GL"))
from qpik.render.pictures import RenderUnavailable, Tiles, render_configurations
robot = qpik.load_robot("iiwa14")
try:
    render_configurations(robot, robot.q_home, tiles=Tiles(size=(32, 32)))
    print("RENDERED")
except RenderUnavailable as exc:
    print("UNAVAILABLE", exc)
from qpik.plots import save
from qpik.plots.closed_form import selfmotion_map
save(selfmotion_map(robot, robot.fk(robot.q_home), num=61), {png!r})
print("PLOT", os.path.getsize({png!r}) > 1000)
"""


def _headless_env() -> dict[str, str]:
    drop = ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM", "MPLBACKEND")
    return {k: v for k, v in os.environ.items() if k not in drop}


def test_without_any_gl_library_mujoco_imports_and_rendering_says_why(tmp_path) -> None:
    code = _NO_GL.format(png=str(tmp_path / "map.png"))
    out = subprocess.run([sys.executable, "-c", code], env=_headless_env(), capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert lines[0] == "MUJOCO_GL None"
    assert lines[1].startswith("UNAVAILABLE offscreen rendering unavailable")
    assert lines[2] == "PLOT True"


def test_with_a_gl_library_the_backend_renders() -> None:
    """Where a backend's library loads on this machine, qpik picks it and MuJoCo draws with it."""
    env = _headless_env()
    present = choose_backend(dict(env), platform=sys.platform, imported=())
    if present is None:
        pytest.skip("no OSMesa or EGL library on this machine")
    code = (
        "import os, qpik, mujoco\n"
        "from qpik.render.pictures import Tiles, render_configurations\n"
        "r = qpik.load_robot('iiwa14')\n"
        "img = render_configurations(r, r.q_home, tiles=Tiles(size=(32, 32)))\n"
        "print(os.environ['MUJOCO_GL'], img.std() > 1)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [present, "True"]


def test_maths_packages_import_no_plotting_or_rendering() -> None:
    code = (
        "import sys\n"
        "import qpik, qpik.analytic, qpik.control, qpik.geometry, qpik.robots\n"
        "print(sorted(m for m in ('matplotlib', 'qpik.render.pictures', 'qpik.plots') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], env=_headless_env(), capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_this_process_got_the_backend_qpik_would_choose() -> None:
    """The test process itself imported qpik before mujoco (conftest), so rendering tests use the backend
    qpik chooses where one loads, rather than being skipped."""
    env = _headless_env()
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        pytest.skip("a display: mujoco's default backend")
    expected = choose_backend(env, platform=sys.platform, imported=())
    if expected is None:
        pytest.skip("no OSMesa or EGL library on this machine")
    assert os.environ.get("MUJOCO_GL") == expected
