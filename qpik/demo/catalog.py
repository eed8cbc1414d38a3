"""Demo section: the built-in arms, their numbers and a picture of each at home."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qpik.robots.catalog import CATALOG
from qpik.robots.loader import load_robot
from qpik.robots.robot import Robot

TITLE = "Catalog"
SAMPLES = 4000


def reach(robot: Robot, samples: int = SAMPLES, seed: int = 0) -> float:
    """Largest distance (m) of the end-effector from the base origin over uniform samples within the limits."""
    q = np.random.default_rng(seed).uniform(robot.q_min, robot.q_max, (samples, robot.dof))
    return float(np.linalg.norm(robot.fk(q)[:, :3, 3] - robot.chain.base[:3, 3], axis=1).max())


def limits_text(robot: Robot) -> str:
    """Joint limits in degrees: ``±170`` for symmetric ones, ``lo..hi`` otherwise."""
    parts = []
    for lo, hi in zip(np.degrees(robot.q_min), np.degrees(robot.q_max)):
        parts.append(f"±{hi:.0f}" if abs(lo + hi) < 1e-6 else f"{lo:.0f}..{hi:.0f}")
    return " ".join(parts)


def run(out: Path) -> None:
    from qpik.render.pictures import render_configurations, unavailable_reason

    robots = [load_robot(name) for name in CATALOG]
    header = f"{'arm':9} {'closed form':18} {'DH':9} {'reach':>7}  joint limits (deg)"
    print(header)
    print("-" * len(header))
    for r in robots:
        kind = {"offset_shoulder": "offset shoulder δ", "srs": "S-R-S ψ", "locked_joint": "q7 locked"}.get(
            r.closed_form or "", "none"
        )
        print(f"{r.name:9} {kind:18} {r.chain.convention:9} {reach(r):6.3f}m  {limits_text(r)}")
    print("\nsources:")
    for r in robots:
        print(f"  {r.name:9} {r.source}" + (f" ({r.notes})" if r.notes else ""))
    if unavailable_reason():
        return
    print()
    for r in robots:
        path = out / f"catalog_{r.name}.png"
        render_configurations(r, r.q_home, path)
        print(f"wrote {path} ({r.name} at home)")
