r"""The MJCF twin of a chain robot: the same kinematics as a MuJoCo model.

Body ``link{k}`` turns with joint ``joint{k}`` (a hinge about its local z axis, or a
slide along it for a prismatic joint). At ``q = 0`` the body frames are taken from
:meth:`SerialChain.frames`, so the chain algebra lives in one place: body *k* is the
joint frame :math:`F_{k-1} P_k M_k(o_k)` (:class:`~qpik.robots.joint.Joint`), and link
frame *k* sits at the constant :math:`S_k` in it. For a standard DH table that is
:math:`F_{k-1} R_z(\theta_k + o_k)` with DH frame *k* at :math:`T_z(d_k) T_x(a_k) R_x(\alpha_k)`.

Every constant transform is written as ``pos``/``quat`` with full float
precision, so the site ``ee`` equals :meth:`Robot.fk` to ~1e-15 m.

Geoms: each :class:`LinkCapsule` is a capsule ``link{k}_capsule`` (or
``link{k}_capsule{j}`` when a link has several; a sphere for a zero-length
segment) in group 0 — the collision geometry; its frame is at the segment
midpoint with z from ``p0`` to ``p1``, so the end points are
``geom_xpos ∓ size[1] · z``. Everything else (floor, pedestal
``base``, ``base_column``, joint housings) is visual: group 2, ``contype=0 conaffinity=0``.
Inertia is a placeholder (1 kg, 0.01 kg m² at the body origin): the twin is a
kinematic model, not a dynamic one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np

from qpik.core.errors import InputError

if TYPE_CHECKING:
    from qpik.robots.description import ArmDescription
    from qpik.robots.joint import Joint

# one colour per link (RGB), cycled
PALETTE = (
    (0.90, 0.49, 0.13),
    (0.20, 0.47, 0.75),
    (0.85, 0.33, 0.31),
    (0.36, 0.72, 0.36),
    (0.58, 0.40, 0.74),
    (0.93, 0.75, 0.20),
    (0.30, 0.70, 0.80),
)
VISUAL = 'group="2" contype="0" conaffinity="0"'


def to_mjcf(robot: ArmDescription, extra_worldbody: Sequence[str] = ()) -> str:
    """The MJCF twin of ``robot`` as an XML string.

    Args:
        robot: a robot (its chain and capsules).
        extra_worldbody: MJCF elements (strings) inserted into ``<worldbody>``,
            for example obstacle geoms.

    Returns:
        MJCF text with bodies ``link1..linkn``, hinges ``joint1..jointn``
        (``range`` = the robot's limits), capsule geoms ``link{k}_capsule`` and
        the end-effector site ``ee``.

    Raises:
        InputError: the chain has mimic joints (a loaded arm with them uses its own model instead).
    """
    chain = robot.chain
    if len(chain.joints) != robot.dof:
        raise InputError(f"to_mjcf: {robot.name} has mimic joints, which the twin does not cover")
    n = chain.dof
    F = chain.frames(np.zeros(n))  # [base, frame_1..frame_n, ee] at q = 0
    body = [F[k - 1] @ j.pre @ _motion(j) for k, j in enumerate(chain.joints, start=1)]
    reach = sum(np.linalg.norm(F[k + 1, :3, 3] - F[k, :3, 3]) for k in range(n + 1))
    radii = {c.link: c.radius for c in robot.capsules}
    r_base = 1.2 * radii.get(1, 0.05)

    lines = [
        f"<mujoco model={quoteattr(robot.name)}>",
        '  <compiler angle="radian" autolimits="true"/>',
        '  <option gravity="0 0 0"/>',
        "  <visual>",
        '    <global offwidth="1920" offheight="1920"/>',
        '    <headlight ambient="0.35 0.35 0.35" diffuse="0.5 0.5 0.5" specular="0.1 0.1 0.1"/>',
        '    <rgba haze="0.9 0.92 0.95 1"/>',
        "  </visual>",
        "  <asset>",
        '    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.95 0.96 0.98" rgb2="0.75 0.8 0.88"'
        ' width="256" height="256"/>',
        '    <texture name="grid" type="2d" builtin="checker" rgb1="0.82 0.83 0.85" rgb2="0.74 0.75 0.78"'
        ' width="256" height="256"/>',
        '    <material name="grid" texture="grid" texrepeat="8 8"/>',
        "  </asset>",
        "  <worldbody>",
        f'    <light name="key" pos="{_fmt((reach, -reach, 2.5 * reach))}" dir="{_fmt((-1, 1, -2.5))}"'
        ' directional="true" diffuse="0.6 0.6 0.6"/>',
        f'    <geom name="floor" type="plane" size="{_fmt((2 * reach, 2 * reach, 0.05))}" material="grid" {VISUAL}/>',
        f'    <geom name="base" type="cylinder" {_pose(chain.base @ _trans_z(0.015))}'
        f' size="{_fmt((r_base, 0.015))}" rgba="0.25 0.25 0.28 1" {VISUAL}/>',
    ]
    # the static part between the base and the first joint's axis
    column = body[0][:3, 3]
    if np.linalg.norm(column - F[0, :3, 3]) > 1e-9:
        lines.append(
            f'    <geom name="base_column" type="cylinder" fromto="{_fmt((*F[0, :3, 3], *column))}"'
            f' size="{_fmt((0.9 * r_base,))}" rgba="0.35 0.35 0.38 1" {VISUAL}/>'
        )
    parent = np.eye(4)
    for k in range(1, n + 1):
        ind = "    " + "  " * (k - 1)
        rgb = PALETTE[(k - 1) % len(PALETTE)]
        rgba = _fmt((*rgb, 1.0))
        lines.append(f'{ind}<body name="link{k}" {_pose(np.linalg.inv(parent) @ body[k - 1])}>')
        lines.append(f'{ind}  <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>')
        kind = "slide" if chain.joints[k - 1].kind == "prismatic" else "hinge"
        lines.append(
            f'{ind}  <joint name="joint{k}" type="{kind}" axis="0 0 1" limited="true"'
            f' range="{_fmt((robot.q_min[k - 1], robot.q_max[k - 1]))}"/>'
        )
        r = radii.get(k, 0.04)
        dark = _fmt((*(0.6 * c for c in rgb), 1.0))
        lines.append(
            f'{ind}  <geom name="link{k}_housing" type="cylinder" size="{_fmt((1.1 * r, 0.9 * r))}"'
            f' rgba="{dark}" {VISUAL}/>'
        )
        to_frame = chain.joints[k - 1].post  # link frame k in body k
        caps = [c for c in robot.capsules if c.link == k]
        for j, c in enumerate(caps):
            name = f"link{k}_capsule" + (str(j) if len(caps) > 1 else "")
            p0, p1 = (to_frame[:3, :3] @ p + to_frame[:3, 3] for p in (c.p0, c.p1))
            if np.linalg.norm(p1 - p0) < 1e-12:
                shape = f'type="sphere" pos="{_fmt(p0)}" size="{_fmt((c.radius,))}"'
            else:
                shape = f'type="capsule" {_segment(p0, p1)} size="{_fmt((c.radius, np.linalg.norm(p1 - p0) / 2))}"'
            lines.append(f'{ind}  <geom name="{name}" {shape} rgba="{rgba}" group="0"/>')
        parent = body[k - 1]
    ee = np.linalg.inv(body[-1]) @ F[-1]
    ind = "    " + "  " * n
    lines.append(f'{ind}<site name="ee" {_pose(ee)} size="0.015" rgba="0.9 0.1 0.1 1"/>')
    for k in range(n, 0, -1):
        lines.append("    " + "  " * (k - 1) + "</body>")
    lines += ["    " + e for e in extra_worldbody]
    lines += ["  </worldbody>", "</mujoco>", ""]
    return "\n".join(lines)


def _motion(joint: Joint) -> np.ndarray:
    """The joint's motion at q = 0 (its offset): R_z(o) or T_z(o), (4, 4)."""
    T = np.eye(4)
    if joint.kind == "prismatic":
        T[2, 3] = joint.offset
    else:
        c, s = np.cos(joint.offset), np.sin(joint.offset)
        T[:2, :2] = ((c, -s), (s, c))
    return T


def _trans_z(z: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = z
    return T


def _pose(T: np.ndarray) -> str:
    """``pos="..." quat="..."`` (w, x, y, z) of a homogeneous transform, full precision."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T[:3, :3]).ravel())
    return f'pos="{_fmt(T[:3, 3])}" quat="{_fmt(quat)}"'


def _segment(p0: np.ndarray, p1: np.ndarray) -> str:
    """``pos``/``quat`` of a frame at the midpoint with z from ``p0`` to ``p1``.

    (MJCF's ``fromto`` would point z from ``to`` to ``from``.)
    """
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, p1 - p0)
    return f'pos="{_fmt((p0 + p1) / 2)}" quat="{_fmt(quat)}"'


def _fmt(values: Sequence[float] | np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in values)
