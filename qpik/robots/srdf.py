"""The allowed self-collision pairs of an SRDF file (MoveIt's ``disable_collisions``).

An SRDF names links; qpik's capsules are per chain link ``k`` (1..n, the body joint ``k`` moves).
:func:`link_names` gives the body name of each chain link in the robot's MuJoCo model (for a
loaded arm the names of its URDF/MJCF, for a catalog arm ``link1`` … ``link7``), and
:func:`disabled_links` maps an SRDF's pairs onto those links.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING

from qpik.core.errors import InputError

if TYPE_CHECKING:
    from qpik.robots.robot import Robot


def link_names(robot: Robot) -> tuple[str, ...]:
    """The name of chain link ``k`` = 1..n: the MuJoCo body of the arm's joint ``k`` (``names[k - 1]``)."""
    import mujoco

    model = robot.mj_model()
    out = []
    for name in robot.joint_names:
        body = model.jnt_bodyid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)]
        out.append(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body))
    return tuple(out)


def read_disabled(srdf: str | os.PathLike) -> set[frozenset[str]]:
    """The ``{link1, link2}`` name pairs of every ``<disable_collisions>`` of an SRDF (a path or its text).

    Raises:
        InputError: the file cannot be read or is not XML.
    """
    text = str(srdf)
    try:
        if not text.lstrip().startswith("<"):
            with open(text, encoding="utf-8") as f:
                text = f.read()
        root = ET.fromstring(text)
    except (OSError, ET.ParseError) as exc:
        raise InputError(f"srdf: cannot read {str(srdf)[:80]!r}: {exc}") from None
    out = set()
    for el in root.iter("disable_collisions"):
        a, b = el.get("link1"), el.get("link2")
        if not a or not b:
            raise InputError("srdf: <disable_collisions> needs link1 and link2")
        out.add(frozenset((a, b)))
    return out


def disabled_links(robot: Robot, srdf: str | os.PathLike) -> set[tuple[int, int]]:
    """The chain-link pairs ``(k, l)``, k < l (1..n), that an SRDF disables (pairs naming other links are
    ignored: qpik has capsules only on the chain's links)."""
    names = {name: k for k, name in enumerate(link_names(robot), start=1)}
    out = set()
    for pair in read_disabled(srdf):
        ks = sorted(names[n] for n in pair if n in names)
        if len(ks) == 2:
            out.add((ks[0], ks[1]))
    return out
