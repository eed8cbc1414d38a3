r"""Kinematics of any MJCF arm through MuJoCo and :class:`mink.Configuration`.

:class:`MjKinematics` gives an arm that has no DH table the interface of
:class:`qpik.Robot` for what the controller needs: ``fk``, ``jacobian``,
``fk_jacobian``, joint limits, point Jacobians and geom distances.

The arm's joints are a subset of the model's hinge/slide joints (all of
them by default); ``q`` (n,) is written into their ``qpos`` addresses and the
rest of ``qpos`` stays at ``qpos0``. One forward-kinematics pass is
``Configuration.update`` (``mj_kinematics`` + ``mj_comPos``); the Jacobians are
read with ``mj_jacSite``/``mj_jac``, which give them at the point and aligned
with the world frame — our convention — whereas mink's ``get_frame_jacobian``
returns the body-frame Jacobian :math:`{}_B J_{WB}` (``[v; ω]`` rotated into the
site frame).

Mimic joints (``mimic``: ``(joint, leader, multiplier, offset)``) follow their leader, an arm joint:
``qpos[joint] = multiplier * qpos[leader] + offset``, and the leader's Jacobian column gains
``multiplier`` times theirs (the chain rule).

Frames: MuJoCo's world frame is the base frame (a loaded robot's model is moved so that it is:
:meth:`qpik.robots.model_source.ModelSource.spec`). Units: metres, radians.
Not thread-safe: every call overwrites the configuration's ``MjData``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import mink
import mujoco
import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import finite_array, joint_vector

if TYPE_CHECKING:
    from qpik.robots.robot import Robot

_ARM_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class MjKinematics:
    """FK, Jacobians and distances of an MJCF arm.

    Args:
        model: a compiled MuJoCo model.
        site: name of the end-effector site.
        joint_names: the arm's joints in order; default: every hinge and slide
            joint of the model, in model order.
        mimic: ``(joint, leader, multiplier, offset)`` per joint coupled to an arm joint ``leader``.

    Attributes:
        model: the MuJoCo model.
        configuration: the :class:`mink.Configuration` holding its ``MjData``.
        dof: number of arm joints n.
        q_min, q_max: joint ranges (rad or m), shape (n,); ±inf for an unlimited joint.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        site: str = "ee",
        joint_names: Sequence[str] | None = None,
        mimic: Sequence[tuple[str, str, float, float]] = (),
    ):
        self.model = model
        self.configuration = mink.Configuration(model)
        self.data = self.configuration.data
        self.site = site
        self.site_id = self._id(mujoco.mjtObj.mjOBJ_SITE, site, "site")
        if joint_names is None:
            joints = [j for j in range(model.njnt) if model.jnt_type[j] in _ARM_JOINTS]
        else:
            joints = [self._id(mujoco.mjtObj.mjOBJ_JOINT, name, "joint") for name in joint_names]
            bad = [joint_names[i] for i, j in enumerate(joints) if model.jnt_type[j] not in _ARM_JOINTS]
            if bad:
                raise InputError(f"joint_names: {bad} are not hinge or slide joints")
        if not joints:
            raise InputError("model: has no hinge or slide joint")
        self.joint_ids = np.array(joints)
        self.qpos_adr = model.jnt_qposadr[self.joint_ids]
        self.dof_adr = model.jnt_dofadr[self.joint_ids]
        limited = model.jnt_limited[self.joint_ids].astype(bool)
        rng = model.jnt_range[self.joint_ids]
        self.q_min = np.where(limited, rng[:, 0], -np.inf)
        self.q_max = np.where(limited, rng[:, 1], np.inf)
        self._qpos = model.qpos0.copy()
        names = [model.joint(int(j)).name for j in self.joint_ids]
        ids = [self._id(mujoco.mjtObj.mjOBJ_JOINT, joint, "mimic joint") for joint, _, _, _ in mimic]
        strays = [lead for _, lead, _, _ in mimic if lead not in names]
        if strays:
            raise InputError(f"mimic: leaders {strays} are not arm joints ({names})")
        self._mimic = [
            (int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j]), names.index(lead), float(m), float(c))
            for j, (_, lead, m, c) in zip(ids, mimic)
        ]
        # the arm is the whole model: q is qpos and Jacobian columns need no selection
        self._whole = (
            not self._mimic
            and np.array_equal(self.qpos_adr, np.arange(model.nq))
            and np.array_equal(self.dof_adr, np.arange(model.nv))
        )
        self._jacp = np.zeros((3, model.nv))
        self._fromto = np.zeros(6)
        self._site_xpos, self._site_xmat = self.data.site_xpos, self.data.site_xmat  # views, fixed buffers

    # ---- constructors -------------------------------------------------------

    @classmethod
    def from_xml(
        cls, xml: str | os.PathLike, site: str = "ee", joint_names: Sequence[str] | None = None
    ) -> MjKinematics:
        """From an MJCF file path or an MJCF string (text starting with ``<``)."""
        text = str(xml)
        if text.lstrip().startswith("<"):
            model = mujoco.MjModel.from_xml_string(text)
        else:
            model = mujoco.MjModel.from_xml_path(text)
        return cls(model, site, joint_names)

    @classmethod
    def from_robot(cls, robot: Robot, extra_worldbody: Sequence[str] = ()) -> MjKinematics:
        """From a robot's MuJoCo model (:meth:`qpik.Robot.mj_spec`: the MJCF twin of a catalog arm,
        a loaded arm's own model), optionally with extra ``<worldbody>`` elements (obstacle geoms,
        sites): in the twin's ``<worldbody>`` under their own names, in a loaded model in a body
        ``extra`` of the world with their names prefixed ``extra/``."""
        if robot.model is None:
            from qpik.robots.mjcf import to_mjcf

            return cls(mujoco.MjModel.from_xml_string(to_mjcf(robot, extra_worldbody)), robot.site, robot.joint_names)
        spec = robot.mj_spec()
        if extra_worldbody:
            child = mujoco.MjSpec.from_string(
                f'<mujoco><worldbody><body name="extra">{"".join(extra_worldbody)}</body></worldbody></mujoco>'
            )
            spec.worldbody.add_frame().attach_body(child.body("extra"), "extra/", "")
        return cls(spec.compile(), robot.site, robot.joint_names, robot.model.mimic)

    @property
    def dof(self) -> int:
        return len(self.joint_ids)

    # ---- kinematics ---------------------------------------------------------

    def update(self, q: np.ndarray) -> None:
        """Forward kinematics at q (n,) into ``self.data`` (no input check)."""
        if self._whole:
            self.configuration.update(q)
        else:
            self._qpos[self.qpos_adr] = q
            for adr, _, lead, m, c in self._mimic:
                self._qpos[adr] = m * q[lead] + c
            self.configuration.update(self._qpos)

    def fk(self, q: np.ndarray) -> np.ndarray:
        """Pose of the end-effector site in the world frame: (4, 4); q (N, n) -> (N, 4, 4)."""
        return self.site_pose(q, self.site)

    def site_pose(self, q: np.ndarray, name: str) -> np.ndarray:
        """Pose of site ``name`` in the world frame: (4, 4); q (N, n) -> (N, 4, 4)."""
        sid = self._id(mujoco.mjtObj.mjOBJ_SITE, name, "site")
        return self._map(q, lambda: self._site_T(sid))

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian ``[v; ω]`` of the site origin, world frame: (6, n); batched (N, 6, n)."""
        return self._map(q, self._site_J)

    def fk_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Site pose (4, 4) and Jacobian (6, n) from one kinematics pass; batched (N, ...)."""
        q, batched = joint_vector(q, self.dof)
        if not batched:
            self.update(q)
            return self._site_T(self.site_id), self._site_J()
        out = [self.fk_jacobian(qi) for qi in q]
        return np.stack([T for T, _ in out]), np.stack([J for _, J in out])

    def point_jacobian(self, q: np.ndarray, body: str, point: np.ndarray) -> np.ndarray:
        r"""Translational Jacobian (3, n) of a world point rigidly attached to ``body``.

        ``point`` (3,) is given in the world frame at configuration ``q``;
        :math:`\dot p = J \dot q`. (MuJoCo ``mj_jac``.)
        """
        q, _ = joint_vector(q, self.dof)
        if q.ndim != 1:
            raise InputError(f"q: expected shape ({self.dof},), got {q.shape}")
        point = finite_array(point, "point", (3,))
        bid = self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")
        self.update(q)
        mujoco.mj_jac(self.model, self.data, self._jacp, None, point, bid)
        return self.columns(self._jacp)

    def geom_distance(self, q: np.ndarray, geom_a: str, geom_b: str, distmax: float = 1.0) -> tuple[float, np.ndarray]:
        """Signed distance (m) between two geoms and the witness segment.

        Returns ``(dist, fromto)`` with ``fromto`` (2, 3): the nearest point on
        ``geom_a`` and on ``geom_b`` (world frame); negative ``dist`` is
        penetration depth. If the geoms are farther apart than ``distmax``,
        ``dist == distmax`` and ``fromto`` is NaN. (MuJoCo ``mj_geomDistance``.)
        """
        q, _ = joint_vector(q, self.dof)
        if q.ndim != 1:
            raise InputError(f"q: expected shape ({self.dof},), got {q.shape}")
        ga = self._id(mujoco.mjtObj.mjOBJ_GEOM, geom_a, "geom")
        gb = self._id(mujoco.mjtObj.mjOBJ_GEOM, geom_b, "geom")
        self.update(q)
        dist = mujoco.mj_geomDistance(self.model, self.data, ga, gb, float(distmax), self._fromto)
        fromto = self._fromto.reshape(2, 3).copy()
        if dist >= distmax:
            fromto[:] = np.nan
        return float(dist), fromto

    # ---- helpers ------------------------------------------------------------

    def _site_T(self, sid: int) -> np.ndarray:
        T = np.empty((4, 4))
        T[:3, :3] = self._site_xmat[sid].reshape(3, 3)
        T[:3, 3] = self._site_xpos[sid]
        T[3] = (0.0, 0.0, 0.0, 1.0)
        return T

    def _site_J(self) -> np.ndarray:
        J = np.empty((6, self.model.nv))
        mujoco.mj_jacSite(self.model, self.data, J[:3], J[3:], self.site_id)
        return J if self._whole else self.columns(J)

    def columns(self, J: np.ndarray) -> np.ndarray:
        """The arm's columns (..., n) of a MuJoCo Jacobian (..., nv): its joints', plus each mimic joint's
        times its multiplier on its leader's (a new array)."""
        out = J[..., self.dof_adr]
        for _, dof, lead, m, _ in self._mimic:
            out[..., lead] += m * J[..., dof]
        return out

    def _map(self, q: np.ndarray, read: Callable[[], np.ndarray]) -> np.ndarray:
        q, batched = joint_vector(q, self.dof)
        if not batched:
            self.update(q)
            return read()
        out = []
        for qi in q:
            self.update(qi)
            out.append(read())
        return np.stack(out)

    def _id(self, kind: mujoco.mjtObj, name: str, what: str) -> int:
        i = mujoco.mj_name2id(self.model, kind, name)
        if i < 0:
            raise InputError(f"{what} {name!r} is not in the model")
        return i
