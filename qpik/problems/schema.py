r"""Problem files (``problems/*.toml``) and the typed :class:`Problem` they load into.

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

import dataclasses
import difflib
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Literal

import numpy as np

from qpik.core.errors import InputError, ProblemFileError, UnknownRobotError
from qpik.core.validate import finite_array
from qpik.core.validate import pose as check_pose
from qpik.geometry.paths import TargetPath
from qpik.geometry.shapes import Shape, shape_from_spec
from qpik.objectives import NAMES as OBJECTIVE_NAMES
from qpik.problems.paths import PATHS
from qpik.robots.loader import load_robot
from qpik.robots.model_files import MeshOptions
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
            720,
            "parameter values per branch in the DP's grid (even)",
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


def problems_folder() -> Path:
    """The folder of the problem files shipped with qpik (the package ``qpik.problem_files``)."""
    return Path(str(resources.files("qpik.problem_files")))


def problem_files(folder: Path | None = None) -> list[Path]:
    """The ``*.toml`` files of ``folder`` (default :func:`problems_folder`), sorted by name."""
    return sorted((folder or problems_folder()).glob("*.toml"))


def list_problems(folder: Path | None = None) -> list[Problem]:
    """Every problem of ``folder`` (default :func:`problems_folder`), loaded, sorted by file name."""
    return [load(f) for f in problem_files(folder)]


def _path(value: object, what: str) -> Path:
    if not isinstance(value, str | Path) or not str(value):
        raise ProblemFileError(f"{what}: expected a file path or a problem name, got {value!r}")
    return Path(value)


def find_problem(name_or_path: str | Path) -> Path:
    """A problem file: ``name_or_path`` itself if it is a file, else the shipped problem of that name.

    A name (no folder, no ``.toml`` suffix needed) is looked up among the shipped problems
    (:func:`problems_folder`), never in the working folder.
    """
    p = _path(name_or_path, "problem")
    if p.is_file():
        return p
    if p.parent != Path(".") or (p.suffix and p.suffix != ".toml"):
        raise ProblemFileError(f"{name_or_path}: no such file")
    candidate = problems_folder() / f"{p.stem}.toml"
    if candidate.is_file():
        return candidate
    shipped = ", ".join(f.stem for f in problem_files())
    raise ProblemFileError(f"{name_or_path}: no such file, and no shipped problem of that name (they are: {shipped})")


def load(path: str | Path) -> Problem:
    """Read and check one problem file; see the module docstring for the format."""
    return _Reader(_path(path, "problem file")).problem()


class _Reader:
    """Reads one file; every error names the file and the field."""

    def __init__(self, file: Path):
        self.file = file

    def fail(self, field: str, message: str) -> ProblemFileError:
        return ProblemFileError(f"{self.file}: {field}: {message}")

    # ---- generic checks -----------------------------------------------------

    def table(self, value: Any, field: str, required: set[str], optional: set[str] = frozenset()) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(field, f"expected a table, got {type(value).__name__}")
        missing = required - set(value)
        if missing:
            raise self.fail(field, f"missing {', '.join(sorted(missing))}")
        unknown = set(value) - required - set(optional)
        if unknown:
            raise self.fail(field, f"unknown key(s) {', '.join(sorted(unknown))}")
        return value

    def array(self, value: Any, field: str, shape: tuple[int | None, ...]) -> np.ndarray:
        try:
            return finite_array(value, field, shape).copy()
        except InputError as exc:
            raise ProblemFileError(f"{self.file}: {exc}") from None

    def stacked(self, value: Any, field: str, shape: tuple[int, ...]) -> np.ndarray:
        """One item of ``shape`` or a list of them, as (N, *shape)."""
        arr = self.array(value, field, None)
        return self.array(arr[None] if arr.ndim == len(shape) else arr, field, (None, *shape))

    def free(self, value: Any, field: str) -> dict[str, Any]:
        """A free-form table."""
        if not isinstance(value, dict):
            raise self.fail(field, f"expected a table, got {type(value).__name__}")
        return value

    def number(self, value: Any, field: str, positive: bool = False) -> float:
        x = float(self.array(value, field, ()))
        if positive and not x > 0:
            raise self.fail(field, f"must be > 0, got {x}")
        return x

    def count(self, value: Any, field: str) -> int:
        if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= MAX_COUNT:
            raise self.fail(field, f"expected an integer from 1 to {MAX_COUNT}, got {value!r}")
        return value

    def text(self, value: Any, field: str) -> str:
        if not isinstance(value, str):
            raise self.fail(field, f"expected a string, got {type(value).__name__}")
        return value

    def poses(self, T: np.ndarray, field: str, project: bool) -> np.ndarray:
        try:
            T, _ = check_pose(T, field, project)
        except InputError as exc:  # includes RotationError
            raise ProblemFileError(f"{self.file}: {exc}") from None
        return T.reshape(-1, 4, 4)

    # ---- sections -----------------------------------------------------------

    def problem(self) -> Problem:
        try:
            with open(self.file, "rb") as fh:
                data = tomllib.load(fh)
        except FileNotFoundError:
            raise ProblemFileError(f"{self.file}: no such file") from None
        except OSError as exc:  # a folder, no permission, ...
            raise ProblemFileError(f"{self.file}: cannot be read ({exc.strerror})") from None
        except tomllib.TOMLDecodeError as exc:
            raise ProblemFileError(f"{self.file}: not valid TOML ({exc})") from None
        optional = {"name", "description", "source", "parameter", "obstacles", "solver", "expected"}
        self.table(data, "top level", {"kind", "robot", "target"}, optional)
        kind = self.text(data["kind"], "kind")
        if kind not in KINDS:
            raise self.fail("kind", f"unknown kind {kind!r}; known: {', '.join(KINDS)}")
        robot = self.robot(data["robot"])
        poses, q_targets, path = self.target(data["target"], robot)
        if kind == "track" and path is None:
            raise self.fail("target", "kind 'track' needs a path target (target.path)")
        if kind in ("ik", "reach") and poses is None:
            raise self.fail("target", f"kind {kind!r} needs poses (pose, rotation+position, q or random), not a path")
        params = None
        if "parameter" in data:
            if kind not in ("ik", "plan"):
                raise self.fail("parameter", f"only kinds 'ik' and 'plan' take a parameter, not {kind!r}")
            params = self.parameter(data["parameter"])
        obstacles = data.get("obstacles", [])
        if not isinstance(obstacles, list):
            raise self.fail("obstacles", "expected an array of tables ([[obstacles]])")
        solver = self.solver(data.get("solver", {}), kind)
        if kind == "plan":
            self.plan_sizes(solver, robot, None if poses is None else len(poses))
        return Problem(
            name=self.text(data.get("name", self.file.stem), "name"),
            kind=kind,  # type: ignore[arg-type]
            description=self.text(data.get("description", ""), "description"),
            source=self.text(data.get("source", ""), "source"),
            robot=robot,
            poses=poses,
            q_targets=q_targets,
            path=path,
            params=params,
            obstacles=tuple(self.obstacle(o, f"obstacles[{i}]") for i, o in enumerate(obstacles)),
            solver=solver,
            expected={k: _numeric(v) for k, v in self.free(data.get("expected", {}), "expected").items()},
            file=self.file,
        )

    def solver(self, value: Any, kind: str) -> dict[str, Any]:
        """The ``[solver]`` table checked against :data:`SOLVER_KEYS` of ``kind``, with the defaults filled in."""
        table = self.free(value, "solver")
        known = SOLVER_KEYS[kind]
        for key in table:
            if key not in known:
                close = difflib.get_close_matches(key, known, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                keys = ", ".join(known) or "none"
                raise self.fail(f"solver.{key}", f"unknown key for kind {kind!r}{hint} (known: {keys})")
        out: dict[str, Any] = {}
        for key, setting in known.items():
            raw = table.get(key, setting.default)
            out[key] = raw if raw is None or key not in table else self.setting(raw, f"solver.{key}", setting)
        return out

    def plan_sizes(self, solver: dict[str, Any], robot: Robot, poses: int | None) -> None:
        """A ``plan`` problem's grid within :data:`MAX_GRID`, and its branches among the closed form's."""
        waypoints = solver["waypoints"] if poses is None else poses
        if waypoints * solver["resolution"] > MAX_GRID:
            size = f"{waypoints} waypoints × resolution {solver['resolution']}"
            raise self.fail("solver.resolution", f"{size} is over {MAX_GRID:,} grid points per branch; use fewer "
                            "waypoints or a lower resolution")  # fmt: skip
        for key in ("branch", "baseline_branch"):
            if solver[key] is None:
                continue
            if robot.closed_form is None:
                raise self.fail(f"solver.{key}", f"{robot.name} has no closed form, so no branches")
            ids = _branch_ids(robot.closed_form)
            if solver[key] not in ids:
                raise self.fail(
                    f"solver.{key}", f"{robot.name}'s branches are {ids[0]} to {ids[-1]}, got {solver[key]}"
                )

    def setting(self, value: Any, field: str, setting: Setting) -> float | int | str:
        if setting.choices:
            if value not in setting.choices:
                raise self.fail(field, f"expected one of {', '.join(setting.choices)}, got {value!r}")
            return value
        if setting.integer:
            if not isinstance(value, int) or isinstance(value, bool):
                raise self.fail(field, f"expected an integer, got {value!r}")
            if setting.positive and value < 1:
                raise self.fail(field, f"must be >= 1, got {value}")
            if setting.minimum is not None and value < setting.minimum:
                raise self.fail(field, f"must be >= {setting.minimum} ({setting.doc}), got {value}")
            if setting.maximum is not None and value > setting.maximum:
                raise self.fail(field, f"must be <= {setting.maximum} ({setting.doc}), got {value}")
            return value
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(field, f"expected a number ({setting.doc}), got {value!r}")
        x = self.number(value, field, positive=setting.positive)
        if x < 0:
            raise self.fail(field, f"must be >= 0, got {x}")
        return x

    def robot(self, value: Any) -> Robot:
        overrides = ("q_min", "q_max", "v_max", "q_home")
        options = {"base", "tip", "joints", "collision_only", "package_map"}
        tbl = self.table(value, "robot", set(), {"name", "model", *options, *overrides})
        if ("name" in tbl) == ("model" in tbl):
            raise self.fail("robot", "give exactly one of name (a catalog arm) and model (an MJCF/URDF file)")
        if "name" in tbl:
            if options & set(tbl):
                raise self.fail("robot", f"{', '.join(sorted(options & set(tbl)))}: only with model")
            target, kwargs, field = self.text(tbl["name"], "robot.name"), {}, "robot.name"
        else:
            target, field = str(self.file.parent / self.text(tbl["model"], "robot.model")), "robot.model"
            kwargs = {k: self.text(tbl[k], f"robot.{k}") for k in ("base", "tip") if k in tbl}
            if "joints" in tbl:
                joints = tbl["joints"]
                if not isinstance(joints, list):
                    raise self.fail("robot.joints", f"expected a list of joint names, got {type(joints).__name__}")
                kwargs["joints"] = [self.text(j, "robot.joints") for j in joints]
            meshes = {}
            if "collision_only" in tbl:
                if not isinstance(tbl["collision_only"], bool):
                    raise self.fail("robot.collision_only", "expected true or false")
                meshes["collision_only"] = tbl["collision_only"]
            if "package_map" in tbl:
                pmap = self.free(tbl["package_map"], "robot.package_map")
                meshes["package_map"] = {
                    k: str(self.file.parent / self.text(v, "robot.package_map")) for k, v in pmap.items()
                }
            if meshes:
                kwargs["meshes"] = MeshOptions(**meshes)
        try:
            robot = load_robot(target, **kwargs)
        except (UnknownRobotError, InputError) as exc:
            raise self.fail(field, str(exc)) from None
        changes = {k: self.array(tbl[k], f"robot.{k}", (robot.dof,)) for k in overrides if k in tbl}
        if not changes:
            return robot
        robot = dataclasses.replace(robot, **changes)
        if not np.all(robot.q_min < robot.q_max):
            raise self.fail("robot", "q_min must be < q_max on every joint")
        if not np.all(robot.v_max > 0):
            raise self.fail("robot.v_max", "must be > 0 on every joint")
        outside = np.flatnonzero((robot.q_home < robot.q_min) | (robot.q_home > robot.q_max))
        if "q_home" in changes and len(outside):
            joints = ", ".join(str(j + 1) for j in outside)
            raise self.fail("robot.q_home", f"outside [q_min, q_max] on joint(s) {joints}")
        return robot

    def target(self, value: Any, robot: Robot) -> tuple[np.ndarray | None, np.ndarray | None, TargetPath | None]:
        forms = {
            "pose": ({"pose"}, {"project"}),
            "rotation": ({"rotation", "position"}, {"project", "sweep"}),
            "q": ({"q"}, set()),
            "random": ({"random"}, set()),
            "path": ({"path"}, {"path_params"}),
        }
        if not isinstance(value, dict):
            raise self.fail("target", "expected a table")
        given = [f for f in forms if f in value or (f == "rotation" and "position" in value)]
        if len(given) != 1:
            names = "pose | rotation+position | q | random | path"
            raise self.fail("target", f"give exactly one of {names}; got {', '.join(given) or 'none'}")
        form = given[0]
        required, optional = forms[form]
        tbl = self.table(value, "target", required, optional)
        project = tbl.get("project", False)
        if not isinstance(project, bool):
            raise self.fail("target.project", "expected true or false")
        if form == "pose":
            T = self.stacked(tbl["pose"], "target.pose", (4, 4))
            return self.poses(T, "target.pose", project), None, None
        if form == "rotation":
            T = np.eye(4)
            T[:3, :3] = self.array(tbl["rotation"], "target.rotation", (3, 3))
            T[:3, 3] = self.array(tbl["position"], "target.position", (3,))
            T = self.poses(T, "target.rotation", project)
            if "sweep" in tbl:
                T = self.sweep(T[0], tbl["sweep"])
            return T, None, None
        if form == "q":
            q = self.stacked(tbl["q"], "target.q", (robot.dof,))
            return robot.fk(q), q, None
        if form == "random":
            rnd = self.table(tbl["random"], "target.random", {"seed", "count"})
            seed = rnd["seed"]
            if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
                raise self.fail("target.random.seed", f"expected an integer >= 0, got {seed!r}")
            count = self.count(rnd["count"], "target.random.count")
            q = np.random.default_rng(seed).uniform(robot.q_min, robot.q_max, size=(count, robot.dof))
            return robot.fk(q), q, None
        name = self.text(tbl["path"], "target.path")
        if name not in PATHS:
            raise self.fail("target.path", f"unknown path {name!r}; known: {', '.join(sorted(PATHS))}")
        params = self.free(tbl.get("path_params", {}), "target.path_params")
        try:
            path = PATHS[name](robot, params)
        except (ValueError, TypeError) as exc:  # InputError is a ValueError
            raise self.fail("target.path_params", str(exc)) from None
        return None, None, path

    def sweep(self, T: np.ndarray, value: Any) -> np.ndarray:
        tbl = self.table(value, "target.sweep", {"axis", "start", "stop", "num"})
        axes = {"x": 0, "y": 1, "z": 2}
        if tbl["axis"] not in axes:
            raise self.fail("target.sweep.axis", f"expected 'x', 'y' or 'z', got {tbl['axis']!r}")
        values = np.linspace(
            self.number(tbl["start"], "target.sweep.start"),
            self.number(tbl["stop"], "target.sweep.stop"),
            self.count(tbl["num"], "target.sweep.num"),
        )
        out = np.repeat(T[None], len(values), axis=0)
        out[:, axes[tbl["axis"]], 3] = values
        return out

    def parameter(self, value: Any) -> np.ndarray:
        if not isinstance(value, dict) or len(set(value) & {"value", "values", "sweep"}) != 1:
            raise self.fail("parameter", "give exactly one of value, values, sweep")
        tbl = self.table(value, "parameter", set(), {"value", "values", "sweep"})
        if "value" in tbl:
            return self.array(tbl["value"], "parameter.value", ()).reshape(1)
        if "values" in tbl:
            return self.array(tbl["values"], "parameter.values", (None,))
        sw = self.table(tbl["sweep"], "parameter.sweep", {"start", "stop", "num"})
        return np.linspace(
            self.number(sw["start"], "parameter.sweep.start"),
            self.number(sw["stop"], "parameter.sweep.stop"),
            self.count(sw["num"], "parameter.sweep.num"),
        )

    def obstacle(self, value: Any, field: str) -> Shape:
        if not isinstance(value, dict):
            raise self.fail(field, "expected a table with a 'type'")
        try:
            return shape_from_spec({"name": field, **value})
        except InputError as exc:
            raise self.fail(field, str(exc)) from None


def _branch_ids(closed_form: str) -> tuple[int, ...]:
    """The public branch ids of a closed form (:attr:`qpik.analytic.solver.AnalyticSolver.branch_ids`)."""
    if closed_form == "srs":
        from qpik.analytic.srs import SRSSolver

        return SRSSolver.branch_ids
    if closed_form == "locked_joint":
        from qpik.analytic.locked_joint import LockedJointSolver

        return LockedJointSolver.branch_ids
    from qpik.analytic.offset_shoulder import OffsetShoulderSolver

    return OffsetShoulderSolver.branch_ids


def _numeric(value: Any) -> Any:
    """A list of numbers (or of equal-length lists) as an int or float array; anything else unchanged."""
    if isinstance(value, list) and value:
        try:
            arr = np.asarray(value)
        except ValueError:  # ragged
            return value
        if arr.dtype.kind in "iu":
            return arr.astype(np.int64)
        if arr.dtype.kind == "f":
            return arr.astype(float)
    return value
