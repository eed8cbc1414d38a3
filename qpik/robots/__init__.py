"""Kinematic models: serial chains (DH tables among them), the arm catalog, MJCF/URDF loading, MJCF twins."""

from qpik.robots.catalog import CATALOG
from qpik.robots.chain import Joint, SerialChain
from qpik.robots.dh import DHChain
from qpik.robots.loader import load_robot
from qpik.robots.robot import LinkCapsule, Robot

__all__ = ["CATALOG", "DHChain", "Joint", "LinkCapsule", "Robot", "SerialChain", "load_robot"]
