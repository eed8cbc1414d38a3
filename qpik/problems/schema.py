r"""The format of problem files (``problems/*.toml``) and the typed :class:`Problem` they load into.

Found and loaded by :mod:`qpik.problems.files`, read and checked by :mod:`qpik.problems.reader`.

Format (TOML; every key below is the whole vocabulary: an unknown key is an error)::

    name = "..."              # optional, defaults to the file stem
    kind = "ik"               # required: "ik" | "track" | "reach" | "plan"
    description = "..."       # optional, one line
    source = "..."            # optional: paper, equations, tables

    [robot]
    name = "nammoto7"         # a catalog name (qpik.CATALOG), or
    # model = "arm.urdf"      # an MJCF/URDF file (relative to this file's folder), loaded by
    #                         # qpik.load_robot with the optional base, tip (strings), joints
    #                         # (list of strings), collision_only (bool) and package_map (table)
    q_min = [7 floats]        # optional overrides (rad), each shape (7,)
    q_max = [7 floats]        #   (rad)
    v_max = [7 floats]        #   (rad/s, > 0)
    q_home = [7 floats]       #   (rad)

    [target]                  # required; exactly one of the five forms:
    # 1. explicit pose(s), 4x4 rows; one pose or a list of poses
    pose = [[r11, r12, r13, px], [..], [..], [0, 0, 0, 1]]
    # 2. rotation + position. `rotation` is written BY ROWS: its COLUMNS are the
    #    end-effector axes (n, t, b) = (x, y, z) in the base frame (m for position)
    rotation = [[nx, tx, bx], [ny, ty, by], [nz, tz, bz]]
    position = [px, py, pz]
    sweep = { axis = "z", start = 0.3, stop = 0.9, num = 25 }   # optional: the
    #    pose is repeated with position[axis] = linspace(start, stop, num)
    project = true            # forms 1-2, optional (default false): project the
    #    rotation onto SO(3); without it a rotation that is not orthonormal
    #    within 1e-6 is an error
    # 3. joint configuration(s) (rad): poses = fk(q); q (7,) or (N, 7)
    q = [7 floats]
    # 4. seeded random set: q = np.random.default_rng(seed).uniform(q_min, q_max,
    #    size=(count, 7)) (limits after overrides), poses = fk(q)
    random = { seed = 0, count = 100 }
    # 5. a named path formula (qpik.problems.paths.PATHS) and its parameters
    path = "zheng2019"
    [target.path_params]
    reading = "relative"

    [parameter]               # kinds "ik" and "plan" only, optional; exactly one of:
    value = -0.80             #   the redundancy parameter δ or ψ (rad)
    values = [-0.8, 0.0]      #   a list
    sweep = { start = -3.14159, stop = 3.14159, num = 73 }   # linspace, inclusive

    [[obstacles]]             # optional, any number; `name` is optional on each
    type = "sphere"           # center (3,), radius > 0
    # type = "capsule"        # p0 (3,), p1 (3,), radius > 0
    # type = "box"            # center (3,), half_extents (3,) > 0, rotation (3x3 rows, optional),
    #                         # project (optional, default false)
    # type = "halfspace"      # normal (3,) != 0, offset: the solid normal·x <= offset
    # (read by qpik.geometry.shape_from_spec, the one obstacle parser)

    [solver]                  # optional: the runner's settings, the keys of SOLVER_KEYS[kind] only
    [expected]                # optional, free-form: figures from the paper; lists of
                              # numbers become arrays (e.g. q = [[..7..], ...]: float (16, 7))

Kinds and targets: ``ik`` and ``reach`` need poses (forms 1-4), ``track`` a path
(form 5), ``plan`` either.

``[solver]`` keys: :data:`SOLVER_KEYS` lists, per kind, every key its runner reads, with
its default and its values; an unknown key is an error that names the closest known
one (a typo such as ``d_saef`` is never ignored), and :attr:`Problem.solver` holds every
key of the kind (the file's value or the default).

All positions and obstacle data are in the robot's base frame, metres. Errors
raise :class:`qpik.core.errors.ProblemFileError` naming the file and the field.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from qpik.core.errors import ProblemFileError
from qpik.geometry.paths import TargetPath
from qpik.geometry.shapes import Shape
from qpik.objectives import NAMES as OBJECTIVE_NAMES
from qpik.robots.robot import Robot

Kind = Literal["ik", "track", "reach", "plan"]
KINDS: tuple[str, ...] = ("ik", "track", "reach", "plan")


@dataclass(frozen=True)
class Setting:
    """One ``[solver]`` key: its default and the values it takes.

    Attributes:
        default: the value when the file omits the key (``None``: the runner decides, see ``doc``).
        doc: what it is, with its unit.
        integer: an integer (else a float).
        positive: the value must be > 0 (else ≥ 0, or any integer).
        choices: the words it takes (then it is a string, one of them).
        minimum, maximum: the bounds of an integer (inclusive; None: the sign rule above only).
    """

    default: float | int | str | None
    doc: str
    integer: bool = False
    positive: bool = False
    choices: tuple[str, ...] = ()
    minimum: int | None = None
    maximum: int | None = None


MAX_COUNT = 100_000
"""The largest count of a target (``random.count``, ``sweep.num``) or a ``[parameter]`` sweep."""
MAX_WAYPOINTS = 20_000
"""The largest ``[solver] waypoints`` of a ``plan`` problem."""
MAX_RESOLUTION = 20_000
"""The largest ``[solver] resolution`` of a ``plan`` problem (parameter values per branch)."""
MAX_GRID = 10_000_000
"""The largest waypoints × resolution of a ``plan`` problem: the DP's grid per branch (its memory and time)."""


_GAINS = {
    "kp_position": Setting(50.0, "position gain of the frame task, 1/s"),
    "kp_orientation": Setting(50.0, "orientation gain of the frame task, 1/s"),
    "manipulability_weight": Setting(0.0, "weight of the manipulability task"),
}
SOLVER_KEYS: dict[str, dict[str, Setting]] = {
    "ik": {"branch": Setting(None, "branch drawn in sweeps (default: the target q's, else the first)", integer=True)},
    "track": {
        "dt": Setting(0.001, "control period, s", positive=True),
        "duration": Setting(None, "simulated time, s (default: the path's duration)", positive=True),
        **_GAINS,
        "posture_weight": Setting(1e-5, "weight of the posture task"),
        "damping": Setting(1e-8, "weight of the damping task"),
    },
    "reach": {
        "dt": Setting(0.002, "control period, s", positive=True),
        "duration": Setting(5.0, "simulated time, s", positive=True),
        **_GAINS,
        "posture_weight": Setting(1e-3, "weight of the posture task"),
        "damping": Setting(1e-4, "weight of the damping task"),
        "d_safe": Setting(0.02, "safety distance of the velocity dampers, m", positive=True),
        "d_influence": Setting(0.10, "influence distance of the velocity dampers, m", positive=True),
        "xi": Setting(0.5, "largest approach speed of the velocity dampers, m/s", positive=True),
    },
    "plan": {
        "objective": Setting(
            "none",
            "the point objective integrated along the path (qpik.objectives)",
            choices=("none", *OBJECTIVE_NAMES),
        ),
        "objective_weight": Setting(1.0, "weight of the objective beside the joint motion"),
        "max_joint_step": Setting(0.1, "largest move of any joint between consecutive waypoints, rad", positive=True),
        "d_safe": Setting(0.02, "smallest capsule–obstacle distance, m", positive=True),
        "resolution": Setting(
            None,
            "parameter values per branch in the DP's grid (even; default 720, 64 on an arm of the 1-D search)",
            integer=True,
            positive=True,
            minimum=8,
            maximum=MAX_RESOLUTION,
        ),
        "reconfigure": Setting(
            "forbid",
            "without a continuous plan: report it, or plan the fewest reconfigurations",
            choices=("forbid", "fewest"),
        ),
        "waypoints": Setting(
            101, "waypoints sampled from a path target", integer=True, positive=True, minimum=2, maximum=MAX_WAYPOINTS
        ),
        "a_max": Setting(None, "joint acceleration limit of every joint along a path target, rad/s²", positive=True),
        "branch": Setting(None, "the one branch the plan may use (default: every branch)", integer=True),
        "baseline_branch": Setting(
            None, "branch of the constant-parameter baselines (default: the plan's first)", integer=True
        ),
    },
}
"""Per kind, every ``[solver]`` key its runner (:mod:`qpik.problems.runners`) reads: the one list of them."""


@dataclass(frozen=True, eq=False)
class Problem:
    """One problem file, checked and converted.

    Attributes:
        name, kind, description, source: as in the file (``name`` defaults to the stem).
        robot: the catalog robot with the file's limit overrides applied.
        poses: target poses (N, 4, 4), base frame, or ``None`` for a path target.
        q_targets: (N, 7) configurations the poses were made from (target forms
            ``q`` and ``random``), else ``None``.
        path: the :class:`~qpik.geometry.paths.TargetPath` of form ``path``, else ``None``.
        params: redundancy parameter values (M,) in rad, or ``None``.
        obstacles: the obstacle shapes (:mod:`qpik.geometry`, world frame), built by
            :func:`qpik.geometry.shape_from_spec`; an obstacle without a ``name`` is
            named by its place in the file, ``"obstacles[i]"``.
        solver: the ``[solver]`` settings: every key of :data:`SOLVER_KEYS` for the kind, the file's
            value (checked and converted) or the default.
        expected: the ``[expected]`` table, numeric lists as arrays (int if all are integers, else float).
        file: the path it was read from.
    """

    name: str
    kind: Kind
    description: str
    source: str
    robot: Robot
    poses: np.ndarray | None
    q_targets: np.ndarray | None
    path: TargetPath | None
    params: np.ndarray | None
    obstacles: tuple[Shape, ...]
    solver: dict[str, Any]
    expected: dict[str, Any]
    file: Path

    def expected_number(self, key: str, default: float | None = None) -> float | None:
        """``[expected] key`` as a finite float (``default`` if absent); :class:`ProblemFileError` if not a number."""
        if key not in self.expected:
            return default
        value = self.expected[key]
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
            raise ProblemFileError(f"{self.file}: expected.{key}: expected a finite number, got {value!r}")
        return float(value)
