r"""Denavit–Hartenberg tables as serial chains.

A :class:`DHChain` is a :class:`~qpik.robots.chain.SerialChain` built from a DH table in
either convention, keeping the table (the closed-form solvers read it):

- ``standard``: :math:`A_i = R_z(\theta_i + o_i)\,T_z(d_i)\,T_x(a_i)\,R_x(\alpha_i)`
  (Nammoto & Kosuge 2012, eq. 1); joint *i* turns about the z axis of frame *i-1*:
  ``pre = I``, ``post`` = :math:`T_z(d_i) T_x(a_i) R_x(\alpha_i)`.
- ``modified`` (Craig): :math:`A_i = R_x(\alpha_{i-1})\,T_x(a_{i-1})\,R_z(\theta_i + o_i)\,T_z(d_i)`;
  joint *i* turns about the z axis of frame *i*: ``pre`` = :math:`R_x(\alpha_{i-1}) T_x(a_{i-1})`,
  ``post`` = :math:`T_z(d_i)`.

Frame *i* of the chain is DH frame *i*; frame 0 is ``base`` (a constant transform from the
world), the end-effector is ``frame_n @ tool``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.core.errors import InputError
from qpik.core.validate import bounded, finite_array
from qpik.robots.chain import SerialChain
from qpik.robots.joint import Joint

Convention = Literal["standard", "modified"]


@dataclass(frozen=True)
class DHChain(SerialChain):
    r"""A revolute serial chain described by a DH table.

    Attributes:
        a, d, alpha, offset: DH parameters per joint (m, m, rad, rad), shape (n,).
            In the ``modified`` convention ``a[i]`` and ``alpha[i]`` are Craig's
            :math:`a_{i-1}`, :math:`\alpha_{i-1}` (they precede joint *i*).
        convention: ``"standard"`` or ``"modified"``.
        base: (4, 4) world-from-frame-0 transform.
        tool: (4, 4) frame-n-from-end-effector transform.
        joints: the :class:`~qpik.robots.joint.Joint` s the table stands for (derived).
    """

    a: tuple[float, ...]
    d: tuple[float, ...]
    alpha: tuple[float, ...]
    offset: tuple[float, ...] = ()
    convention: Convention = "standard"
    base: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        for name in ("a", "d", "alpha", "offset"):  # finite numbers, lengths within 1e6 m
            bounded(finite_array(getattr(self, name), f"DHChain.{name}", (None,)), f"DHChain.{name}")
        n = len(self.a)
        if not (len(self.d) == len(self.alpha) == n) or (len(self.offset) and len(self.offset) != n):
            raise InputError("DHChain: a, d, alpha (and offset) must have the same length")
        if self.convention not in ("standard", "modified"):
            raise InputError(f"DHChain.convention: unknown convention {self.convention!r}")
        for name in ("a", "d", "alpha", "offset"):
            object.__setattr__(self, name, tuple(float(x) for x in getattr(self, name)))
        object.__setattr__(self, "offset", self.offset or (0.0,) * n)
        joints = []
        for i in range(n):
            rx = _rot_x(self.alpha[i])
            if self.convention == "standard":
                pre, post = np.eye(4), _trans(0.0, 0.0, self.d[i]) @ _trans(self.a[i], 0.0, 0.0) @ rx
            else:
                pre, post = _trans(self.a[i], 0.0, 0.0) @ rx, _trans(0.0, 0.0, self.d[i])
            joints.append(Joint(pre=pre, post=post, offset=self.offset[i]))
        self._set(joints, self.base, self.tool)


def _rot_x(alpha: float) -> np.ndarray:
    """R_x(alpha) as (4, 4), with cos/sin within 1e-15 of 0 or ±1 rounded (cos(π/2) -> 0)."""
    c, s = (sy.snap(float(f(alpha))) for f in (np.cos, np.sin))
    T = np.eye(4)
    T[1:3, 1:3] = ((c, -s), (s, c))
    return T


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T
