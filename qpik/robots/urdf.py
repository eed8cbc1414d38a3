r"""A URDF of an arm, written from its kinematics at q = 0 (for URDF-based peers such as TRAC-IK).

Only the joint axes and the end-effector pose at q = 0 are used, through :meth:`Robot.fk_jacobian`,
so any arm with FK and a geometric Jacobian gets one (no DH table is read). Column k of
:math:`J = [v; \omega]` at q = 0 gives joint k's unit axis :math:`\omega_k` (base frame) and,
since :math:`v_k = \omega_k \times (p_{ee} - o)` for every point o of the axis, the point
:math:`a_k = p_{ee} - v_k \times \omega_k` of the axis nearest the end-effector.

Link frames (base frame, at q = 0): link k's origin :math:`o_k` is the point of axis k nearest
:math:`o_{k-1}` (:math:`o_0` the base origin), its z axis is :math:`\omega_k`, and its rotation is
link k-1's turned by a rotation taking :math:`z_{k-1}` to :math:`\omega_k` (:func:`_align`; the base's
z for k = 1). Joint k (``revolute``, ``axis 0 0 1``) places link k in link k-1; a fixed joint
``ee_joint`` places the end-effector link ``ee``. Turning each link about its own z by
:math:`q_k` then gives the product of exponentials :math:`\prod_k e^{[\xi_k] q_k}\, T_{ee}(0)`:
the arm's FK. Root link: ``base`` (the frame of qpik's poses); tip: ``ee``. Limits are the
robot's (rad, rad/s); the inertia (1 kg, 0.01 kg m²) is a placeholder: the model is kinematic.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

import numpy as np

from qpik.core.errors import InputError

if TYPE_CHECKING:
    from qpik.robots.description import ArmDescription

BASE, TIP = "base", "ee"


def to_urdf(robot: ArmDescription) -> str:
    """The URDF of ``robot`` as an XML string: links ``base``, ``link1..linkn``, ``ee``; joints ``joint1..jointn``.

    Raises:
        InputError: the chain has mimic joints (a coupled column is no single joint axis).
    """
    if len(robot.chain.joints) != robot.dof:
        raise InputError(f"to_urdf: {robot.name} has mimic joints, which this writer does not cover")
    n = robot.dof
    T_ee, J = (x[0] for x in robot.fk_jacobian(np.zeros((1, n))))  # the batched path: nothing to compile
    frames = [np.eye(4)]
    for k in range(n):
        w = J[3:, k] / np.linalg.norm(J[3:, k])
        a = T_ee[:3, 3] - np.cross(J[:3, k], w)
        prev = frames[-1]
        F = np.eye(4)
        F[:3, :3] = _align(prev[:3, 2], w) @ prev[:3, :3]
        F[:3, 3] = a + w * (w @ (prev[:3, 3] - a))
        frames.append(F)
    lines = [
        f"<robot name={quoteattr(robot.name)}>",
        f'  <link name="{BASE}"/>',
    ]
    for k in range(1, n + 1):
        lines += [
            f'  <link name="link{k}">',
            "    <inertial>",
            '      <origin xyz="0 0 0" rpy="0 0 0"/>',
            '      <mass value="1"/>',
            '      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>',
            "    </inertial>",
            "  </link>",
            f'  <joint name="joint{k}" type="revolute">',
            f'    <parent link="{BASE if k == 1 else f"link{k - 1}"}"/>',
            f'    <child link="link{k}"/>',
            f"    {_origin(np.linalg.inv(frames[k - 1]) @ frames[k])}",
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{float(robot.q_min[k - 1])!r}" upper="{float(robot.q_max[k - 1])!r}" effort="0"'
            f' velocity="{float(robot.v_max[k - 1])!r}"/>',
            "  </joint>",
        ]
    lines += [
        f'  <link name="{TIP}"/>',
        '  <joint name="ee_joint" type="fixed">',
        f'    <parent link="link{n}"/>',
        f'    <child link="{TIP}"/>',
        f"    {_origin(np.linalg.inv(frames[n]) @ T_ee)}",
        "  </joint>",
        "</robot>",
        "",
    ]
    return "\n".join(lines)


def _align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) taking the unit vector ``a`` to the unit vector ``b``: the smallest one when a·b ≥ 0.

    Rodrigues with :math:`v = a \\times b`, :math:`c = a \\cdot b`: :math:`R = I + [v]_\\times + [v]_\\times^2/(1 + c)`,
    accurate for c ≥ 0. For c < 0 (where 1/(1 + c) would magnify round-off) a half turn
    :math:`2uu^T - I` about a unit u ⟂ a first takes a to −a, then Rodrigues from −a to b.
    """
    c = float(a @ b)
    if c < 0.0:
        u = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        u /= np.linalg.norm(u)
        return _align(-a, b) @ (2.0 * np.outer(u, u) - np.eye(3))
    v = np.cross(a, b)
    V = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + V + V @ V / (1.0 + c)


def _origin(T: np.ndarray) -> str:
    """``<origin xyz=".." rpy=".."/>`` of a homogeneous transform, full precision.

    URDF's rpy is :math:`R = R_z(y) R_y(p) R_x(r)`: :math:`p = \\mathrm{atan2}(-R_{20}, \\sqrt{R_{00}^2 + R_{10}^2})`,
    :math:`r = \\mathrm{atan2}(R_{21}, R_{22})`, :math:`y = \\mathrm{atan2}(R_{10}, R_{00})`; at
    :math:`p = \\pm\\pi/2` only :math:`r \\mp y` is defined: y = 0 and :math:`r = \\mathrm{atan2}(\\pm R_{01}, R_{11})`.
    """
    R = T[:3, :3]
    cp = math.hypot(R[0, 0], R[1, 0])
    pitch = math.atan2(-R[2, 0], cp)
    if cp > 1e-12:
        roll, yaw = math.atan2(R[2, 1], R[2, 2]), math.atan2(R[1, 0], R[0, 0])
    else:
        roll, yaw = math.atan2(math.copysign(1.0, -R[2, 0]) * R[0, 1], R[1, 1]), 0.0
    xyz = " ".join(repr(float(x)) for x in _clean(T[:3, 3]))
    rpy = " ".join(repr(float(x)) for x in _clean(np.array([roll, pitch, yaw])))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _clean(x: np.ndarray) -> np.ndarray:
    """Round-off (|x| < 1e-15) written as 0."""
    return np.where(np.abs(x) < 1e-15, 0.0, x)
