"""``qpik demo``: one section per capability, run in order.

Each module here defines ``TITLE`` and ``run(out: pathlib.Path) -> None``,
prints what it shows and writes its pictures under ``out``. ``ORDER`` fixes
the order of the sections.
"""

from __future__ import annotations

import importlib
from pathlib import Path

ORDER = ("catalog", "closed_form", "controller")


def run_all(out: Path, only: list[str] | None = None) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name in ORDER:
        if only and name not in only:
            continue
        module = importlib.import_module(f"{__name__}.{name}")
        print(f"\n== {module.TITLE} ==")
        module.run(out)
