"""Offscreen pictures of arm configurations, drawn by MuJoCo.

:func:`render_configurations` draws K configurations of a robot's MJCF twin
(or of any :class:`~qpik.robots.mujoco_backend.MjKinematics` arm) as a grid of
tiles, or overlaid in one tile, and writes one PNG.

OpenGL: MuJoCo picks its GL backend from ``MUJOCO_GL`` when ``mujoco`` is
first imported; ``import qpik`` names one only where its library loads
(:mod:`qpik.render.gl`). Where no GL context can be made (no OSMesa or EGL, or
glfw on a machine with no display), rendering raises :class:`RenderUnavailable`
with a one-line reason, before MuJoCo gets to abort the process;
:func:`unavailable_reason` tells in advance.
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from qpik.core.errors import InputError, RenderUnavailable
from qpik.core.validate import finite_array
from qpik.robots.mujoco_backend import MjKinematics
from qpik.robots.robot import Robot

GHOST_ALPHA = 0.3
_unavailable: str | None = None  # why GL failed in this process, once it has
_checked = False  # unavailable_reason() has tried a context


@dataclass(frozen=True)
class Camera:
    """A free camera (MuJoCo ``mjCAMERA_FREE``) around a look-at point.

    Attributes:
        azimuth: degrees about the world z axis (MuJoCo convention: the camera
            sits at ``lookat - distance·(cos el cos az, cos el sin az, sin el)``;
            135 puts it at +x, −y, in front of and to the right of an arm reaching along +x).
        elevation: degrees, negative looks down.
        distance: metres from ``lookat``; ``None`` fits every configuration in view.
        lookat: (3,) world point; ``None`` takes the centre of the configurations.
    """

    azimuth: float = 135.0
    elevation: float = -20.0
    distance: float | None = None
    lookat: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Tiles:
    """How :func:`render_configurations` lays out its picture (each checked by it,
    :class:`~qpik.core.errors.InputError` naming the field).

    Attributes:
        cols: tiles per row, ≥ 1 (None: ``ceil(sqrt(K))``).
        size: tile (width, height), pixels (whole, ≥ 16 each).
        camera: the view; None: one fixed view that fits all K configurations, so that tiles compare.
        overlay: draw all configurations in one tile: the first opaque, the others translucent.
        labels: one text per tile, drawn in its top-left corner (None: none).
    """

    cols: int | None = None
    size: tuple[int, int] = (480, 400)
    camera: Camera | None = None
    overlay: bool = False
    labels: Sequence[str] | None = None


def render_configurations(
    arm: Robot | MjKinematics,
    qs: np.ndarray,
    path: str | os.PathLike | None = None,
    *,
    tiles: Tiles | None = None,
    extra_worldbody: Sequence[str] = (),
) -> np.ndarray:
    """Draw configurations of an arm and (optionally) write them as one PNG.

    Args:
        arm: a :class:`Robot` (its MJCF twin is drawn) or an :class:`MjKinematics` arm.
        qs: joint vectors, (n,) or (K, n).
        path: PNG file to write, ``.png`` (parent folders are made); ``None`` writes nothing.
        tiles: columns, tile size, camera, overlay and labels (:class:`Tiles`; default its defaults).
        extra_worldbody: MJCF elements added to the twin's ``<worldbody>``
            (obstacles); only for a :class:`Robot`.

    An :class:`MjKinematics` arm's model gets its offscreen buffer
    (``vis.global_.offwidth/offheight``) enlarged in place if a tile needs it.

    Returns:
        The picture, (rows*height, cols*width, 3) uint8.

    Raises:
        RenderUnavailable: no OpenGL context can be made.
        InputError: bad ``qs``, ``size``, ``cols``, ``labels``, ``path`` (not ``.png``), or
            ``extra_worldbody`` with an MjKinematics arm.
    """
    tiles = Tiles() if tiles is None else tiles
    if not isinstance(tiles, Tiles):
        raise InputError(f"tiles: expected Tiles, got {type(tiles).__name__}")
    cols, size, camera, overlay, labels = tiles.cols, tiles.size, tiles.camera, tiles.overlay, tiles.labels
    if isinstance(arm, Robot):
        kin = MjKinematics.from_robot(arm, extra_worldbody)
    elif extra_worldbody:
        raise InputError("extra_worldbody: only a Robot's MJCF twin can take extra elements")
    else:
        kin = arm
    qs = finite_array(qs, "qs")
    qs = qs[None] if qs.ndim == 1 else qs
    if qs.ndim != 2 or qs.shape[1] != kin.dof or len(qs) == 0:
        raise InputError(f"qs: expected shape ({kin.dof},) or (K, {kin.dof}), got {qs.shape}")
    size = finite_array(size, "size", (2,))
    width, height = (int(s) for s in size)
    if width < 16 or height < 16 or np.any(size != np.round(size)):
        raise InputError(f"size: tiles must be whole pixels, at least 16x16, got {tuple(size.tolist())}")
    ntiles = 1 if overlay else len(qs)
    if labels is not None and len(labels) != ntiles:
        raise InputError(f"labels: expected {ntiles} texts, got {len(labels)}")
    if cols is not None and (isinstance(cols, bool) or not isinstance(cols, int | np.integer) or cols < 1):
        raise InputError(f"cols: expected an integer >= 1, got {cols!r}")
    if path is not None and Path(path).suffix.lower() != ".png":
        raise InputError(f"path: the picture is written as PNG, so the file name must end in .png, got {path}")
    cols = min(cols or int(np.ceil(np.sqrt(ntiles))), ntiles)
    rows = -(-ntiles // cols)

    model, data = kin.model, kin.data
    cam = _free_camera(kin, qs, camera or Camera(), width / height)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    image = np.full((rows * height, cols * width, 3), 255, np.uint8)
    with _renderer(model, height, width) as renderer:
        for t in range(ntiles):
            _pose(kin, qs[0] if overlay else qs[t])
            renderer.update_scene(data, cam)
            if overlay:
                _add_ghosts(kin, qs[1:], renderer.scene)
            r, c = divmod(t, cols)
            image[r * height : (r + 1) * height, c * width : (c + 1) * width] = renderer.render()
    if labels is not None:
        _draw_labels(image, labels, cols, (width, height))
    if path is not None:
        from PIL import Image

        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(image).save(path)
    return image


def unavailable_reason() -> str | None:
    """Why offscreen rendering cannot work in this process (one line), or None if it can.

    The first call tries to make a GL context for a one-geom model; the answer is
    kept (a failed GL start is never retried, see :func:`_renderer`).
    """
    global _checked
    if not _checked:
        model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size="0.1"/></worldbody></mujoco>')
        with contextlib.suppress(RenderUnavailable):
            _renderer(model, 16, 16).close()
        _checked = True
    return _unavailable


def _renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """A ``mujoco.Renderer``, or :class:`RenderUnavailable` with the reason on one line.

    A failed GL start is remembered: a second ``mjr_makeContext`` without a
    context aborts the process, so it is never tried again.
    """
    global _unavailable
    _unavailable = _unavailable or _gl_problem()
    if _unavailable is None:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # glfw warns before it fails
                return mujoco.Renderer(model, height, width)
        except (mujoco.FatalError, ImportError, RuntimeError, OSError, AttributeError) as exc:
            _unavailable = " ".join(str(exc).split()) or type(exc).__name__
    backend = os.environ.get("MUJOCO_GL", "unset")
    raise RenderUnavailable(
        f"offscreen rendering unavailable (MUJOCO_GL={backend}: {_unavailable}); install OSMesa (Debian: "
        "libosmesa6) or EGL (libegl1), or set MUJOCO_GL=osmesa or egl before mujoco is first imported"
    )


def _gl_problem() -> str | None:
    """Why the GL backend mujoco chose at import cannot work here, if that is known in advance."""
    context = getattr(mujoco, "GLContext", None)
    if context is None:
        return "mujoco has no GL backend"
    backend = getattr(context, "__module__", "").rsplit(".", 1)[-1]
    headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if backend == "glfw" and sys.platform.startswith("linux") and headless:
        return "mujoco chose glfw, which needs a display, and there is none"
    return None


def _pose(kin: MjKinematics, q: np.ndarray) -> None:
    kin.update(q)
    mujoco.mj_camlight(kin.model, kin.data)


def _add_ghosts(kin: MjKinematics, qs: np.ndarray, scene: mujoco.MjvScene) -> None:
    """Append the moving geoms of each configuration in ``qs`` to ``scene``, translucent."""
    option, perturb = mujoco.MjvOption(), mujoco.MjvPerturb()
    for q in qs:
        start = scene.ngeom
        _pose(kin, q)
        mujoco.mjv_addGeoms(kin.model, kin.data, option, perturb, mujoco.mjtCatBit.mjCAT_DYNAMIC, scene)
        for i in range(start, scene.ngeom):
            scene.geoms[i].rgba[3] = GHOST_ALPHA


def _free_camera(kin: MjKinematics, qs: np.ndarray, view: Camera, aspect: float) -> mujoco.MjvCamera:
    """A free camera; unset distance/look-at fit a sphere around every moving geom of every q."""
    model, data = kin.model, kin.data
    moving = np.flatnonzero(model.body_weldid[model.geom_bodyid] != 0)
    long = np.isin(model.geom_type[moving], (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER))
    half = np.where(long, model.geom_size[moving, 1], 0.0)[:, None]  # half-length along the geom's z
    pts = [np.zeros(3)]
    for q in qs:
        kin.update(q)
        z = data.geom_xmat[moving].reshape(-1, 3, 3)[:, :, 2]
        pts += [*data.site_xpos, *(data.geom_xpos[moving] + half * z), *(data.geom_xpos[moving] - half * z)]
    pad = float(model.geom_size[moving, 0].max()) if len(moving) else 0.05
    pts = np.array(pts)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0)) if view.lookat is None else np.asarray(view.lookat, float)
    radius = float(np.linalg.norm(pts - centre, axis=1).max()) + pad
    fovy = np.radians(model.vis.global_.fovy)
    half_fov = min(fovy / 2, np.arctan(np.tan(fovy / 2) * aspect))
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.azimuth, cam.elevation = view.azimuth, view.elevation
    cam.distance = view.distance if view.distance is not None else 1.05 * radius / np.sin(half_fov)
    cam.lookat[:] = centre
    return cam


def _draw_labels(image: np.ndarray, labels: Sequence[str], cols: int, size: tuple[int, int]) -> None:
    """Each tile's label in its top-left corner, in matplotlib's DejaVu Sans (Greek letters included) at a size that
    reads at the tile's scale (a twentieth of its height, at least 14 px), on a pale band."""
    from matplotlib import font_manager
    from PIL import Image, ImageDraw, ImageFont

    pic = Image.fromarray(image)
    draw = ImageDraw.Draw(pic)
    font = ImageFont.truetype(font_manager.findfont("DejaVu Sans"), max(14, size[1] // 20))
    for t, text in enumerate(labels):
        r, c = divmod(t, cols)
        at = (c * size[0] + 8, r * size[1] + 6)
        box = draw.textbbox(at, str(text), font=font)
        draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(245, 245, 245))
        draw.text(at, str(text), fill=(20, 20, 20), font=font)
    image[:] = np.asarray(pic)
