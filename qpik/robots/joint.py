r"""One joint of a serial chain: :class:`Joint`, the transform :math:`P\,M(q + o)\,S` from link *k-1* to link *k*.

:math:`P` (``pre``, (4, 4)): link *k-1* to the joint frame, whose z axis is the joint axis; :math:`M` the
motion, :math:`R_z` (revolute, rad) or :math:`T_z` (prismatic, m); :math:`S` (``post``, (4, 4)): the moved
joint frame to link frame *k*; o the offset. A coupled (mimic) joint has :math:`q_k = m\,q_i` for an
independent joint *i* before it. The chain of them: :mod:`qpik.robots.chain`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Frame, Ops, Scalar
from qpik.core.errors import InputError
from qpik.core.validate import number, single_pose

JointKind = Literal["revolute", "prismatic"]
ZERO_VEC = (0.0, 0.0, 0.0)


def _eye() -> np.ndarray:
    return np.eye(4)


@dataclass(frozen=True)
class Joint:
    r"""One joint: :math:`P\,M(q + o)\,S` from link *k-1* to link *k* (see the module docstring).

    Attributes:
        pre: (4, 4) constant transform from link *k-1* to the joint frame (z = joint axis).
        post: (4, 4) constant transform from the moved joint frame to link frame *k*.
        kind: ``"revolute"`` (q in rad, about z) or ``"prismatic"`` (q in m, along z).
        offset: o, added to q before the motion (rad or m).
        name: the joint's name in its model (``""`` for a DH table).
        mimic: ``(i, m)`` for a coupled joint: its q is m times independent joint i's (i counts the
            chain's independent joints from 0; i comes before this joint); None for an independent joint.
    """

    pre: np.ndarray = field(default_factory=_eye)
    post: np.ndarray = field(default_factory=_eye)
    kind: JointKind = "revolute"
    offset: float = 0.0
    name: str = ""
    mimic: tuple[int, float] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str) or self.kind not in ("revolute", "prismatic"):
            raise InputError(f"Joint.kind: unknown kind {self.kind!r} (revolute or prismatic)")
        for name in ("pre", "post"):  # rigid transforms: rotation blocks orthonormal, lengths within 1e6 m
            object.__setattr__(self, name, single_pose(getattr(self, name), f"Joint.{name}"))
        object.__setattr__(self, "offset", number(self.offset, "Joint.offset", minimum=None))
        if self.mimic is not None:
            try:
                i, m = self.mimic
            except (TypeError, ValueError):
                raise InputError(f"Joint.mimic: expected (joint index, multiplier), got {self.mimic!r}") from None
            if isinstance(i, bool) or not isinstance(i, int | np.integer) or i < 0:
                raise InputError(f"Joint.mimic: joint index must be an int >= 0, got {i!r}")
            object.__setattr__(self, "mimic", (int(i), number(m, "Joint.mimic multiplier", minimum=None)))

    def motion(self, q: Scalar, ops: Ops) -> Frame:
        """:math:`M(q + o)` as a :mod:`qpik.algebra.symbolic` frame."""
        x = sy.add(q, self.offset)
        if self.kind == "prismatic":
            return sy.frame_of(np.eye(4))[0], (0.0, 0.0, x)
        return sy.rot_z(ops.cos(x), ops.sin(x)), ZERO_VEC

    def local_expr(self, q: Scalar, ops: Ops) -> Frame:
        """:math:`P\\,M(q + o)\\,S`, link *k-1* to link *k* (constants folded)."""
        return sy.compose(sy.compose(sy.frame_of(self.pre), self.motion(q, ops)), sy.frame_of(self.post))

    @cached_property
    def axis_source(self) -> str:
        """Where the world axis is read most cheaply: ``"before"`` (P = I: frame *k-1*), ``"after"``
        (S a translation along z: frame *k*) or ``"joint"`` (frame *k-1* times P)."""
        if np.array_equal(self.pre, np.eye(4)):
            return "before"
        post = self.post
        if np.array_equal(post[:3, :3], np.eye(3)) and post[0, 3] == 0.0 and post[1, 3] == 0.0:
            return "after"
        return "joint"
