"""A clock for the time columns of qpik's reports: the work of a call, without building its functions.

The first call of a solver traces its CasADi functions and compiles them (:mod:`qpik.native.compiled`),
which can take far longer than the solve itself. A :class:`Stopwatch` runs from its creation and
stops while a section runs under :meth:`Stopwatch.paused`: the solvers build their functions there,
so that a reported time is the same on the first call and on later ones.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager


class Stopwatch:
    """Seconds from its creation to :meth:`stop`, less the sections run under :meth:`paused` (wall clock,
    ``time.perf_counter``)."""

    def __init__(self) -> None:
        self._start = time.perf_counter()
        self._excluded = 0.0
        self._depth = 0
        self._paused_at = 0.0
        self._stopped: float | None = None

    @property
    def running(self) -> bool:
        """False inside a :meth:`paused` section and after :meth:`stop`."""
        return self._depth == 0 and self._stopped is None

    def stop(self) -> float:
        """Stop the clock for good (a later call changes nothing) and return :meth:`elapsed`."""
        if self._stopped is None:
            self._stopped = self.elapsed()
        return self._stopped

    @contextmanager
    def paused(self) -> Iterator[None]:
        """Stop the clock for the body (sections may nest)."""
        if self._depth == 0:
            self._paused_at = time.perf_counter()
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            if self._depth == 0:
                self._excluded += time.perf_counter() - self._paused_at

    def elapsed(self) -> float:
        """Seconds counted so far."""
        if self._stopped is not None:
            return self._stopped
        now = self._paused_at if self._depth else time.perf_counter()
        return now - self._start - self._excluded
