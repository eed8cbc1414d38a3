"""A robot: a serial chain plus limits, home configuration and link capsules.

Frames: every pose a robot gives or takes (FK, Jacobians, frames, capsules, obstacles) is in its
**base frame**: for a catalog arm the world frame of its MuJoCo twin; for an arm loaded with
``base="link"`` that link's frame (:mod:`qpik.robots.loader`), whose pose in the file's world
frame is ``robot.model.placement``; for one loaded without ``base`` the file's world frame.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, Literal

import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Frame, Vec
from qpik.core.errors import InputError
from qpik.core.validate import joint_vector, number
from qpik.robots.cache import RobotCache
from qpik.robots.chain import SerialChain
from qpik.robots.description import ModelFile

if TYPE_CHECKING:
    import mujoco

    from qpik.robots.recognize import Canonical

ClosedForm = Literal["offset_shoulder", "srs", "locked_joint", "locked_search", "locked_general"] | None


@dataclass(frozen=True)
class LinkCapsule:
    """A capsule rigidly attached to link ``link`` (1..n, the body moved by joint ``link``).

    ``p0``, ``p1`` (3,) are the segment end points in link frame ``link`` of the chain (for a chain with mimic
    joints, ``link`` counts every chain joint)
    (:meth:`SerialChain.frames`; the DH frame for a DH table), metres; ``radius`` in metres.
    A zero-length segment is a sphere.
    """

    link: int
    p0: np.ndarray
    p1: np.ndarray
    radius: float


@dataclass(frozen=True)
class Robot:
    """An arm: of the catalog, a user's own chain (a DH table, say), or loaded from an MJCF/URDF file.

    Attributes:
        name: catalog or model name.
        chain: the kinematic model (:class:`~qpik.robots.chain.SerialChain`, e.g. a DH table).
        q_min, q_max: joint position limits (rad), shape (n,).
        v_max: joint velocity limits (rad/s), shape (n,).
        q_home: a home configuration (rad), shape (n,).
        capsules: one :class:`LinkCapsule` per moving link.
        closed_form: which analytic IK applies: ``"offset_shoulder"`` (δ),
            ``"srs"`` (ψ), ``"locked_joint"`` (q7 locked, or q1 where ``canonical.reversed``), ``"locked_search"``
            (q1 or q7 locked, no closed form: the branches found by a certified 1-D search,
            :mod:`qpik.analytic.locked_search`), ``"locked_general"`` (q7 or q1 locked, a general 6-R chain left: its
            branches from one eigenproblem, :mod:`qpik.analytic.general_solver`) or ``None``.
        source: where the numbers come from.
        model: the MJCF/URDF model of a loaded robot (:func:`qpik.robots.loader.load_robot`),
            or None for a catalog arm (whose MuJoCo model is the twin).
        canonical: for a closed form found in a loaded chain (:func:`qpik.robots.recognize.recognize`),
            the catalog-form DH table and the joint map to it; None when ``chain`` is that table itself.
        a_max, j_max: joint acceleration (rad/s²) and jerk (rad/s³) limits, shape (n,), or None where no
            source gives them (:mod:`qpik.control.limits_motion` then needs them given).
        cache: what is built once for this robot (:class:`~qpik.robots.cache.RobotCache`), freed with it.
    """

    name: str
    chain: SerialChain
    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray
    q_home: np.ndarray
    capsules: tuple[LinkCapsule, ...] = ()
    closed_form: ClosedForm = None
    source: str = ""
    notes: str = field(default="", compare=False)
    model: ModelFile | None = field(default=None, compare=False)
    canonical: Canonical | None = field(default=None, compare=False)
    a_max: np.ndarray | None = field(default=None, compare=False)
    j_max: np.ndarray | None = field(default=None, compare=False)
    cache: RobotCache = field(default_factory=RobotCache, init=False, repr=False, compare=False)

    @property
    def branch_functions(self) -> bool:
        """Whether the arm's analytic IK gives its branches as expressions of the pose and parameter (every family but
        ``"locked_search"`` and ``"locked_general"``, whose branches are found per pose and parameter): what the path
        NLP and DP of :func:`qpik.plan_self_motion` and :func:`qpik.solve_best` differentiate. Without, they treat the
        arm as one of no closed form."""
        return self.closed_form is not None and self.closed_form not in ("locked_search", "locked_general")

    @property
    def dof(self) -> int:
        """n, the number of independent joints (entries of q)."""
        return self.chain.dof

    @cached_property
    def identifier(self) -> str:
        """The name as an identifier that CasADi accepts in function names: ASCII letters and digits, each run of
        other characters one ``_`` (none at the ends), ``robot_`` before a leading digit; ``"robot"`` if empty."""
        out = "_".join(re.findall(r"[A-Za-z0-9]+", self.name)) or "robot"
        return f"robot_{out}" if out[0].isdigit() else out

    # kinematics (see SerialChain for shapes; every pose in the robot's base frame, see the module docstring)
    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector pose (4, 4) in the base frame; batched (N, 4, 4)."""
        return self.chain.fk(q)

    def frames(self, q: np.ndarray) -> np.ndarray:
        """Base-frame poses of ``[base, frame_1..frame_n, ee]``: (n+2, 4, 4); batched (N, n+2, 4, 4)."""
        return self.chain.frames(q)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian ``[v; ω]`` in the base frame: (6, n); batched (N, 6, n)."""
        return self.chain.jacobian(q)

    def fk_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose (4, 4) and Jacobian (6, n) from one kinematics pass, base frame."""
        return self.chain.fk_jacobian(q)

    def hessian(self, q: np.ndarray) -> np.ndarray:
        """Kinematic Hessian ``H[k] = ∂J/∂q_k``: (n, 6, n); batched (N, n, 6, n)."""
        return self.chain.hessian(q)

    def manipulability(self, q: np.ndarray, translational: bool = False) -> np.ndarray | float:
        """Yoshikawa's sqrt(det(J Jᵀ)) (unitless mix of m and rad); batched (N,)."""
        return self.chain.manipulability(q, translational)

    def manipulability_gradient(self, q: np.ndarray, translational: bool = False) -> np.ndarray:
        """∂m/∂q (per rad) from the kinematic Hessian: (n,); batched (N, n)."""
        return self.chain.manipulability_gradient(q, translational)

    def within_limits(self, q: np.ndarray, tol: float = 0.0) -> np.ndarray | bool:
        """Whether every joint of q (n,) or (N, n) is in [q_min - tol, q_max + tol] (``tol`` ≥ 0, rad)."""
        tol = number(tol, "tol")
        q, _ = joint_vector(q, self.dof)
        ok = np.all((q >= self.q_min - tol) & (q <= self.q_max + tol), axis=-1)
        return bool(ok) if ok.ndim == 0 else ok

    def with_home(self, q_home: np.ndarray) -> Robot:
        """This robot with the home configuration ``q_home`` (n,), rad, within the limits (a new robot, with its own
        cache).

        Raises:
            InputError: NaN/inf, a wrong shape, or a joint outside ``[q_min, q_max]``.
        """
        q, batched = joint_vector(q_home, self.dof, "q_home")
        if batched:
            raise InputError(f"q_home: expected shape ({self.dof},), got {np.shape(q_home)}")
        if not self.within_limits(q):
            bad = np.flatnonzero((q < self.q_min) | (q > self.q_max))
            raise InputError(f"q_home: joints {', '.join(str(j + 1) for j in bad)} outside their limits")
        return replace(self, q_home=q.copy())

    def capsule_segments_expr(self, frames: list[Frame]) -> list[tuple[Vec, Vec]]:
        """Base-frame end points ``(a, b)`` of every capsule from the frames of :meth:`SerialChain.frames_expr`.

        Capsule ``c`` is ``self.capsules[c]``: ``a = R_k p0 + t_k``, ``b = R_k p1 + t_k`` with
        ``(R_k, t_k)`` the world pose of its link ``k``. Written in :mod:`qpik.algebra.symbolic`
        (numpy batches or CasADi symbols).
        """
        out = []
        for c in self.capsules:
            R, t = frames[c.link]
            out.append(tuple(sy.vadd(sy.matvec(R, tuple(map(sy.snap, p))), t) for p in (c.p0, c.p1)))
        return out  # type: ignore[return-value]

    def capsule_segments(self, q: np.ndarray) -> np.ndarray:
        """Base-frame end points of every capsule: (C, 2, 3); batched (N, C, 2, 3), m."""
        F = self.chain.frames(q)  # (..., n+2, 4, 4): compiled for one configuration
        if not self.capsules:
            return np.zeros((*F.shape[:-3], 0, 2, 3))
        links = [c.link for c in self.capsules]
        ends = np.array([[c.p0, c.p1] for c in self.capsules], dtype=float)  # (C, 2, 3), link frames
        G = np.take(F, links, axis=-3)  # (..., C, 4, 4): the capsules' links
        R, t = G[..., :3, :3], G[..., :3, 3]
        return np.einsum("...cij,cej->...cei", R, ends) + t[..., None, :]

    @cached_property
    def fixed_capsules(self) -> np.ndarray:
        """Which capsules no joint moves (C,) bool: e.g. a first link's capsule on the first joint's axis.

        A capsule is fixed when its world end points are the same, to 1e-12 m, at 16 configurations
        drawn uniformly inside the limits (clipped to ±π) from a fixed seed; a capsule that any joint
        moves moves at almost every configuration. Its distance to an obstacle is a constant that no
        velocity can change: the controller leaves such pairs out of its rows and clearances.
        """
        lo, hi = np.maximum(self.q_min, -np.pi), np.minimum(self.q_max, np.pi)
        q = lo + (hi - lo) * np.random.default_rng(0).random((16, self.dof))
        segments = self.capsule_segments(q)  # (16, C, 2, 3)
        return np.all(np.abs(segments - segments[:1]) <= 1e-12, axis=(0, 2, 3))

    @cached_property
    def capsule_radii(self) -> np.ndarray:
        return np.array([c.radius for c in self.capsules])

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The arm's joints in :meth:`mj_model`, in chain order."""
        return self.model.joint_names if self.model else tuple(f"joint{k}" for k in range(1, self.dof + 1))

    @property
    def site(self) -> str:
        """The end-effector site of :meth:`mj_model` (it equals :meth:`fk`)."""
        return self.model.site if self.model else "ee"

    def to_mjcf(self) -> str:
        """The MuJoCo model as MJCF text: for a catalog arm the twin (one body per link, capsules as
        geoms, site ``ee``); for a loaded arm its own model with the capsules drawn (visual only)
        and the site :attr:`site` (:meth:`~qpik.robots.model_source.ModelSource.spec_with`)."""
        if self.model is not None:
            return self.model.spec_with(self).to_xml()
        from qpik.robots.mjcf import to_mjcf

        return to_mjcf(self)

    def to_urdf(self) -> str:
        """The URDF of the arm from its joint axes at q = 0, root ``base``, tip ``ee`` (:mod:`qpik.robots.urdf`)."""
        from qpik.robots.urdf import to_urdf

        return to_urdf(self)

    def mj_spec(self) -> mujoco.MjSpec:
        """The MuJoCo model as a spec (what :meth:`to_mjcf` writes, at full precision)."""
        if self.model is not None:
            return self.model.spec_with(self)
        import mujoco

        return mujoco.MjSpec.from_string(self.to_mjcf())

    def mj_model(self) -> mujoco.MjModel:
        """:meth:`mj_spec` compiled by MuJoCo."""
        return self.mj_spec().compile()


def default_capsules(chain: SerialChain, radii: tuple[float, ...]) -> tuple[LinkCapsule, ...]:
    """One capsule per link, from its joint's axis point to the next joint's (or the ee).

    The points are taken at q = 0 (from :meth:`SerialChain.axes`) and expressed in the
    link's frame, where they are constant for any q.
    """
    q0 = np.zeros(chain.dof)
    F = chain.frames(q0)
    n = chain.dof
    pts = [*chain.axes(q0)[1], F[n + 1, :3, 3]]
    caps = []
    for k in range(1, n + 1):
        inv = np.linalg.inv(F[k])
        p0, p1 = (inv[:3, :3] @ p + inv[:3, 3] for p in (pts[k - 1], pts[k]))
        caps.append(LinkCapsule(k, _clean(p0), _clean(p1), radii[k - 1]))
    return tuple(caps)


def _clean(p: np.ndarray) -> np.ndarray:
    return np.where(np.abs(p) < 1e-12, 0.0, p)


def as_robot(robot: object, name: str = "robot") -> Robot:
    """``robot`` if it is a :class:`Robot`, else :class:`InputError` naming ``name`` (a name: how to load it)."""
    if isinstance(robot, Robot):
        return robot
    if isinstance(robot, str):
        raise InputError(f"{name}: expected a qpik.Robot, got the string {robot!r} (use qpik.load_robot({robot!r}))")
    raise InputError(f"{name}: expected a qpik.Robot, got {type(robot).__name__}")
