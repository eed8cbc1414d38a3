"""A problem's pieces as one value (:class:`~qpik.scene.scene.Scene`) and what it evaluates."""

from qpik.scene.scene import Scene

__all__ = ["Scene"]
