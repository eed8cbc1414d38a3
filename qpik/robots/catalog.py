"""The built-in arms, with the sources of their DH tables.

Limits for ``nammoto7`` and ``zheng7`` are not given by their papers; the
values here are plausible iiwa-like choices (reasons beside each) and every
problem file can override them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from qpik.core.errors import UnknownRobotError
from qpik.robots.dh import DHChain
from qpik.robots.locked_joint import find_locked_joint, layout_words
from qpik.robots.robot import Robot, default_capsules

PI = np.pi
DEG = PI / 180.0

IIWA_Q_MAX = np.array([170, 120, 170, 120, 170, 120, 175]) * DEG
IIWA_V_MAX = np.array([85, 85, 100, 75, 130, 135, 135]) * DEG
# KUKA's iiwa data sheet gives no joint acceleration or jerk limits: these are chosen, at Franka's
# values for the like joints (below), and every controller limit can override them.
IIWA_A_MAX = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
IIWA_J_MAX = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])


def nammoto7() -> Robot:
    """Offset-shoulder arm of Nammoto & Kosuge 2012 (Table 1 with Table 3 lengths); closed form in δ."""
    a1, d1, d3, d5, d7 = 0.100, 0.320, 0.400, 0.350, 0.065
    chain = DHChain(
        a=(a1, 0, 0, 0, 0, 0, 0),
        d=(d1, 0, d3, 0, -d5, 0, -d7),
        alpha=(PI / 2, -PI / 2, PI / 2, -PI / 2, PI / 2, PI / 2, 0),
        offset=(0, 0, 0, PI / 2, 0, PI, 0),
    )
    # Nammoto & Kosuge 2012 gives no limits. Table 4 needs |θ4| up to 2.96 rad and |θ3| up to
    # 2.18 rad, so iiwa's ±120° on the even joints would forbid most of its
    # branches: take ±170° on joints 1-5, iiwa's ±120° on the wrist-pitch θ6 and
    # ±175° on θ7.
    q_max = np.array([170, 170, 170, 170, 170, 120, 175]) * DEG
    return Robot(
        name="nammoto7",
        chain=chain,
        q_min=-q_max,
        q_max=q_max,
        v_max=IIWA_V_MAX.copy(),
        a_max=IIWA_A_MAX.copy(),
        j_max=IIWA_J_MAX.copy(),
        q_home=np.array([0.0, -0.5, 0.0, -0.6, 0.0, 0.8, 0.0]),
        capsules=default_capsules(chain, (0.06, 0.06, 0.055, 0.05, 0.05, 0.045, 0.04)),
        closed_form="offset_shoulder",
        source="Nammoto & Kosuge 2012, Tables 1 and 3",
        notes="limits chosen (not in the paper): ±170° on joints 1-5, ±120° on joint 6, ±175° on joint 7",
    )


def iiwa14() -> Robot:
    """KUKA LBR iiwa 14 R820, S-R-S; closed form in the arm angle ψ."""
    chain = DHChain(
        a=(0,) * 7,
        d=(0.36, 0, 0.42, 0, 0.40, 0, 0.126),
        alpha=(-PI / 2, PI / 2, PI / 2, -PI / 2, -PI / 2, PI / 2, 0),
    )
    return Robot(
        name="iiwa14",
        chain=chain,
        q_min=-IIWA_Q_MAX,
        q_max=IIWA_Q_MAX.copy(),
        v_max=IIWA_V_MAX.copy(),
        a_max=IIWA_A_MAX.copy(),
        j_max=IIWA_J_MAX.copy(),
        q_home=np.array([0.0, 0.5, 0.0, -1.2, 0.0, 0.9, 0.0]),
        capsules=default_capsules(chain, (0.08, 0.08, 0.07, 0.07, 0.065, 0.06, 0.05)),
        closed_form="srs",
        source="KUKA LBR iiwa 14 R820 datasheet; DH matching the KUKA URDF joint signs",
    )


def zheng7() -> Robot:
    """Offset-wrist arm of Zheng et al. 2019 (Table I); no closed form."""
    chain = DHChain(
        a=(0, 0.518, 0.428, 0, 0, 0, 0),
        d=(0.149, 0.204, -0.204, 0.140, 0.140, 0.140, 0.082),
        alpha=(PI / 2, 0, 0, -PI / 2, PI / 2, -PI / 2, 0),
    )
    # Zheng et al. 2019 gives no limits. Its initial configuration has θ4 = -120° and
    # θ6 = 90°, so iiwa's ±120° would start it on a limit: take ±170° on
    # joints 1-6 and ±175° on joint 7, with iiwa's velocity limits.
    q_max = np.array([170, 170, 170, 170, 170, 170, 175]) * DEG
    return Robot(
        name="zheng7",
        chain=chain,
        q_min=-q_max,
        q_max=q_max,
        v_max=IIWA_V_MAX.copy(),
        a_max=IIWA_A_MAX.copy(),
        j_max=IIWA_J_MAX.copy(),
        q_home=np.array([0.0, 1.0472, -0.5236, -2.0944, 0.0, 1.5708, -1.5708]),
        capsules=default_capsules(chain, (0.07, 0.06, 0.055, 0.05, 0.05, 0.045, 0.04)),
        closed_form=None,
        source="Zheng et al. 2019, Table I",
        notes="limits chosen (not in the paper): ±170° on joints 1-6, ±175° on joint 7",
    )


def panda() -> Robot:
    """Franka Emika Panda (modified DH, offsets at elbow and wrist), flange as end-effector; closed form with q7
    locked (:mod:`qpik.analytic.locked_joint`)."""
    tool = np.eye(4)
    tool[2, 3] = 0.107
    chain = DHChain(
        a=(0, 0, 0, 0.0825, -0.0825, 0, 0.088),
        d=(0.333, 0, 0.316, 0, 0.384, 0, 0),
        alpha=(0, -PI / 2, PI / 2, PI / 2, -PI / 2, PI / 2, PI / 2),
        convention="modified",
        tool=tool,
    )
    return Robot(
        name="panda",
        chain=chain,
        q_min=np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]),
        q_max=np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]),
        v_max=np.array([2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100]),
        a_max=np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]),  # Franka's robot and interface specifications
        j_max=np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]),
        q_home=np.array([0.0, -PI / 4, 0.0, -3 * PI / 4, 0.0, PI / 2, PI / 4]),
        capsules=default_capsules(chain, (0.07, 0.07, 0.065, 0.065, 0.06, 0.055, 0.05)),
        closed_form="locked_joint",
        source="Franka Emika Panda documentation (DH, limits)",
        notes=locked_joint_notes(chain),
    )


def locked_joint_notes(chain: DHChain) -> str:
    """The notes of an arm of the locked-q7 family: its geometry in words (:mod:`qpik.robots.locked_joint`)."""
    found, why = find_locked_joint(chain)
    if found is None:
        raise ValueError(f"not a locked-q7 arm: {why}")
    return found.describe(layout_words(chain))


CATALOG: dict[str, Callable[[], Robot]] = {
    "nammoto7": nammoto7,
    "iiwa14": iiwa14,
    "zheng7": zheng7,
    "panda": panda,
}
"""The catalog arms by name, each with the function that builds its :class:`Robot` (:func:`catalog_robot`)."""

_cache: dict[str, Robot] = {}


def catalog_robot(name: str) -> Robot:
    """A built-in arm by name: ``"nammoto7"``, ``"iiwa14"``, ``"zheng7"`` or ``"panda"``.

    The same object is returned on every call (robots are immutable).
    """
    if not isinstance(name, str) or name not in CATALOG:
        raise UnknownRobotError(f"unknown robot {name!r}; known: {', '.join(CATALOG)}")
    if name not in _cache:
        _cache[name] = CATALOG[name]()
    return _cache[name]
