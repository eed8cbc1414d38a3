"""``qpik demo``: one section per capability, run in order.

Each module here defines ``TITLE`` and ``run(out: pathlib.Path) -> None``,
prints what it shows and writes its pictures under ``out``. ``ORDER`` fixes
the order of the sections.
"""

from __future__ import annotations

import importlib
from pathlib import Path

ORDER = ("catalog", "closed_form", "best", "plan", "controller")


def run_all(out: Path, only: list[str] | None = None) -> None:
    """Run the sections of ``ORDER`` (or ``only`` those), writing pictures under ``out``.

    Without OpenGL one line says that the pictures of the arms are skipped; the
    tables and the matplotlib plots are made all the same.
    """
    from qpik.native.build import cache_dir, compiler
    from qpik.render.pictures import unavailable_reason

    out.mkdir(parents=True, exist_ok=True)
    cache, cc = cache_dir(), compiler()
    if cc and not any(cache.glob("*.so")):
        print(
            f"first run: qpik compiles its functions with {cc} as they are first used (the whole tour takes"
            f" about a minute and a half on 2 cores), cached in {cache}; later runs skip the compiles"
        )
    reason = unavailable_reason()
    if reason:
        print(f"pictures of the arms skipped: {reason} (tables and plots still follow)")
    for name in ORDER:
        if only and name not in only:
            continue
        module = importlib.import_module(f"{__name__}.{name}")
        print(f"\n== {module.TITLE} ==")
        module.run(out)
