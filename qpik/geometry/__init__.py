"""Obstacle shapes and closed-form signed distances / witness points to link capsules."""

from qpik.geometry.distance import Distances, ObstacleSet, PairDistance, distance, distances
from qpik.geometry.shapes import Box, Capsule, HalfSpace, Shape, Sphere, obstacles_from_specs, shape_from_spec

__all__ = [
    "Box",
    "Capsule",
    "Distances",
    "HalfSpace",
    "ObstacleSet",
    "PairDistance",
    "Shape",
    "Sphere",
    "distance",
    "distances",
    "obstacles_from_specs",
    "shape_from_spec",
]
