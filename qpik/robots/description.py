"""What the model writers and a loaded model read of a robot, as structural types.

:class:`~qpik.robots.robot.Robot` satisfies :class:`ArmDescription`; the writers
(:func:`qpik.robots.mjcf.to_mjcf`, :func:`qpik.robots.urdf.to_urdf`) and a loaded robot's model
(:class:`~qpik.robots.model_source.ModelSource`, a :class:`ModelFile`) are typed against these
protocols, so that the robot can call them without the modules importing each other.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    import mujoco

    from qpik.robots.chain import SerialChain


class Capsule(Protocol):
    """A capsule on link ``link`` (1..n): segment ``p0``–``p1`` (3,) in that link's frame, m; ``radius``, m."""

    @property
    def link(self) -> int: ...

    @property
    def p0(self) -> np.ndarray: ...

    @property
    def p1(self) -> np.ndarray: ...

    @property
    def radius(self) -> float: ...


class ArmDescription(Protocol):
    """An arm's chain, limits and capsules (base frame; rad, rad/s, m); read-only, as a frozen robot is."""

    @property
    def name(self) -> str: ...

    @property
    def chain(self) -> SerialChain: ...

    @property
    def q_min(self) -> np.ndarray: ...

    @property
    def q_max(self) -> np.ndarray: ...

    @property
    def v_max(self) -> np.ndarray: ...

    @property
    def dof(self) -> int: ...

    @property
    def capsules(self) -> Sequence[Capsule]: ...

    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector pose(s) (4, 4) or (N, 4, 4) at q (n,) or (N, n)."""
        ...

    def fk_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose(s) and geometric Jacobian(s) (6, n) or (N, 6, n), base frame."""
        ...


class ModelFile(Protocol):
    """The model file a loaded robot came from (:class:`~qpik.robots.model_source.ModelSource`)."""

    @property
    def joint_names(self) -> tuple[str, ...]: ...

    @property
    def site(self) -> str: ...

    def spec_with(self, robot: ArmDescription) -> mujoco.MjSpec:
        """The model's spec with the robot's capsules and an end-effector site."""
        ...
