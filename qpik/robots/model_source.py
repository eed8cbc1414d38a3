r"""Where a loaded robot's model comes from, and the MuJoCo spec rebuilt from it: :class:`ModelSource`.

A loaded robot keeps the file it came from (MJCF or URDF, mesh options, the arm's joint names, the
tip body) so that the model can be read again: :meth:`ModelSource.spec` moved into the robot's
base frame (every element of the world body moved by the inverse of ``placement``, (4, 4), m),
:meth:`ModelSource.qpos` the model's ``qpos`` at an arm configuration q (n,) (mimic joints coupled),
and :meth:`ModelSource.spec_with` the spec with the robot's capsules drawn (translucent, visual
only), a site at the end effector and lights for pictures, which :meth:`qpik.Robot.to_mjcf` writes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from qpik.robots.body_tree import BodyTree, joint_frame
from qpik.robots.model_files import captured_warnings, read_spec

if TYPE_CHECKING:
    import mujoco

    from qpik.robots.description import ArmDescription


SITE = "qpik_ee"
"""Name of the end-effector site that :meth:`ModelSource.spec_with` adds to the model."""
CAPSULE_RGBA = (0.2, 0.6, 1.0, 0.3)


@dataclass(frozen=True)
class ModelSource:
    """Where a loaded robot comes from, to rebuild its MuJoCo model.

    Attributes:
        path: the MJCF or URDF file.
        package_map: ``{package: folder}`` for ``package://`` mesh paths.
        collision_only: visual geoms (and meshes only they use) are left out.
        joint_names: the arm's independent joints in the model, in chain order (one per entry of q).
        tip_body: the body the end effector is attached to.
        site: the name of the end-effector site added by :meth:`spec_with`.
        placement: (4, 4) the base frame's pose in the file's world frame (joints above the base at
            their reference), m; :meth:`spec` moves the model by its inverse.
        allow_outside: mesh paths may leave their package root.
        mimic: ``(joint, leader, multiplier, offset)`` per mimic joint on the chain: the model's
            ``qpos[joint] = multiplier * qpos[leader] + offset``.
    """

    path: Path
    package_map: Mapping[str, str] = field(default_factory=dict)
    collision_only: bool = False
    joint_names: tuple[str, ...] = ()
    tip_body: str = ""
    site: str = SITE
    placement: np.ndarray = field(default_factory=lambda: np.eye(4), compare=False)  # (arrays do not compare)
    allow_outside: bool = False
    mimic: tuple[tuple[str, str, float, float], ...] = ()

    def spec(self) -> mujoco.MjSpec:
        """A fresh spec of the file (meshes resolved, static bodies kept), moved so that its world frame is the
        robot's base frame (a mimic joint keeps the joint equality MuJoCo reads from the file)."""
        with captured_warnings():  # said when the file was loaded (the robot's notes)
            spec = read_spec(self.path, self.package_map, self.collision_only, self.allow_outside)
        if not np.array_equal(self.placement, np.eye(4)):
            move_world(spec, np.linalg.inv(self.placement))
        return spec

    def qpos(self, model: mujoco.MjModel, q: np.ndarray) -> np.ndarray:
        """The model's ``qpos`` at arm configuration q (n,): ``qpos0`` with the arm's and the mimic joints' entries."""
        qpos = model.qpos0.copy()
        adr = {nm: int(model.joint(nm).qposadr[0]) for nm in self.joint_names}
        for nm, x in zip(self.joint_names, q):
            qpos[adr[nm]] = x
        for joint, leader, m, c in self.mimic:
            qpos[model.joint(joint).qposadr[0]] = m * qpos[adr[leader]] + c
        return qpos

    def spec_with(self, robot: ArmDescription) -> mujoco.MjSpec:
        """The spec with the robot's capsules (visual: translucent, group 2, no contacts) and the end-effector site.

        Capsule ``c`` of link ``k`` is geom ``qpik_capsule{c}`` on the body of chain joint ``k``, placed by
        link frame ``k`` (the joint frame) in that body.
        """
        import mujoco

        spec = self.spec()
        model = spec.compile()
        for c, cap in enumerate(robot.capsules):
            joint = model.joint(robot.chain.joints[cap.link - 1].name)
            body = spec.body(model.body(int(joint.bodyid[0])).name)
            to_link = joint_frame(model, joint.id)  # link frame k in the joint's body (at any q: it moves with it)
            p0, p1 = (to_link[:3, :3] @ p + to_link[:3, 3] for p in (cap.p0, cap.p1))
            g = body.add_geom()
            g.name = f"qpik_capsule{c}"
            g.contype, g.conaffinity, g.group = 0, 0, 2
            g.rgba = CAPSULE_RGBA
            half = 0.5 * float(np.linalg.norm(p1 - p0))
            if half < 1e-9:
                g.type, g.size, g.pos = mujoco.mjtGeom.mjGEOM_SPHERE, [cap.radius, 0, 0], p0
            else:  # centre and orientation rather than fromto, which MuJoCo refuses for very short segments
                quat = np.zeros(4)
                mujoco.mju_quatZ2Vec(quat, p1 - p0)
                g.type, g.size = mujoco.mjtGeom.mjGEOM_CAPSULE, [cap.radius, half, 0]
                g.pos, g.quat = 0.5 * (p0 + p1), quat
        q_ref = np.array([model.qpos0[model.joint(nm).qposadr[0]] for nm in self.joint_names])
        tree = BodyTree(model, self.qpos(model, q_ref))
        ee = np.linalg.inv(tree.pose(model.body(self.tip_body).id)) @ robot.fk(q_ref)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(ee[:3, :3]).ravel())
        site = spec.body(self.tip_body).add_site()
        site.name, site.pos, site.quat, site.size, site.rgba = (
            self.site,
            ee[:3, 3],
            quat,
            [0.01, 0, 0],
            [0.9, 0.1, 0.1, 1],
        )
        _stage(spec)
        return spec


def move_world(spec: mujoco.MjSpec, T: np.ndarray) -> None:
    """Move everything in the spec's world body by the rigid transform ``T`` (4, 4), through one frame."""
    import mujoco

    frame = spec.worldbody.add_frame()
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T[:3, :3]).ravel())
    frame.pos, frame.quat = T[:3, 3], quat
    w = spec.worldbody
    for element in [*w.bodies, *w.geoms, *w.sites, *w.cameras, *w.lights, *w.frames]:
        if element is not frame and element.frame is None:
            element.set_frame(frame)


def _stage(spec: mujoco.MjSpec) -> None:
    """Lights and a sky for pictures, as the twin has (nothing that collides or moves)."""
    import mujoco

    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    sky = spec.add_texture()
    sky.name, sky.type = "qpik_sky", mujoco.mjtTexture.mjTEXTURE_SKYBOX
    sky.builtin = mujoco.mjtBuiltin.mjBUILTIN_GRADIENT
    sky.rgb1, sky.rgb2, sky.width, sky.height = [0.95, 0.96, 0.98], [0.75, 0.8, 0.88], 256, 256
    light = spec.worldbody.add_light()
    light.name, light.pos, light.dir, light.diffuse = "qpik_key", [1.0, -1.0, 2.5], [-1.0, 1.0, -2.5], [0.6, 0.6, 0.6]
    light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
