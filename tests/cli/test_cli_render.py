"""``qpik render`` through the CLI entry point."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from qpik.cli import main


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    rc = main(argv)
    out, err = capsys.readouterr()
    if "nothing drawn" in err:
        pytest.skip(err.strip())
    return rc, out, err


def test_home_pose_png(tmp_path, capsys) -> None:
    path = tmp_path / "pose.png"
    rc, out, _ = _run(["render", "--robot", "panda", "-o", str(path), "--size", "64,48"], capsys)
    assert rc == 0 and path.exists() and "panda" in out
    image = np.asarray(Image.open(path).convert("RGB"))
    assert image.shape == (48, 64, 3) and len(np.unique(image.reshape(-1, 3), axis=0)) > 5


def test_several_configurations_tile(tmp_path, capsys) -> None:
    path = tmp_path / "two.png"
    argv = ["render", "-r", "iiwa14", "--q", "0,0.5,0,-1.2,0,0.9,0", "--q", "0 0 0 0 0 0 0"]
    rc, out, _ = _run([*argv, "-o", str(path), "--size", "64,48"], capsys)
    assert rc == 0 and "2 configurations" in out
    assert Image.open(path).size == (128, 48)


def test_wrong_number_of_angles_is_an_error(tmp_path, capsys) -> None:
    rc = main(["render", "-r", "iiwa14", "--q", "0,0.5", "-o", str(tmp_path / "x.png")])
    err = capsys.readouterr().err
    assert rc == 2 and "--q: expected 7 angles, got 2" in err
    assert not (tmp_path / "x.png").exists()


def test_without_gl_it_fails_in_one_line_saying_why(tmp_path) -> None:
    """No GL library found (``ctypes.util.find_library`` answers None, as on a machine without them, and no display):
    nothing is written, exit code 2, one line naming what to install."""
    drop = ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    png = tmp_path / "z.png"
    argv = ["render", "-r", "zheng7", "-o", str(png)]
    code = (
        "import ctypes.util, sys\n"
        "ctypes.util.find_library = lambda name: None\n"
        f"from qpik.cli import main\nsys.exit(main({argv!r}))"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and not png.exists() and out.stdout == ""
    assert out.stderr.count("\n") == 1, out.stderr
    assert out.stderr.startswith("qpik render: nothing drawn, no OpenGL: offscreen rendering unavailable")
    assert "libosmesa6" in out.stderr and "EGL" in out.stderr
