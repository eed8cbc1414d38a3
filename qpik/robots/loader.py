r"""Robots from MJCF and URDF files: ``qpik.load_robot(path_or_name, ...)``.

MuJoCo parses and compiles the file (it reads URDF too; mesh paths and visual geoms
are handled by :mod:`qpik.robots.model_files`). The arm is the chain of bodies from
``base`` to ``tip``; its joints are the hinge and slide joints on that path (or those
named in ``joints``: the others on the path are then locked at their reference
position). Joint *k* becomes a :class:`~qpik.robots.joint.Joint` with

- ``pre``: from link frame *k-1* through the bodies' ``pos``/``quat`` to the joint's
  anchor, turned so that z is the joint axis; ``post = I``: link frame *k* is the
  joint frame (anchor on the axis, z along it);
- ``offset`` :math:`= -q_{ref}`: MuJoCo moves a hinge by :math:`q - q_{ref}` (``qpos0``).

so that the chain's FK equals MuJoCo's ``mj_kinematics`` of the same model. The tool
is the tip body's (or site's) frame in link *n*, times ``ee``.

Frames: every pose of the robot (:meth:`qpik.Robot.fk`, the capsules, obstacles given to the
controller and planner) is in the **base frame**: the frame of the ``base`` body or site, as
pinocchio, KDL/TRAC-IK and MoveIt give poses relative to a chain's base link. Without ``base``
it is the model's world frame. The base's pose in the model's world frame, with the joints above
the base at their reference, is ``robot.model.placement`` (4, 4): a world-frame pose is
``robot.model.placement @ robot.fk(q)``. The MuJoCo model of the robot
(:meth:`~qpik.robots.model_source.ModelSource.spec`)
is moved by its inverse, so that its world frame is the base frame too.

Mimic joints (URDF ``<mimic joint=J multiplier=m offset=c>``) on the chain are coupled, not free:
:math:`q_{mimic} = m\,q_J + c` (:class:`~qpik.robots.joint.Joint` ``mimic``), with J an arm joint
before it on the chain; the arm's q has one entry per independent joint.

From the model (:mod:`qpik.robots.limits`, which refuses invalid limits):

- position limits: the joint ``range`` (URDF ``<limit lower upper>``); a joint without one (URDF
  ``continuous``) gets :data:`~qpik.robots.limits.CONTINUOUS_LIMIT` (two turns each way, so that a path through ±π
  stays inside and the closed form offers each angle's representatives q + 2πk);
- velocity limits: URDF ``<limit velocity>``; in MJCF, the ``ctrlrange`` of a velocity
  actuator on the joint; otherwise :data:`~qpik.robots.limits.DEFAULT_VELOCITY`;
- inertias are not used: an inertia MuJoCo refuses (PR2's violate the triangle inequality) is
  replaced (:func:`~qpik.robots.model_files.repair_inertias`), and ``robot.notes`` says so;
- home: the keyframe ``home`` if the model has one, else the reference configuration
  moved at least :data:`HOME_MARGIN` of each joint's range inside its limits;
- link capsules: the smallest capsule containing the collision geoms (those with a
  non-zero ``contype`` or ``conaffinity``) rigidly attached to each link, or all its geoms
  when none of them collides (:mod:`qpik.robots.capsule_fit`; meshes by their vertices,
  spheres, capsules and boxes exactly, a cylinder by a polygon around it, an ellipsoid by
  its box: :mod:`qpik.robots.link_capsules`). Geoms on side branches (fingers) count at their
  reference position.

The chain is matched against the closed-form patterns (:mod:`qpik.robots.recognize`): an
S-R-S or offset-shoulder arm gets ``closed_form`` and its ``canonical`` table, any other
the reason in ``notes``.

A loaded robot keeps its model (:class:`~qpik.robots.model_source.ModelSource`):
:meth:`qpik.Robot.to_mjcf` gives the model itself with the capsules drawn (translucent, visual only) and a site at the
end effector, so that the simulation and the pictures run on the real arm.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from qpik.core.errors import InputError, UnknownRobotError
from qpik.core.validate import finite_array, flag
from qpik.robots.body_tree import BodyTree, joint_frame, pose_matrix
from qpik.robots.catalog import CATALOG, catalog_robot
from qpik.robots.chain import SerialChain
from qpik.robots.joint import Joint
from qpik.robots.limits import arm_limits
from qpik.robots.link_capsules import link_capsules
from qpik.robots.model_files import MeshOptions, UrdfJoint, captured_warnings, is_urdf, read_spec, urdf_joints
from qpik.robots.model_source import ModelSource
from qpik.robots.recognize import REDUNDANCY, recognize
from qpik.robots.robot import Robot

_ASKED: dict[tuple[str, str], Robot] = {}
"""A catalog arm of no family asked for a locked joint (``load_robot("zheng7", redundancy="q7")``), once per arm and
parameter (as the catalog's own)."""

if TYPE_CHECKING:
    import mujoco


HOME_MARGIN = 0.1
"""Without a ``home`` keyframe, the home configuration keeps this fraction of each joint's range from its limits."""


MODEL_SUFFIXES = (".urdf", ".xml", ".mjcf")
"""A robot given by a name with one of these suffixes (any case) is a model file's path."""


def looks_like_a_file(path_or_name: str | os.PathLike) -> bool:
    """Whether :func:`load_robot` reads ``path_or_name`` as a file path, never as a catalog name: a path object, or a
    name with a folder separator or a suffix of :data:`MODEL_SUFFIXES`."""
    if not isinstance(path_or_name, str):
        return True
    return "/" in path_or_name or os.sep in path_or_name or Path(path_or_name).suffix.lower() in MODEL_SUFFIXES


def load_robot(
    path_or_name: str | os.PathLike,
    *,
    base: str | None = None,
    tip: str | None = None,
    joints: Sequence[str] | None = None,
    ee: np.ndarray | None = None,
    name: str | None = None,
    meshes: MeshOptions | None = None,
    redundancy: str | None = None,
) -> Robot:
    """A catalog arm by name, or the arm of an MJCF or URDF file.

    Args:
        path_or_name: ``"nammoto7"``, ``"iiwa14"``, ``"zheng7"``, ``"panda"`` (the catalog,
            no options), or the path of an MJCF (``.xml``) or URDF (``.urdf``) file.
        base: body or site the chain starts from, and the frame of every pose of the robot (its FK, capsules,
            obstacles): poses are relative to the base, as in pinocchio, KDL and MoveIt; default the model's
            world. The base's pose in the world is ``robot.model.placement``.
        tip: body or site at the end effector; default the end of the chain: from the base down
            to the first body with two moving branches (a gripper's fingers) or none.
        joints: names of the arm's joints in chain order; default every hinge and slide joint on
            the path from base to tip. Other joints on the path are locked at their reference.
        ee: (4, 4) end-effector frame in the tip's frame (default identity), m.
            Mimic joints on the chain (URDF ``<mimic>``) are coupled to their leader, not arm joints of their own.
        name: the robot's name (default the model's name; any text: ``robot.identifier`` is its C-safe form).
        meshes: how the meshes are read: ``package_map``, ``collision_only``, ``allow_outside``
            (:class:`~qpik.robots.model_files.MeshOptions`; default its defaults).
        redundancy: the closed form's parameter, ``"psi"``, ``"delta"``, ``"q7"`` (q7 locked) or ``"q1"`` (q1
            locked, the chain read from the flange), instead of the first family that fits
            (:func:`~qpik.robots.recognize.recognize`); a catalog arm takes only its own (none locks q1), but one of no
            family (``zheng7``) takes ``"q7"`` or ``"q1"`` where its file would be of a family with that joint locked
            (the 1-D search's or the general 6-R's): the same arm, with that family.

    Raises:
        UnknownRobotError: neither a catalog name nor an existing file; a name that looks like a file
            (:func:`looks_like_a_file`) and is none says "no such file".
        InputError: a bad model: not well-formed XML or declaring entities, MuJoCo cannot read it, a mesh is
            missing or outside its root, the chain from base to tip branches or has no joint, a joint on it is a
            ball or free joint, unknown names, invalid limits (:mod:`qpik.robots.limits`), a mimic joint whose
            leader is not an arm joint before it.
    """
    if not isinstance(path_or_name, str | os.PathLike):
        raise UnknownRobotError(
            f"path_or_name: expected a catalog name or a file path, got {type(path_or_name).__name__}"
        )
    text = os.fspath(path_or_name)
    options = (base, tip, joints, ee, name, meshes)
    if redundancy is not None and redundancy not in REDUNDANCY:
        raise InputError(f"redundancy: expected one of {', '.join(REDUNDANCY)} or None, got {redundancy!r}"[:200])
    if text in CATALOG:
        if any(o is not None for o in options):
            raise InputError(f"load_robot: {text!r} is a catalog arm; the options are for model files")
        robot = catalog_robot(text)
        if redundancy is None or (REDUNDANCY[redundancy] == robot.closed_form and redundancy != "q1"):
            return robot
        if robot.closed_form is None:  # an arm of no family here: the one its file would get, asked for
            found, why = recognize(robot.chain, redundancy)
            if found is not None:
                key = (text, redundancy)
                if key not in _ASKED:
                    _ASKED[key] = replace(robot, closed_form=found.kind, canonical=found,
                                          notes=f"{found.notes}; {robot.notes}")  # fmt: skip
                return _ASKED[key]
        raise InputError(f"redundancy: {text!r} has no closed form in {redundancy} (its family: {robot.closed_form})")
    path = Path(text)
    if not path.is_file():
        known = ", ".join(CATALOG)
        if not looks_like_a_file(path_or_name):
            raise UnknownRobotError(f"unknown robot {text!r}; known: {known}, or the path of an MJCF or URDF file")
        what = "is a folder, not a model file" if path.is_dir() else "no such file"
        raise UnknownRobotError(f"{text!r}: {what} (the catalog's arms: {known})")
    if name is not None and not isinstance(name, str):
        raise InputError(f"name: expected a string, got {type(name).__name__}")
    meshes = MeshOptions() if meshes is None else meshes
    if not isinstance(meshes, MeshOptions):
        raise InputError(f"meshes: expected MeshOptions, got {type(meshes).__name__}")
    pmap = {k: os.fspath(v) for k, v in (meshes.package_map or {}).items()}
    collision_only, allow_outside = meshes.collision_only, flag(meshes.allow_outside, "allow_outside")
    urdf = urdf_joints(path) if is_urdf(path) else None
    model, notes = _compile(path, pmap, collision_only, allow_outside)
    tree = BodyTree(model)
    base_id, base_offset = tree.frame(base, "base") if base is not None else (0, np.eye(4))
    tip_id, tip_offset = tree.frame(tip, "tip") if tip is not None else (tree.default_tip(base_id), np.eye(4))
    path_bodies = tree.path(base_id, tip_id)
    on_chain = tree.arm_joints(path_bodies, joints)
    _finite(model, path_bodies, on_chain, path.name)
    mimic = _mimic(model, on_chain, urdf or {}, path.name)
    arm = [j for j in on_chain if j not in mimic]
    names = tuple(model.joint(j).name for j in arm)
    source = ModelSource(
        path.resolve(),
        pmap,
        collision_only,
        names,
        model.body(tip_id).name,
        allow_outside=allow_outside,
        mimic=tuple((model.joint(j).name, model.joint(lead).name, m, c) for j, (lead, m, c) in mimic.items()),
    )
    q_ref = model.qpos0[model.jnt_qposadr[arm]]
    tree = BodyTree(model, source.qpos(model, q_ref))  # mimic joints coupled at the reference
    placement = tree.pose(base_id) @ base_offset
    source = replace(source, placement=placement)
    chain = _chain(model, path_bodies, on_chain, arm, mimic, base_offset, tip_offset, ee)
    q_min, q_max, v_max, limit_notes = arm_limits(model, arm, urdf, path.name)
    notes += limit_notes
    if mimic:
        notes.append(
            "mimic joints coupled to their leaders (their own limits are not enforced): "
            + ", ".join(
                f"{model.joint(j).name} = {m:g}·{model.joint(lead).name} + {c:g}" for j, (lead, m, c) in mimic.items()
            )
        )
    home = _home(model, arm, q_min, q_max)
    canonical, why = recognize(chain, redundancy)
    if canonical is None:
        notes.insert(0, f"no closed form: {why}")
    elif canonical.notes:
        notes.insert(0, canonical.notes)
    return Robot(
        name=name or model.names[: model.names.index(b"\0")].decode() or path.stem,
        chain=chain,
        q_min=q_min,
        q_max=q_max,
        v_max=v_max,
        q_home=home,
        capsules=link_capsules(model, tree, on_chain, chain, placement),
        closed_form=None if canonical is None else canonical.kind,  # type: ignore[arg-type]
        source=str(path.resolve()),
        notes="; ".join(notes),
        model=source,
        canonical=canonical,
    )


def _compile(
    path: Path, pmap: Mapping[str, str], collision_only: bool, allow_outside: bool
) -> tuple[mujoco.MjModel, list[str]]:
    """The compiled model and the notes of what was repaired in it (:func:`~qpik.robots.model_files.read_spec`)."""
    repaired: list[str] = []
    with captured_warnings() as said:
        spec = read_spec(path, pmap, collision_only, allow_outside, repaired)
        try:
            model = spec.compile()
        except (ValueError, RuntimeError) as exc:
            raise InputError(f"{path.name}: MuJoCo cannot compile it ({' '.join(str(exc).split())})") from None
    notes = [f"MuJoCo warned: {' '.join(text.split())}" for text in dict.fromkeys(said)]
    if repaired:
        notes.append(f"invalid inertias replaced (the kinematics does not use them): {', '.join(repaired)}")
    return model, notes


def _finite(model: mujoco.MjModel, bodies: list[int], on_chain: list[int], file: str) -> None:
    """Refuse NaN or infinite placements of the chain's bodies and joints (MuJoCo keeps them)."""
    for b in bodies:
        if not (np.all(np.isfinite(model.body_pos[b])) and np.all(np.isfinite(model.body_quat[b]))):
            raise InputError(f"{file}: body {model.body(b).name!r} has a NaN or infinite position or orientation")
    for j in on_chain:
        values = (model.jnt_pos[j], model.jnt_axis[j], model.qpos0[model.jnt_qposadr[j]])
        if not all(np.all(np.isfinite(v)) for v in values):
            raise InputError(f"{file}: joint {model.joint(j).name!r} has a NaN or infinite anchor, axis or reference")


def _mimic(
    model: mujoco.MjModel, on_chain: list[int], urdf: Mapping[str, UrdfJoint], file: str
) -> dict[int, tuple[int, float, float]]:
    """``{joint id: (leader id, multiplier, offset)}`` of the chain joints that an active joint equality couples to
    an independent chain joint before them: ``qpos = multiplier * qpos[leader] + offset``.

    MuJoCo writes a URDF ``<mimic>`` as such an equality; an MJCF may have its own. With MuJoCo's
    :math:`y - y_0 = a_0 + a_1 (x - x_0)`: multiplier :math:`a_1`, offset :math:`y_0 + a_0 - a_1 x_0`.
    A URDF mimic joint that MuJoCo left uncoupled (its leader is no joint of the file) is refused.
    """
    import mujoco

    out: dict[int, tuple[int, float, float]] = {}
    for e in range(model.neq):
        if model.eq_type[e] != mujoco.mjtEq.mjEQ_JOINT or not model.eq_active0[e]:
            continue
        j, lead = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        if j not in on_chain:
            continue
        name = model.joint(j).name
        a = model.eq_data[e, :5]
        if lead < 0 or np.any(a[2:] != 0.0):
            raise InputError(f"{file}: joint {name!r} is held by a joint equality that is not linear in another joint")
        if lead not in on_chain[: on_chain.index(j)] or lead in out:
            raise InputError(
                f"{file}: joint {name!r} mimics {model.joint(lead).name!r}, which is not an independent arm joint "
                "before it on the chain (qpik couples a mimic joint to such a joint only)"
            )
        if not np.all(np.isfinite(a[:2])):
            raise InputError(f"{file}: joint {name!r}: mimic multiplier and offset must be finite, got {a[1]}, {a[0]}")
        y0, x0 = (float(model.qpos0[model.jnt_qposadr[i]]) for i in (j, lead))
        out[j] = (lead, float(a[1]), y0 + float(a[0]) - float(a[1]) * x0)
    for j in on_chain:
        info = urdf.get(model.joint(j).name)
        if j not in out and info is not None and info.mimic is not None:
            raise InputError(f"{file}: joint {info.name!r} mimics {info.mimic!r}, which is not a joint of the file")
    return out


def _chain(
    model: mujoco.MjModel,
    bodies: list[int],
    on_chain: list[int],
    arm: list[int],
    mimic: Mapping[int, tuple[int, float, float]],
    base_offset: np.ndarray,
    tip_offset: np.ndarray,
    ee: np.ndarray | None,
) -> SerialChain:
    """The serial chain of the joints ``on_chain`` along ``bodies``, in the base frame (see the module docstring).

    ``arm``: the independent joints (one entry of q each); ``mimic``: the others, coupled to a leader in ``arm``.
    """
    import mujoco

    joints = []
    acc = np.linalg.inv(base_offset)  # the current body frame in the last link frame (the base frame at first)
    for b in bodies:
        acc = acc @ pose_matrix(model.body_pos[b], model.body_quat[b])
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            if j not in on_chain:
                continue  # locked at its reference: no motion
            anchor = joint_frame(model, j)
            slide = int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_SLIDE)
            q_ref = float(model.qpos0[model.jnt_qposadr[j]])
            if j in mimic:  # qpos = m q_leader + c: the motion m q_leader + (c - q_ref)
                lead, m, c = mimic[j]
                coupling, offset = (arm.index(lead), m), c - q_ref
            else:
                coupling, offset = None, -q_ref
            joints.append(
                Joint(
                    pre=acc @ anchor,
                    kind="prismatic" if slide else "revolute",
                    offset=offset,
                    name=model.joint(j).name,
                    mimic=coupling,
                )
            )
            acc = np.linalg.inv(anchor)
    tool = acc @ tip_offset @ (np.eye(4) if ee is None else finite_array(ee, "ee", (4, 4)))
    return SerialChain(joints, tool=tool)


def _home(model: mujoco.MjModel, arm: list[int], q_min: np.ndarray, q_max: np.ndarray) -> np.ndarray:
    """The ``home`` keyframe's arm joints, else the reference moved inside the limits by :data:`HOME_MARGIN`."""
    import mujoco

    adr = model.jnt_qposadr[arm]
    k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
    if k >= 0:
        return model.key_qpos[k][adr].copy()
    margin = HOME_MARGIN * (q_max - q_min)
    return np.clip(model.qpos0[adr], q_min + margin, q_max - margin)
