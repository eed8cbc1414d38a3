"""Lines on stderr for long work, so that nothing runs for long without a word.

A piece of work says nothing for its first :data:`QUIET` seconds (most calls end before), then one line, then
one every :data:`TICK` seconds, each with its count and the time so far, and one when it ends. The compiles of
:mod:`qpik.native.build` follow the same rhythm.
"""

from __future__ import annotations

import sys
import time

QUIET = 2.0
"""Seconds a piece of work runs before it says what it does."""
TICK = 8.0
"""Seconds between its progress lines after that."""


class Progress:
    """Progress of ``total`` steps of ``what`` (words), as ``qpik: <what>: <done>/<total> (<elapsed> s)`` lines on
    stderr: after :data:`QUIET` s, every :data:`TICK` s, and at :meth:`finish` once it has spoken (``enabled``
    False: never)."""

    def __init__(self, what: str, total: int, enabled: bool = True):
        self.what, self.total, self.enabled = what, int(total), enabled
        self.start = time.monotonic()
        self._next = self.start + QUIET
        self.spoken = False

    def __call__(self, done: int) -> None:
        """``done`` steps are finished: a line if it is time for one."""
        now = time.monotonic()
        if self.enabled and now >= self._next:
            self._say(done, now)
            self._next = now + TICK

    def finish(self, done: int | None = None) -> None:
        """The work ended after ``done`` steps (default all): a last line if any was printed."""
        if self.spoken:
            self._say(self.total if done is None else done, time.monotonic())

    def _say(self, done: int, now: float) -> None:
        print(f"qpik: {self.what}: {done}/{self.total} ({now - self.start:.0f} s)", file=sys.stderr, flush=True)
        self.spoken = True
