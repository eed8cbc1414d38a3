r"""The body tree of a compiled MuJoCo model, and the frames the loader reads from it.

:class:`BodyTree` holds the parents and children of every body and the bodies' world poses
(4, 4) at the reference configuration (or at a given ``qpos``), from ``mj_kinematics``; it finds
a body or site by name, the default tip below a base (down while exactly one child moves), the
bodies from base to tip and the arm's hinge and slide joints among them.

:func:`pose_matrix` is the (4, 4) transform of a MuJoCo position and unit quaternion (w, x, y, z);
:func:`joint_frame` the frame of a joint in its body: origin at the joint's anchor, z along its
axis (the link frame *k* of :mod:`qpik.robots.chain`). Lengths in metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from qpik.core.errors import InputError

if TYPE_CHECKING:
    import mujoco


class BodyTree:
    """The body tree of a compiled model: parents, joints per body, poses at the reference configuration (or at
    ``qpos``), in the model's world frame."""

    def __init__(self, model: mujoco.MjModel, qpos: np.ndarray | None = None):
        import mujoco

        self.model = model
        self.data = mujoco.MjData(model)
        if qpos is not None:
            self.data.qpos[:] = qpos
        mujoco.mj_kinematics(model, self.data)
        self.children: dict[int, list[int]] = {b: [] for b in range(model.nbody)}
        for b in range(1, model.nbody):
            self.children[int(model.body_parentid[b])].append(b)

    def pose(self, body: int) -> np.ndarray:
        """World pose (4, 4) of a body at the reference configuration."""
        T = np.eye(4)
        T[:3, :3] = self.data.xmat[body].reshape(3, 3)
        T[:3, 3] = self.data.xpos[body]
        return T

    def frame(self, name: str, what: str) -> tuple[int, np.ndarray]:
        """A body's id and identity, or a site's body id and the site's pose in that body."""
        import mujoco

        b = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if b >= 0:
            return b, np.eye(4)
        s = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, name)
        if s >= 0:
            return int(self.model.site_bodyid[s]), pose_matrix(self.model.site_pos[s], self.model.site_quat[s])
        raise InputError(f"{what}: no body or site {name!r} in the model")

    def moves(self, body: int) -> bool:
        """Whether a body or one below it has a joint."""
        return bool(self.model.body_jntnum[body]) or any(self.moves(c) for c in self.children[body])

    def default_tip(self, base: int) -> int:
        """Down from ``base`` while exactly one child moves (then to its end through static bodies)."""
        body = base
        while True:
            moving = [c for c in self.children[body] if self.moves(c)]
            if len(moving) > 1:
                if body == base:
                    names = ", ".join(repr(self.model.body(c).name) for c in moving)
                    raise InputError(
                        f"branched chain: {self.model.body(body).name or 'world'!r} carries {len(moving)} moving "
                        f"branches ({names}); name the arm's end with tip=... (or joints=...)"
                    )
                return body
            if not moving:
                static = self.children[body]
                if len(static) == 1 and not self.children[static[0]]:
                    return static[0]  # a single static end link (a URDF flange or tool frame)
                return body
            body = moving[0]

    def path(self, base: int, tip: int) -> list[int]:
        """Bodies from base (excluded) down to tip (included)."""
        out, b = [], tip
        while b != base:
            if b == 0:
                raise InputError(
                    f"branched chain: tip {self.model.body(tip).name!r} is not below base "
                    f"{self.model.body(base).name or 'world'!r}"
                )
            out.append(b)
            b = int(self.model.body_parentid[b])
        return out[::-1]

    def arm_joints(self, bodies: list[int], names: Sequence[str] | None) -> list[int]:
        """Ids of the arm's joints: hinge/slide joints on the path, or the named ones (all on the path)."""
        import mujoco

        m = self.model
        on_path = [j for b in bodies for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])]
        kinds = {int(mujoco.mjtJoint.mjJNT_HINGE): "hinge", int(mujoco.mjtJoint.mjJNT_SLIDE): "slide"}
        if names is None:
            bad = [j for j in on_path if int(m.jnt_type[j]) not in kinds]
            if bad:
                kind = mujoco.mjtJoint(int(m.jnt_type[bad[0]])).name[6:].lower()
                raise InputError(
                    f"unsupported joint: {m.joint(bad[0]).name!r} is a {kind} joint "
                    "(only hinge and slide joints can be arm joints; choose base= below it)"
                )
            arm = on_path
        else:
            arm = []
            for nm in names:
                j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, nm)
                if j < 0:
                    raise InputError(f"joints: no joint {nm!r} in the model")
                if j not in on_path:
                    raise InputError(f"joints: {nm!r} is not on the chain from base to tip (a branched chain?)")
                if int(m.jnt_type[j]) not in kinds:
                    raise InputError(f"unsupported joint: {nm!r} is not a hinge or slide joint")
                arm.append(j)
            if arm != sorted(arm, key=on_path.index):
                raise InputError("joints: not in chain order from base to tip")
        if not arm:
            raise InputError("no joints: the chain from base to tip has no hinge or slide joint")
        return arm


def pose_matrix(pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    import mujoco

    T = np.eye(4)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, float))
    T[:3, :3], T[:3, 3] = R.reshape(3, 3), pos
    return T


def _align(axis: np.ndarray) -> np.ndarray:
    """A rotation (4, 4) taking z to the unit vector ``axis`` (exact for ±z)."""
    T = np.eye(4)
    z = axis / np.linalg.norm(axis)
    if abs(z[2]) == 1.0 and z[0] == 0.0 and z[1] == 0.0:
        T[:3, :3] = np.diag([1.0, z[2], z[2]])
        return T
    x = np.cross((0.0, 0.0, 1.0) if abs(z[2]) < 0.9 else (1.0, 0.0, 0.0), z)
    x /= np.linalg.norm(x)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, np.cross(z, x), z
    return T


def joint_frame(model: mujoco.MjModel, j: int) -> np.ndarray:
    """The joint frame (anchor, z along the axis) in its body's frame, (4, 4)."""
    T = _align(model.jnt_axis[j])
    T[:3, 3] = model.jnt_pos[j]
    return T
