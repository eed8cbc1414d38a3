"""Offscreen rendering: pictures that are not blank, grids, overlays, and the no-GL path."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from qpik.core.errors import InputError
from qpik.render.pictures import RenderUnavailable, Tiles, render_configurations
from qpik.robots.loader import load_robot
from qpik.robots.mujoco_backend import MjKinematics

SIZE = (96, 80)
IIWA = load_robot("iiwa14")


def _render(*args, **kwargs) -> np.ndarray:
    try:
        return render_configurations(*args, **kwargs)
    except RenderUnavailable as exc:
        pytest.skip(str(exc))


def test_png_is_written_and_not_blank(tmp_path) -> None:
    path = tmp_path / "sub" / "home.png"
    image = _render(IIWA, IIWA.q_home, path, tiles=Tiles(size=SIZE))
    assert image.shape == (SIZE[1], SIZE[0], 3) and image.dtype == np.uint8
    on_disk = np.asarray(Image.open(path).convert("RGB"))
    np.testing.assert_array_equal(on_disk, image)
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 10


def test_grid_of_tiles_one_pose_per_tile() -> None:
    qs = np.stack([IIWA.q_home, np.zeros(7), -IIWA.q_home])
    image = _render(IIWA, qs, tiles=Tiles(cols=2, size=SIZE))
    w, h = SIZE
    assert image.shape == (2 * h, 2 * w, 3)
    tiles = [image[:h, :w], image[:h, w:], image[h:, :w]]
    assert not np.array_equal(tiles[0], tiles[1]) and not np.array_equal(tiles[1], tiles[2])
    assert np.all(image[h:, w:] == 255)  # the empty fourth tile stays white
    # a tile is the same picture as that configuration drawn alone with the same camera fit
    alone = _render(IIWA, qs[[1, 0, 2]], tiles=Tiles(cols=3, size=SIZE))[:, :w]
    np.testing.assert_array_equal(alone, tiles[1])


def test_overlay_adds_ghosts_and_obstacles_show() -> None:
    single = _render(IIWA, IIWA.q_home[None], tiles=Tiles(size=SIZE))
    both = _render(IIWA, np.stack([IIWA.q_home, np.zeros(7)]), tiles=Tiles(size=SIZE, overlay=True))
    assert both.shape == single.shape and not np.array_equal(both, single)
    ball = '<geom name="ball" type="sphere" size="0.15" pos="0.4 -0.4 0.5" rgba="1 0 0 1"/>'
    with_ball = _render(IIWA, IIWA.q_home, extra_worldbody=[ball], tiles=Tiles(size=SIZE))
    red = (with_ball[..., 0] > 150) & (with_ball[..., 1] < 60) & (with_ball[..., 2] < 60)
    assert red.sum() > 20


def test_any_mjcf_arm_renders() -> None:
    image = _render(MjKinematics.from_robot(load_robot("panda")), load_robot("panda").q_home, tiles=Tiles(size=SIZE))
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 10


def test_bad_inputs() -> None:
    with pytest.raises(InputError, match="qs"):
        render_configurations(IIWA, np.zeros(6))
    with pytest.raises(InputError, match="labels"):
        render_configurations(IIWA, np.zeros((2, 7)), tiles=Tiles(labels=["one"]))
    with pytest.raises(InputError, match="extra_worldbody"):
        render_configurations(MjKinematics.from_robot(IIWA), np.zeros(7), extra_worldbody=["<geom size='1'/>"])


def test_no_gl_raises_render_unavailable_with_one_line() -> None:
    """With a GL backend that cannot start (glfw, no display) rendering says why in one line."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MUJOCO_GL"] = "glfw"
    code = (
        "import qpik\n"
        "from qpik.render.pictures import RenderUnavailable, Tiles, render_configurations\n"
        "r = qpik.load_robot('iiwa14')\n"
        "try:\n"
        "    render_configurations(r, r.q_home, tiles=Tiles(size=(32, 32)))\n"
        "    print('RENDERED')\n"
        "except RenderUnavailable as exc:\n"
        "    print('UNAVAILABLE', exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    if out.stdout.startswith("RENDERED"):
        pytest.skip("glfw works here without a display")
    lines = out.stdout.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("UNAVAILABLE offscreen rendering unavailable (MUJOCO_GL=glfw")
