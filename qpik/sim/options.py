"""What :func:`qpik.sim.simulate` records and how it reports, as one value."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SimOptions:
    """The log of one run of :func:`qpik.sim.simulate` (each checked by it, :class:`~qpik.core.errors.InputError`
    naming the field).

    Attributes:
        record_every: log every this many steps (and always the last state), an integer ≥ 1; at most
            :data:`qpik.sim.run.MAX_RECORDS` records, :data:`qpik.sim.run.MAX_STEPS` steps.
        v_max: velocity limits (n,), rad/s, for the summary; None: the robot's.
        d_safe: safety distance, m, to mark on plots (None: none).
        label: a name for plots and summaries.
        progress: show a tqdm bar; None: when stderr is a terminal.
    """

    record_every: int = 1
    v_max: np.ndarray | None = None
    d_safe: float | None = None
    label: str = "run"
    progress: bool | None = None
