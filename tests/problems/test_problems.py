"""Problem files: the shipped files load with the paper's numbers; every malformed field is reported."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import fd

import qpik
from qpik.core.errors import ProblemFileError, QpikError
from qpik.core.validate import project_to_so3
from qpik.geometry import Capsule, HalfSpace, Sphere, shape_from_spec
from qpik.problems import (
    KINDS,
    PATHS,
    find_problem,
    get_runner,
    list_problems,
    load,
    problem_files,
    problems_folder,
    run_problem,
    runner,
)
from qpik.problems import runners as runners_module

FOLDER = problems_folder()


def write(tmp_path: Path, text: str, name: str = "p.toml") -> Path:
    f = tmp_path / name
    f.write_text(text)
    return f


Q = "q = [0.1, 0.2, 0.3, -0.4, 0.5, 0.6, 0.7]"
BASE = f"""
kind = "ik"
[robot]
name = "iiwa14"
[target]
{Q}
"""
ZHENG = 'path = "zheng2019"\npath_params = { reading = "literal" }'
SPHERE = '[[obstacles]]\ntype = "sphere"\n'


def with_target(text: str, kind: str = "ik") -> str:
    """BASE with its ``[target]`` body replaced by ``text``."""
    return BASE.replace(Q, text).replace('kind = "ik"', f'kind = "{kind}"')


def with_robot(text: str) -> str:
    """BASE with ``text`` added to its ``[robot]`` table."""
    return BASE.replace('name = "iiwa14"', f'name = "iiwa14"\n{text}')


# ---- the shipped files -------------------------------------------------------


def test_every_shipped_problem_loads():
    problems = list_problems()
    assert len(problems) >= 3
    assert len({p.name for p in problems}) == len(problems)
    for p in problems:
        assert p.kind in KINDS and p.description and p.source, p.file
        assert (p.poses is None) != (p.path is None), p.file
        if p.poses is not None:
            R = p.poses[:, :3, :3]
            np.testing.assert_allclose(np.swapaxes(R, 1, 2) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12)


def test_nammoto_table4_holds_the_paper_numbers():
    p = load(FOLDER / "nammoto2012_table4.toml")
    assert p.kind == "ik" and p.robot is qpik.load_robot("nammoto7")
    n, t, b = (0.18, -0.16, -0.97), (0.63, 0.78, -0.01), (0.76, -0.61, 0.25)  # eqs. (33)-(35)
    assert p.poses.shape == (1, 4, 4)
    np.testing.assert_allclose(p.poses[0, :3, :3], project_to_so3(np.column_stack([n, t, b])), atol=1e-15)
    np.testing.assert_allclose(p.poses[0, :3, 3], (-0.18, 0.41, 0.41))
    np.testing.assert_array_equal(p.params, [-0.80])
    q = p.expected["q"]
    assert q.shape == (16, 7)
    np.testing.assert_array_equal(p.expected["branches"], np.arange(1, 17))
    np.testing.assert_array_equal(q[:8, 0], 1.12)  # rows 1-8 use theta_1[1] (the Table 2 row 8 erratum)
    np.testing.assert_array_equal(q[8:, 0], -2.02)
    assert p.expected["tolerance"] == 0.05 and "row No. 8" in p.expected["notes"]


def test_shimizu_iiwa_pose_and_psi_sweep():
    p = load(FOLDER / "shimizu2008_iiwa.toml")
    q = np.array([0.16, np.pi / 2, 0.5, np.pi / 3, 0.6, np.pi / 6, 0.3])
    np.testing.assert_allclose(p.q_targets, q[None], atol=1e-15)
    ssik = pytest.importorskip("ssik.prebuilt.kuka.iiwa14_ik")
    np.testing.assert_allclose(p.poses[0], ssik.fk(q), atol=1e-12)
    assert p.params[0] == pytest.approx(-np.pi) and p.params[-1] == pytest.approx(np.pi)
    np.testing.assert_allclose(np.diff(p.params), np.deg2rad(5.0), atol=1e-12)


@pytest.mark.parametrize("reading", ["relative", "literal"])
def test_zheng2019_path(tmp_path, reading):
    text = (FOLDER / "zheng2019_clik.toml").read_text().replace('reading = "relative"', f'reading = "{reading}"')
    p = load(write(tmp_path, text))
    path = p.path
    assert p.kind == "track" and path.duration == 6.0 and p.solver["dt"] == 0.001
    T0 = p.robot.fk(path.q0)
    np.testing.assert_allclose(path.q0, [0, 1.0472, -0.5236, -2.0944, 0, 1.5708, -1.5708])
    gap = np.linalg.norm(path.pose(0.0)[:3, 3] - T0[:3, 3])
    assert gap == pytest.approx(0.0 if reading == "relative" else np.hypot(0.4, 0.2), abs=1e-15)
    t = np.linspace(0.0, path.duration, 201)
    T = path.pose(t)
    assert T.shape == (201, 4, 4) and path.twist(t).shape == (201, 6)
    np.testing.assert_allclose(T[:, :3, :3], np.broadcast_to(T0[:3, :3], (201, 3, 3)), atol=0)
    # the feed-forward twist is the time derivative of the pose (ω = 0: constant rotation)
    v_fd = fd(lambda s: path.pose(s[..., 0])[..., :3, 3], t[:, None])[..., 0]
    np.testing.assert_allclose(path.twist(t)[:, :3], v_fd, atol=1e-8)
    np.testing.assert_array_equal(path.twist(t)[:, 3:], 0.0)
    np.testing.assert_allclose(path.twist(1.5), path.twist(np.array([1.5]))[0])
    # eq. (19): x - x0 = 0.4 (cos(0.5 t) - 1) in the relative reading
    dx = T[:, 0, 3] - T0[0, 3]
    np.testing.assert_allclose(dx, 0.4 * (np.cos(0.5 * t) - (reading == "relative")), atol=1e-14)


def test_find_problem_by_name_or_path():
    assert find_problem("zheng2019_clik") == FOLDER / "zheng2019_clik.toml"
    assert find_problem(FOLDER / "zheng2019_clik.toml") == FOLDER / "zheng2019_clik.toml"
    with pytest.raises(ProblemFileError, match="no such file"):
        find_problem("no_such_problem")


def test_the_shipped_problems_are_found_from_any_folder(tmp_path, monkeypatch):
    """The problem files ship inside the package: a ``problems/`` folder in the working folder is not read."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "problems").mkdir()
    (tmp_path / "problems" / "zheng2019_clik.toml").write_text("not a problem")
    assert (problems_folder() / "__init__.py").is_file() and problems_folder() != tmp_path / "problems"
    assert find_problem("zheng2019_clik") == problems_folder() / "zheng2019_clik.toml"
    source = Path(__file__).parents[2] / "problems"
    assert {p.stem for p in problem_files()} == {p.stem for p in source.glob("*.toml")}
    assert problem_files(tmp_path / "problems") == [tmp_path / "problems" / "zheng2019_clik.toml"]


# ---- the other target forms, parameters, obstacles ------------------------------


def test_pose_forms_and_sweep(tmp_path):
    p = load(write(tmp_path, with_target("pose = [[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0.4], [0, 0, 0, 1]]")))
    assert p.poses.shape == (1, 4, 4) and p.poses[0, 0, 3] == 0.5 and p.q_targets is None
    eye = "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"
    turn = "[[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"
    assert load(write(tmp_path, with_target(f"pose = [{eye}, {turn}]"))).poses.shape == (2, 4, 4)
    sweep = """rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
position = [0.5, 0.0, 0.4]
sweep = { axis = "z", start = 0.3, stop = 0.9, num = 25 }"""
    p = load(write(tmp_path, with_target(sweep)))
    assert p.poses.shape == (25, 4, 4)
    np.testing.assert_allclose(p.poses[:, 2, 3], np.linspace(0.3, 0.9, 25))
    np.testing.assert_array_equal(p.poses[:, 0, 3], 0.5)


def test_q_and_random_forms_use_overridden_limits(tmp_path):
    p = load(write(tmp_path, with_target("q = [[0, 0, 0, 0, 0, 0, 0], [0.1, 0.2, 0.3, -0.4, 0.5, 0.6, 0.7]]")))
    np.testing.assert_allclose(p.poses, p.robot.fk(p.q_targets), atol=0)
    text = """
kind = "reach"
[robot]
name = "panda"
q_max = [0.5, 0.5, 0.5, -0.1, 0.5, 0.5, 0.5]
v_max = [1, 1, 1, 1, 1, 1, 1]
[target]
random = { seed = 3, count = 500 }
"""
    a, b = load(write(tmp_path, text)), load(write(tmp_path, text))
    np.testing.assert_array_equal(a.q_targets, b.q_targets)
    assert a.q_targets.shape == (500, 7) and a.poses.shape == (500, 4, 4)
    assert np.all(a.q_targets <= 0.5) and np.all(a.q_targets >= a.robot.q_min)
    np.testing.assert_array_equal(a.robot.v_max, 1.0)
    assert a.robot.name == "panda" and a.robot is not qpik.load_robot("panda")
    np.testing.assert_array_equal(a.robot.q_min, qpik.load_robot("panda").q_min)


@pytest.mark.parametrize(
    ("table", "want"),
    [
        ("value = 0.5", [0.5]),
        ("values = [0.1, -0.2]", [0.1, -0.2]),
        ("sweep = { start = 0, stop = 1, num = 3 }", [0, 0.5, 1]),
    ],
)
def test_parameter_forms(tmp_path, table, want):
    p = load(write(tmp_path, BASE + f"[parameter]\n{table}\n"))
    np.testing.assert_allclose(p.params, want)


def test_obstacles(tmp_path):
    text = (
        BASE
        + """
[[obstacles]]
type = "sphere"
name = "ball"
center = [0.5, 0, 0.5]
radius = 0.1
[[obstacles]]
type = "capsule"
p0 = [0, 0, 0]
p1 = [0, 0, 1]
radius = 0.05
[[obstacles]]
type = "box"
center = [0.4, 0.4, 0.2]
half_extents = [0.1, 0.2, 0.3]
[[obstacles]]
type = "halfspace"
normal = [0, 0, 2]
offset = 0.2
"""
    )
    sphere, capsule, box, half = load(write(tmp_path, text)).obstacles
    assert isinstance(sphere, Sphere) and sphere.name == "ball" and sphere.radius == 0.1
    assert isinstance(capsule, Capsule) and capsule.name == "obstacles[1]" and capsule.p1[2] == 1.0
    np.testing.assert_array_equal(box.rotation, np.eye(3))
    np.testing.assert_array_equal(half.normal, [0, 0, 1])
    assert half.offset == pytest.approx(0.1)  # the solid 2z <= 0.2


@pytest.mark.parametrize(
    "normal, offset", [([0, 0, 2], 0.2), ([0, -3, 4], 1.0), ([1e-3, 0, 0], -2e-3), ([0.2, 0.3, -0.1], 0.05)]
)
def test_a_halfspace_means_the_same_through_both_entry_points(tmp_path, normal, offset):
    """The problem file and shape_from_spec / HalfSpace give the set {x : normal·x <= offset} as written."""
    text = BASE + f'[[obstacles]]\ntype = "halfspace"\nnormal = {normal}\noffset = {offset}\n'
    from_file = load(write(tmp_path, text)).obstacles[0]
    from_spec = shape_from_spec({"type": "halfspace", "normal": normal, "offset": offset})
    direct = HalfSpace(normal, offset)
    points = np.random.default_rng(0).uniform(-2, 2, (2000, 3))
    inside = points @ np.asarray(normal, float) <= offset  # the inequality as the user wrote it
    for shape in (from_file, from_spec, direct):
        assert isinstance(shape, HalfSpace)
        np.testing.assert_array_equal(points @ shape.normal <= shape.offset, inside)
        np.testing.assert_allclose(np.linalg.norm(shape.normal), 1.0)


# ---- errors ------------------------------------------------------------------------

ERRORS = [
    (BASE.replace('"iiwa14"', '"ur5"'), r"robot\.name: unknown robot 'ur5'"),
    (BASE.replace('kind = "ik"', 'kind = "dance"'), r"kind: unknown kind 'dance'"),
    (BASE.replace('kind = "ik"', ""), r"top level: missing kind"),
    ("colour = 1\n" + BASE, r"top level: unknown key\(s\) colour"),
    (with_robot("q_max = [1, 2]"), r"robot\.q_max: expected shape \(7,\)"),
    (with_robot("q_max = [-3, -3, -3, -3, -3, -3, -3]"), r"q_min must be < q_max"),
    (with_robot("speed = 1"), r"robot: unknown key\(s\) speed"),
    (with_target("q = [0.1, 0.2]"), r"target\.q: expected shape \(N, 7\)"),
    (with_target("q = [0.1, nan, 0.3, -0.4, 0.5, 0.6, 0.7]"), r"target\.q: contains NaN or inf"),
    (with_target(f"random = {{ seed = 1, count = 2 }}\n{Q}"), r"target: give exactly one of .*got q, random"),
    (with_target("rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]"), r"target: missing position"),
    (
        with_target("rotation = [[1, 0, 0], [0, 1, 0.1], [0, 0, 1]]\nposition = [0, 0, 1]"),
        r"target\.rotation: rotation is not orthonormal",
    ),
    (with_target('path = "spiral"'), r"target\.path: unknown path 'spiral'"),
    (with_target("random = { seed = 1 }"), r"target\.random: missing count"),
    (with_target("random = { seed = 1, count = 0 }"), r"target\.random\.count"),
    (BASE + "[parameter]\nvalue = 1\nvalues = [1]\n", r"parameter: give exactly one of"),
    (BASE + "[parameter]\nsweep = { start = 0, stop = 1 }\n", r"parameter\.sweep: missing num"),
    (BASE + '[[obstacles]]\ntype = "cone"\n', r"obstacles\[0\]: obstacle type: expected one of .* got 'cone'"),
    (BASE + SPHERE + "center = [0, 0, 0]\n", r"obstacles\[0\]: sphere obstacle: missing key\(s\) \['radius'\]"),
    (BASE + SPHERE + "center = [0, 0, 0]\nradius = -1\n", r"obstacles\[0\]: radius: must be finite and > 0"),
    (BASE + SPHERE + "center = [0, 0]\nradius = 1\n", r"obstacles\[0\]: center: expected shape \(3,\)"),
    (
        BASE + '[[obstacles]]\ntype = "box"\ncenter = [0, 0, 0]\nhalf_extents = [1, 1, 1]\n'
        "rotation = [[2, 0, 0], [0, 1, 0], [0, 0, 1]]\n",
        r"obstacles\[0\]: rotation: rotation is not orthonormal",
    ),
    (
        BASE + '[[obstacles]]\ntype = "halfspace"\nnormal = [0, 0, 0]\noffset = 0\n',
        r"obstacles\[0\]: normal: must not be the zero vector",
    ),
    (with_target(Q, kind="track"), r"target: kind 'track' needs a path"),
    (with_target(ZHENG, kind="track") + "[parameter]\nvalue = 0\n", r"parameter: only kinds 'ik' and 'plan'"),
    (with_target(ZHENG.replace("literal", "odd")), r"target\.path_params: reading must be"),
    (with_target(ZHENG.replace('"literal"', '"literal", speed = 2')), r"target\.path_params: unknown parameter"),
    (with_target(ZHENG), r"kind 'ik' needs poses"),
    (BASE + "[solver]\ndt = 1\n[solver.x]\n= 2\n", r"not valid TOML"),
]


@pytest.mark.parametrize(("text", "message"), ERRORS, ids=[m for _, m in ERRORS])
def test_malformed_files_name_the_file_and_field(tmp_path, text, message):
    f = write(tmp_path, text, "broken.toml")
    with pytest.raises(ProblemFileError, match=message) as info:
        load(f)
    assert str(info.value).startswith(f"{f}: ")


def test_project_true_accepts_the_rounded_rotation(tmp_path):
    rounded = "[[0.18, 0.63, 0.76], [-0.16, 0.78, -0.61], [-0.97, -0.01, 0.25]]"
    text = with_target(f"rotation = {rounded}\nposition = [0, 0, 1]")
    with pytest.raises(ProblemFileError, match="project=True"):
        load(write(tmp_path, text))
    assert load(write(tmp_path, text + "project = true\n")).poses.shape == (1, 4, 4)


def test_missing_file():
    with pytest.raises(ProblemFileError, match="no such file"):
        load("/nonexistent/problem.toml")


def test_path_registry_names_are_the_documented_ones():
    assert "zheng2019" in PATHS


# ---- runners -----------------------------------------------------------------------


def test_runner_registry(tmp_path, monkeypatch):
    monkeypatch.setattr(runners_module, "RUNNERS", {})
    monkeypatch.setattr(runners_module, "RUNNER_MODULES", ())
    problem = load(write(tmp_path, BASE))
    with pytest.raises(QpikError, match="no runner for kind 'ik' yet"):
        run_problem(problem, tmp_path / "out")
    seen = []

    @runner("ik")
    def fake(p, out):
        seen.append((p.name, out.is_dir()))
        return "# report"

    assert get_runner("ik") is fake
    assert run_problem(problem, tmp_path / "out") == "# report"
    assert seen == [("p", True)]


def test_runner_modules_are_imported_on_demand(monkeypatch):
    monkeypatch.setattr(runners_module, "RUNNERS", {})
    monkeypatch.setattr(runners_module, "RUNNER_MODULES", ("qpik.no_such_runner_module",))
    with pytest.raises(ModuleNotFoundError):
        get_runner("ik")


REACH = BASE.replace('kind = "ik"', 'kind = "reach"')


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (REACH + "[solver]\nd_saef = 0.03\n", r"solver\.d_saef: unknown key for kind 'reach'; did you mean 'd_safe'\?"),
        (REACH + "[solver]\nkp_positon = 5\n", r"solver\.kp_positon: .*did you mean 'kp_position'\?"),
        (REACH + "[solver]\nbranch = 1\n", r"solver\.branch: unknown key for kind 'reach'"),
        (BASE + "[solver]\nd_safe = 0.03\n", r"solver\.d_safe: unknown key for kind 'ik' \(known: branch\)"),
        (REACH + '[solver]\ndt = "fast"\n', r"solver\.dt: expected a number \(control period, s\), got 'fast'"),
        (REACH + "[solver]\ndt = 0\n", r"solver\.dt: must be > 0"),
        (REACH + "[solver]\ndamping = -1e-4\n", r"solver\.damping: must be >= 0"),
        (REACH + "[solver]\nxi = nan\n", r"solver\.xi: contains NaN"),
        (REACH + "[solver]\nkp_position = true\n", r"solver\.kp_position: expected a number"),
        (BASE + "[solver]\nbranch = 1.5\n", r"solver\.branch: expected an integer"),
        (with_robot("q_home = [0, 0, 0, 3.0, 0, 0, 0]"), r"robot\.q_home: outside \[q_min, q_max\] on joint\(s\) 4"),
    ],
)
def test_solver_keys_and_q_home_are_checked(tmp_path, text, message):
    with pytest.raises(ProblemFileError, match=message):
        load(write(tmp_path, text))


def test_solver_table_is_complete_with_defaults(tmp_path):
    from qpik.problems.schema import SOLVER_KEYS

    p = load(write(tmp_path, REACH + "[solver]\nd_safe = 0.03\nkp_position = 10\n"))
    assert set(p.solver) == set(SOLVER_KEYS["reach"])
    assert p.solver["d_safe"] == 0.03 and p.solver["kp_position"] == 10.0 and isinstance(p.solver["kp_position"], float)
    assert p.solver["d_influence"] == SOLVER_KEYS["reach"]["d_influence"].default
    assert load(write(tmp_path, BASE)).solver == {"branch": None}
    for problem in list_problems():  # every shipped file's keys are known to its kind
        assert set(problem.solver) == set(SOLVER_KEYS[problem.kind])


def test_expected_numbers_are_checked(tmp_path):
    p = load(write(tmp_path, BASE + '[expected]\ntolerance = "small"\nfk_tolerance = 0.1\n'))
    assert p.expected_number("fk_tolerance") == 0.1 and p.expected_number("absent", 2.0) == 2.0
    with pytest.raises(ProblemFileError, match=r"expected\.tolerance: expected a finite number, got 'small'"):
        p.expected_number("tolerance")


def test_project_true_refuses_what_is_not_a_rotation(tmp_path):
    """TOML ``project = true`` used to turn −R, a reflection, into some rotation of another orientation."""
    text = with_target("rotation = [[-1, 0, 0], [0, -1, 0], [0, 0, -1]]\nposition = [0, 0, 1]\nproject = true")
    with pytest.raises(ProblemFileError, match="cannot be projected"):
        load(write(tmp_path, text))
    box = BASE + '[[obstacles]]\ntype = "box"\ncenter = [0, 0, 0]\nhalf_extents = [1, 1, 1]\n'
    box += "rotation = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]\nproject = true\n"
    with pytest.raises(ProblemFileError, match=r"obstacles\[0\]: .*cannot be projected"):
        load(write(tmp_path, box))
    text = with_target('rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nposition = [0, 0, 1]\nproject = "no"')
    with pytest.raises(ProblemFileError, match=r"target\.project: expected true or false"):
        load(write(tmp_path, text))


# ---- size caps of plan problems (a file cannot ask for hours of work or all the memory) --------------------------

PLAN = with_target(ZHENG, "plan")
WIPE = with_target(
    'path = "wipe"\npath_params = { center = [0.5, 0.0, 0.3], amplitude = 0.1, length = 0.3, strokes = 2, '
    "duration = 4.0 }",
    "plan",
)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (PLAN + "[solver]\nwaypoints = 3000000\n", r"solver\.waypoints: must be <= 20000"),
        (PLAN + "[solver]\nwaypoints = 1\n", r"solver\.waypoints: must be >= 2"),
        (PLAN + "[solver]\nresolution = 100000000\n", r"solver\.resolution: must be <= 20000"),
        (PLAN + "[solver]\nresolution = 4\n", r"solver\.resolution: must be >= 8"),
        (PLAN + "[solver]\nwaypoints = 10000\nresolution = 2000\n", r"solver\.resolution: 10000 waypoints × resolution "
         r"2000 is over 10,000,000 grid points per branch"),
        (PLAN + "[solver]\nbaseline_branch = 99\n", r"solver\.baseline_branch: iiwa14's branches are 0 to 7, got 99"),
        (PLAN + "[solver]\nbranch = -1\n", r"solver\.branch: iiwa14's branches are 0 to 7, got -1"),
        (PLAN.replace('"iiwa14"', '"nammoto7"') + "[solver]\nbranch = 0\n", r"nammoto7's branches are 1 to 16, got 0"),
        (PLAN.replace('"iiwa14"', '"zheng7"') + "[solver]\nbaseline_branch = 1\n", r"zheng7 has no closed form"),
        (WIPE.replace("strokes = 2", "strokes = -3"), r"target\.path_params: strokes must be > 0, got -3"),
        (WIPE.replace("strokes = 2", "strokes = 0"), r"strokes must be > 0"),
        (with_target("random = { seed = 0, count = 100000000 }"), r"target\.random\.count: expected an integer from 1"),
        (BASE + "[parameter]\nsweep = { start = 0, stop = 1, num = 1000001 }\n", r"parameter\.sweep\.num: expected an"),
    ],
)  # fmt: skip
def test_plan_sizes_are_capped(tmp_path, text, message):
    with pytest.raises(ProblemFileError, match=message):
        load(write(tmp_path, text))


def test_sizes_at_their_caps_load(tmp_path):
    p = load(write(tmp_path, PLAN + "[solver]\nwaypoints = 20000\nresolution = 500\nbaseline_branch = 7\n"))
    assert p.solver["waypoints"] == 20000 and p.solver["baseline_branch"] == 7
    assert load(write(tmp_path, WIPE)).path.duration == 4.0
