r"""Named end-effector paths for ``[target] path = "..."`` in problem files.

A path is a time-parametrised target (:class:`qpik.geometry.paths.TargetPath`): ``pose(t)`` (4, 4) and the
feed-forward ``twist(t)`` ``[v; ω]`` (6,), both in the base frame,
for ``0 <= t <= duration`` (s). Both accept a scalar ``t`` or an array ``t``
(K,), which gives (K, 4, 4) and (K, 6).

A path formula is registered by name with :func:`path_formula`; its builder
receives the robot and the ``[target.path_params]`` table and returns a
:class:`TargetPath`. Unknown or missing parameters raise ``KeyError``/
``ValueError`` subclasses that the loader reports with the file name.

Registered formulas (``wipe``: see :func:`wipe`):

- ``zheng2019`` — Zheng et al. 2019, eq. (19), from the initial configuration ``q0``
  (default the paper's ``(0, 1.0472, -0.5236, -2.0944, 0, 1.5708, -1.5708)``)
  with initial pose :math:`(R_0, p_0) = \mathrm{fk}(q_0)` and constant
  orientation :math:`R_0`. Read literally, eq. (19) is
  :math:`p(t) = p_0 + (0.4\cos 0.5t,\; 0.4\sin t,\; 0.2 e^{-0.2t})`, which
  starts 0.45 m away from :math:`p_0` (``reading = "literal"``). The
  ``"relative"`` reading subtracts the value at t = 0 so that the path starts
  at the initial pose:
  :math:`p(t) = p_0 + (0.4(\cos 0.5t - 1),\; 0.4\sin t,\; 0.2(e^{-0.2t} - 1))`.
  Both have the velocity :math:`\dot p = (-0.2\sin 0.5t,\; 0.4\cos t,\; -0.04 e^{-0.2t})`
  and ω = 0. Parameters: ``reading`` (required: ``"relative"`` or
  ``"literal"``), ``duration`` (s, default 20), ``q0`` (7 floats, optional).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import finite_array
from qpik.geometry.paths import TargetPath
from qpik.robots.robot import Robot

PathBuilder = Callable[[Robot, dict[str, Any]], TargetPath]
PATHS: dict[str, PathBuilder] = {}


def path_formula(name: str) -> Callable[[PathBuilder], PathBuilder]:
    """Decorator: register ``builder(robot, params) -> TargetPath`` under ``name``."""

    def register(builder: PathBuilder) -> PathBuilder:
        PATHS[name] = builder
        return builder

    return register


ZHENG2019_Q0 = (0.0, 1.0472, -0.5236, -2.0944, 0.0, 1.5708, -1.5708)


@path_formula("zheng2019")
def zheng2019(robot: Robot, params: dict[str, Any]) -> TargetPath:
    """Zheng et al. 2019, eq. (19); see the module docstring for the two readings."""
    unknown = set(params) - {"reading", "duration", "q0"}
    if unknown:
        raise InputError(f"unknown parameter(s) {', '.join(sorted(unknown))}; known: reading, duration, q0")
    reading = params.get("reading")
    if reading not in ("relative", "literal"):
        raise InputError(f"reading must be 'relative' or 'literal', got {reading!r}")
    duration = float(params.get("duration", 20.0))
    if not duration > 0:
        raise InputError(f"duration must be > 0 s, got {duration}")
    q0 = finite_array(params.get("q0", ZHENG2019_Q0), "q0", (robot.dof,))
    T0 = robot.fk(q0)

    def wave(t: np.ndarray) -> np.ndarray:
        return np.stack([0.4 * np.cos(0.5 * t), 0.4 * np.sin(t), 0.2 * np.exp(-0.2 * t)], axis=-1)

    def velocity(t: np.ndarray) -> np.ndarray:
        return np.stack([-0.2 * np.sin(0.5 * t), 0.4 * np.cos(t), -0.04 * np.exp(-0.2 * t)], axis=-1)

    # literal: p0 + wave(t); relative: the same curve moved so that it starts at p0
    origin = T0[:3, 3] - (wave(np.zeros(1))[0] if reading == "relative" else 0.0)
    return TargetPath("zheng2019", duration, q0, T0[:3, :3].copy(), lambda t: origin + wave(t), velocity)


@path_formula("wipe")
def wipe(robot: Robot, params: dict[str, Any]) -> TargetPath:
    r"""A wiping motion over a table: the tool pointing straight down (its z axis along −z of the base),
    sweeping sideways while it advances.

    :math:`p(t) = c + (a \sin(2\pi k t / T),\ -\ell/2 + \ell t / T,\ 0)` for :math:`0 \le t \le T`, with
    the centre ``center`` c (3 floats, m), the sideways amplitude ``amplitude`` a (m), ``length`` ℓ (m) along y,
    ``strokes`` k (back-and-forth sweeps) and ``duration`` T (s). The rotation is diag(1, −1, −1).
    """
    known = {"center", "amplitude", "length", "strokes", "duration"}
    unknown = set(params) - known
    if unknown:
        raise InputError(f"unknown parameter(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(known))}")
    missing = known - set(params)
    if missing:
        raise InputError(f"missing parameter(s) {', '.join(sorted(missing))}")
    c = finite_array(params["center"], "center", (3,)).copy()
    a, length, k, T = (float(finite_array(params[x], x, ())) for x in ("amplitude", "length", "strokes", "duration"))
    if not T > 0:
        raise InputError(f"duration must be > 0 s, got {T}")
    if not k > 0:
        raise InputError(f"strokes must be > 0, got {k:g}")
    w = 2.0 * np.pi * k / T

    def position(t: np.ndarray) -> np.ndarray:
        return c + np.stack([a * np.sin(w * t), -0.5 * length + length * t / T, 0.0 * t], axis=-1)

    def velocity(t: np.ndarray) -> np.ndarray:
        return np.stack([a * w * np.cos(w * t), np.full_like(t, length / T), 0.0 * t], axis=-1)

    return TargetPath("wipe", T, None, np.diag([1.0, -1.0, -1.0]), position, velocity)
