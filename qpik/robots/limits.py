"""The arm joints' position and velocity limits from a model file, checked, never silently rewritten.

A limit the file gives is used as given, or refused with an :class:`~qpik.core.errors.InputError` naming
the joint and the attribute:

- a position limit that is NaN or infinite, or ``lower > upper``;
- ``lower == upper``: the file locks the joint (leave it out of ``joints=`` to keep it at its
  reference, or name another ``base``/``tip``);
- a velocity limit that is NaN, infinite, zero or negative.

A limit the file does not give gets a documented default, said in ``robot.notes``:
:data:`CONTINUOUS_LIMIT` for the position (a URDF ``continuous`` joint says so, and gets it without
a note) and, without a URDF ``velocity`` or an MJCF velocity actuator, :data:`DEFAULT_VELOCITY`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from qpik.core.errors import InputError

if TYPE_CHECKING:
    import mujoco

    from qpik.robots.model_files import UrdfJoint

CONTINUOUS_LIMIT = 2.0 * np.pi
"""Limits ±this (rad, or m for a slide joint) of a joint that has none in the model (URDF ``continuous``)."""
DEFAULT_VELOCITY = 1.5
"""Velocity limit (rad/s, or m/s for a slide joint) of a joint whose model gives none."""


def arm_limits(
    model: mujoco.MjModel, arm: list[int], urdf: Mapping[str, UrdfJoint] | None, file: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """``(q_min, q_max, v_max, notes)`` of the arm joints ``arm`` (ids in ``model``), each (n,).

    ``urdf``: the file's joints (:func:`~qpik.robots.model_files.urdf_joints`) for a URDF, None for
    an MJCF (whose limits are the compiled ``range`` and velocity actuators). ``file``: named in errors.

    Raises:
        InputError: an invalid limit (see the module docstring), naming the joint and the attribute.
    """
    n = len(arm)
    q_min, q_max, v_max = np.empty(n), np.empty(n), np.empty(n)
    unlimited, no_velocity = [], []
    for i, j in enumerate(arm):
        name = model.joint(j).name
        info = None if urdf is None else urdf.get(name)
        if info is not None:
            lower, upper, velocity = info.lower, info.upper, info.velocity
            if info.kind == "continuous":
                lower = upper = None
            elif lower is None and upper is None:
                unlimited.append(name)
            else:  # the URDF default of a missing attribute is 0
                lower, upper = (0.0 if lower is None else lower), (0.0 if upper is None else upper)
        else:
            limited = bool(model.jnt_limited[j])
            lower, upper = (float(x) for x in model.jnt_range[j]) if limited else (None, None)
            if not limited:
                unlimited.append(name)
            velocity = _actuator_velocity(model, j)
        if lower is None:
            q_min[i], q_max[i] = -CONTINUOUS_LIMIT, CONTINUOUS_LIMIT
        else:
            q_min[i], q_max[i] = _position(file, name, lower, upper)
        if velocity is None:
            no_velocity.append(name)
            v_max[i] = DEFAULT_VELOCITY
        else:
            v_max[i] = _velocity(file, name, velocity)
    notes = []
    if unlimited:
        notes.append(f"no position limit in the file for {', '.join(unlimited)}: ±{CONTINUOUS_LIMIT:.4f} used")
    if no_velocity:
        notes.append(f"no velocity limit in the file for {', '.join(no_velocity)}: {DEFAULT_VELOCITY} used")
    return q_min, q_max, v_max, notes


def _position(file: str, joint: str, lower: float, upper: float) -> tuple[float, float]:
    for attr, x in (("lower", lower), ("upper", upper)):
        if math.isnan(x):
            raise InputError(f"{file}: joint {joint!r}: limit {attr} is NaN")
        if math.isinf(x):
            raise InputError(f"{file}: joint {joint!r}: limit {attr} is infinite (a finite limit is needed)")
    if lower > upper:
        raise InputError(f"{file}: joint {joint!r}: limit lower {lower!r} > upper {upper!r}")
    if lower == upper:
        raise InputError(
            f"{file}: joint {joint!r} is locked in the file (limit lower = upper = {lower!r}); leave it out of "
            "joints=... or choose base/tip around it"
        )
    return lower, upper


def _velocity(file: str, joint: str, v: float) -> float:
    if not math.isfinite(v) or v <= 0.0:
        raise InputError(f"{file}: joint {joint!r}: limit velocity {v!r} (must be finite and > 0)")
    return v


def _actuator_velocity(model: mujoco.MjModel, j: int) -> float | None:
    """The ``ctrlrange`` bound of a velocity actuator on joint ``j``, or None without one."""
    import mujoco

    out = None
    for a in range(model.nu):
        velocity = (
            model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
            and model.actuator_trnid[a, 0] == j
            and model.actuator_biasprm[a, 1] == 0.0
            and model.actuator_biasprm[a, 2] < 0.0
            and model.actuator_ctrllimited[a]
        )
        if velocity:
            out = float(np.abs(model.actuator_ctrlrange[a]).max())
    return out
