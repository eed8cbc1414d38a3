"""What is built once per robot (solvers, compiled functions, Taylor models), owned by the robot.

Every :class:`~qpik.robots.robot.Robot` holds one :class:`RobotCache` (``robot.cache``): what is built for
it lives as long as it does and is freed with it, a copy (``dataclasses.replace``, pickling to another
process) starts empty, and nothing is keyed by the robot's ``id()``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable
from typing import TypeVar

T = TypeVar("T")
_MISSING = object()


class RobotCache:
    """Values by key, each built at most once (also when several threads ask at once)."""

    def __init__(self) -> None:
        self._values: dict[Hashable, object] = {}
        self._lock = threading.RLock()  # re-entrant: building one value may ask for another

    def get(self, key: Hashable, build: Callable[..., T], *args: object) -> T:
        """The value of ``key``, from ``build(*args)`` the first time it is asked for."""
        value = self._values.get(key, _MISSING)
        if value is _MISSING:
            with self._lock:
                value = self._values.get(key, _MISSING)
                if value is _MISSING:
                    value = self._values[key] = build(*args)
        return value  # type: ignore[return-value]

    def __len__(self) -> int:
        return len(self._values)

    def __reduce__(self) -> tuple:
        return (RobotCache, ())  # compiled code and locks stay in their process: a copy starts empty
