"""Kinematic models: serial chains (DH tables among them), the arm catalog, MJCF/URDF loading, MJCF twins."""

from typing import TYPE_CHECKING

from qpik.core.lazy import exports

if TYPE_CHECKING:
    from qpik.robots.catalog import CATALOG
    from qpik.robots.chain import SerialChain
    from qpik.robots.dh import DHChain
    from qpik.robots.joint import Joint
    from qpik.robots.loader import load_robot
    from qpik.robots.robot import LinkCapsule, Robot

__getattr__, __dir__ = exports(
    __name__,
    {
        "qpik.robots.catalog": ("CATALOG",),
        "qpik.robots.chain": ("SerialChain",),
        "qpik.robots.dh": ("DHChain",),
        "qpik.robots.joint": ("Joint",),
        "qpik.robots.loader": ("load_robot",),
        "qpik.robots.robot": ("LinkCapsule", "Robot"),
    },
)

__all__ = ["CATALOG", "DHChain", "Joint", "LinkCapsule", "Robot", "SerialChain", "load_robot"]
