r"""The reader of one problem file: TOML in, a checked :class:`~qpik.problems.schema.Problem` out.

:class:`Reader` checks every table against the vocabulary of :mod:`qpik.problems.schema` (an unknown
key is an error naming the closest known one), converts the robot (catalog name or model file, with
limit overrides), the target (poses, configurations, random draws, sweeps, named paths), the
redundancy parameters (rad), the obstacles (base frame, m) and the ``[solver]`` settings, and
raises :class:`~qpik.core.errors.ProblemFileError` naming the file and the field.
"""

from __future__ import annotations

import dataclasses
import difflib
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from qpik.core.errors import InputError, ProblemFileError, UnknownRobotError
from qpik.core.validate import finite_array
from qpik.core.validate import pose as check_pose
from qpik.geometry.paths import TargetPath
from qpik.geometry.shapes import Shape, shape_from_spec
from qpik.planning.options import default_resolution
from qpik.problems.paths import PATHS
from qpik.problems.schema import KINDS, MAX_COUNT, MAX_GRID, SOLVER_KEYS, Problem, Setting
from qpik.robots.loader import load_robot
from qpik.robots.model_files import MeshOptions
from qpik.robots.robot import Robot


class Reader:
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
        """One item of ``shape`` or a list of them, as ``(N, *shape)``."""
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
        resolution = solver["resolution"] or default_resolution(robot)
        if waypoints * resolution > MAX_GRID:
            size = f"{waypoints} waypoints × resolution {resolution}"
            raise self.fail("solver.resolution", f"{size} is over {MAX_GRID:,} grid points per branch; use fewer "
                            "waypoints or a lower resolution")  # fmt: skip
        for key in ("branch", "baseline_branch"):
            if solver[key] is None:
                continue
            if not robot.branch_functions:
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
