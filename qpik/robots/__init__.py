"""Kinematic models: DH chains, the arm catalog, MJCF twins."""

from qpik.robots.catalog import CATALOG, load_robot
from qpik.robots.dh import DHChain
from qpik.robots.robot import LinkCapsule, Robot

__all__ = ["CATALOG", "DHChain", "LinkCapsule", "Robot", "load_robot"]
