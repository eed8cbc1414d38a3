"""examples/: every script runs, and what it prints or writes is checked by code of its own.

Each script runs once in a subprocess (``python examples/<name>.py <tmp folder>`` from the
repository root). Every script found by the glob must exit with 0; the scripts below also have
their output checked against independent computations: forward kinematics from a DH product
written here (or MuJoCo's kinematics of the twin), distances from closest points computed here,
the path formula of Zheng et al. 2019 written here, a KKT certificate for the QP, and the paper's
numbers read from the problem files as raw TOML.
"""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pytest
from PIL import Image
from scipy.optimize import nnls

import qpik

# --dist loadgroup: one worker runs the whole module, so its module- and session-scoped fixtures are built once
pytestmark = pytest.mark.xdist_group("examples")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))
HANG_GUARD = 900  # s: only stops a script that never ends; the scripts take seconds

DEG = np.pi / 180
# KUKA LBR iiwa 14 R820 datasheet: position (deg) and velocity (deg/s) limits
IIWA_Q_MAX = np.array([170, 120, 170, 120, 170, 120, 175]) * DEG
IIWA_V_MAX = np.array([85, 85, 100, 75, 130, 135, 135]) * DEG
FLOAT = r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?"


@dataclass
class Run:
    returncode: int
    stdout: str
    stderr: str
    out: Path


_runs: dict[str, Run] = {}


@pytest.fixture(scope="session")
def run_example(tmp_path_factory: pytest.TempPathFactory):
    """``run_example(stem)``: the script's :class:`Run` (each script runs once per session)."""

    def run(stem: str) -> Run:
        if stem not in _runs:
            out = tmp_path_factory.mktemp(stem)
            proc = subprocess.run(
                [sys.executable, str(EXAMPLES / f"{stem}.py"), str(out)],
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=HANG_GUARD,
            )
            _runs[stem] = Run(proc.returncode, proc.stdout, proc.stderr, out)
        result = _runs[stem]
        assert result.returncode == 0, f"{stem} failed:\n{result.stdout}\n{result.stderr}"
        return result

    return run


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.stem for s in SCRIPTS])
def test_example_runs(run_example, script: Path) -> None:
    result = run_example(script.stem)
    assert result.stdout.strip(), "an example prints what it shows"


# ---- independent helpers ------------------------------------------------------------------


def dh_fk(chain, q: np.ndarray) -> np.ndarray:
    """End-effector pose of a standard-DH chain: the product of Rz(θ+o) Tz(d) Tx(a) Rx(α), then the tool."""
    assert chain.convention == "standard"
    T = np.array(chain.base, dtype=float)
    for th, o, d, a, al in zip(q, chain.offset, chain.d, chain.a, chain.alpha):
        c, s, ca, sa = np.cos(th + o), np.sin(th + o), np.cos(al), np.sin(al)
        T = T @ np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, d], [0, 0, 0, 1]])
    return T @ chain.tool


def rotation_angle(R: np.ndarray) -> float:
    """Angle (rad) of a rotation matrix, accurate near 0."""
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return float(np.arctan2(np.linalg.norm(w), np.trace(R) - 1.0))


def pose_gap(A: np.ndarray, B: np.ndarray) -> tuple[float, float]:
    """Position (m) and rotation (rad) distance between two poses."""
    return float(np.linalg.norm(A[:3, 3] - B[:3, 3])), rotation_angle(A[:3, :3].T @ B[:3, :3])


def wrap(x: np.ndarray) -> np.ndarray:
    return (np.asarray(x) + np.pi) % (2 * np.pi) - np.pi


def srs_branch(q: np.ndarray) -> int:
    """The README's S-R-S branch number: 4·[θ2 < 0] + 2·[θ4 < 0] + [θ6 < 0]."""
    return 4 * int(q[1] < 0) + 2 * int(q[3] < 0) + int(q[5] < 0)


def assert_picture(path: Path) -> None:
    """A PNG that shows something: not tiny, not one flat colour."""
    assert path.is_file(), path
    img = np.asarray(Image.open(path).convert("RGB"))
    assert img.shape[0] >= 100 and img.shape[1] >= 100
    assert img.std() > 10.0
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50


def project_rotation(R: np.ndarray) -> np.ndarray:
    """The nearest rotation (Frobenius norm): U Vᵀ of the SVD."""
    U, _, Vt = np.linalg.svd(R)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def toml_problem(name: str) -> dict:
    with open(ROOT / "problems" / f"{name}.toml", "rb") as fh:
        return tomllib.load(fh)


def mj_site_pose(model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray) -> np.ndarray:
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    T = np.eye(4)
    T[:3, :3] = data.site("ee").xmat.reshape(3, 3)
    T[:3, 3] = data.site("ee").xpos
    return T


def capsule_segments(model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray, names: list[str]):
    """World end points (C, 2, 3) and radii (C,) of the named capsule/sphere geoms at q (MuJoCo kinematics)."""
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    segs, radii = [], []
    for name in names:
        g = data.geom(name)
        size = model.geom(name).size
        half = size[1] if model.geom(name).type[0] == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0
        z = g.xmat.reshape(3, 3)[:, 2]
        segs.append([g.xpos - half * z, g.xpos + half * z])
        radii.append(size[0])
    return np.array(segs), np.array(radii)


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    s = 0.0 if ab @ ab == 0 else float(np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + s * ab)))


# ---- examples/table4_branches.py ------------------------------------------------------------


def test_table4_branches(run_example) -> None:
    result = run_example("table4_branches")
    raw = toml_problem("nammoto2012_table4")
    T = np.eye(4)
    T[:3, :3] = project_rotation(np.array(raw["target"]["rotation"]))
    T[:3, 3] = raw["target"]["position"]
    paper = np.array(raw["expected"]["q"])  # Table 4, rad, 2 decimals
    chain = qpik.load_robot("nammoto7").chain

    with open(result.out / "branches.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["branch"]) for r in rows] == list(range(1, 17))
    q = np.array([[float(r[f"q{j}"]) for j in range(1, 8)] for r in rows])
    assert all(r["valid"] == "1" for r in rows)
    for i in range(16):
        pos, rot = pose_gap(dh_fk(chain, q[i]), T)
        assert pos < 1e-9 and rot < 1e-9, (i + 1, pos, rot)
    diff = np.abs(wrap(q - paper)).max(axis=1)
    assert diff.max() < 0.05  # the paper's rounding, as its problem file allows
    gaps = np.abs(wrap(q[:, None] - q[None])).max(axis=2) + np.eye(16)
    assert gaps.min() > 1e-3  # 16 different configurations

    # the printed branch table (3 decimals) is the CSV's q
    table = re.findall(rf"^\s*(\d+)((?:\s+{FLOAT}){{7}})\s+yes\s+in\b", result.stdout, re.M)
    assert [int(b) for b, _ in table] == list(range(1, 17))
    printed_q = np.array([[float(v) for v in cols.split()] for _, cols in table])
    np.testing.assert_allclose(printed_q, q, atol=6e-4)
    # the printed residuals are tiny and the printed differences to Table 4 are the recomputed ones
    res = re.findall(rf"^\s*(\d+)\s+({FLOAT})\s+({FLOAT})\s+(\d+\.\d{{3}})$", result.stdout, re.M)
    assert [int(r[0]) for r in res] == list(range(1, 17))
    for (_, pos, rot, d), want in zip(res, diff):
        assert float(pos) < 1e-9 and float(rot) < 1e-9
        assert abs(float(d) - want) < 6e-4
    assert_picture(result.out / "branches.png")


# ---- examples/iiwa_feasible_intervals.py ----------------------------------------------------


def test_iiwa_feasible_intervals(run_example) -> None:
    result = run_example("iiwa_feasible_intervals")
    text = result.stdout
    q0 = np.array([float(v) for v in re.search(r"q0 = \[([^\]]*)\] rad", text).group(1).split()])
    psi0, branch0 = re.search(rf"q0 has ψ = ({FLOAT}) rad on branch (\d)", text).groups()
    psi0, branch0 = float(psi0), int(branch0)
    intervals = {}
    for b, spans, measure in re.findall(r"branch (\d): (.*?)  \(([\d.]+)° in all\)", text):
        found = re.findall(rf"\[({FLOAT}), ({FLOAT})\]", spans)
        intervals[int(b)] = [(float(lo), float(hi)) for lo, hi in found]
        total = sum(hi - lo for lo, hi in intervals[int(b)])
        assert abs(np.degrees(total) - float(measure)) < 0.06
    assert sorted(intervals) == list(range(8))

    robot = qpik.load_robot("iiwa14")
    pose = dh_fk(robot.chain, q0)
    assert srs_branch(q0) == branch0
    assert np.all(np.abs(q0) <= IIWA_Q_MAX)  # q0 is inside the limits, so its ψ is feasible on its branch
    assert any(lo <= psi0 <= hi for lo, hi in intervals[branch0])

    # Dense sampling: every branch's q at 1441 values of ψ, checked by FK and against the datasheet limits.
    psi = np.linspace(-np.pi, np.pi, 1441)
    sols = qpik.ik(robot, np.broadcast_to(pose, (len(psi), 4, 4)), psi)
    for col, b in enumerate(sols.branch):
        qs = sols.q[:, col]
        reaches = np.array([max(pose_gap(dh_fk(robot.chain, q), pose)) < 1e-8 for q in qs])
        assert reaches.all()
        signs = np.array([srs_branch(q) for q in qs])
        clear = np.min(np.abs(qs[:, [1, 3, 5]]), axis=1) > 1e-9
        assert np.all(signs[clear] == b)
        inside = np.all(np.abs(qs) <= IIWA_Q_MAX, axis=1)
        listed = np.zeros(len(psi), bool)
        edges = []
        for lo, hi in intervals[int(b)]:
            listed |= (psi >= lo) & (psi <= hi)
            edges += [lo, hi]
        away = np.min(np.abs(psi[:, None] - np.array([*edges, np.inf])[None]), axis=1) > 1e-4
        assert np.array_equal(listed[away], inside[away]), f"branch {b}"

    q_mid = np.array([float(v) for v in re.search(r"  q = \[([^\]]*)\] rad", text).group(1).split()])
    assert max(pose_gap(dh_fk(robot.chain, q_mid), pose)) < 1e-5  # printed to 6 decimals
    assert srs_branch(q_mid) == branch0 and np.all(np.abs(q_mid) <= IIWA_Q_MAX)
    assert_picture(result.out / "selfmotion.png")


# ---- examples/panda_q7_branches.py ---------------------------------------------------------

# Franka Emika Panda datasheet: joint limits (rad)
PANDA_Q_MIN = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
PANDA_Q_MAX = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])


def panda_branch(q: np.ndarray) -> int:
    """The Panda's branch number of qpik.analytic.locked_joint: 4·[q2 < 0] + 2·[q4 > −0.467] + wrist, the wrist bit
    [cos q5 > 0] for q4 in Franka's range (−π, 0) and beyond 2.6308 rad, [cos q5 < 0] between (where the shoulder
    point changes side of the forearm axis)."""
    flip = 0.0 < q[3] < 2.6308
    return 4 * int(q[1] < 0) + 2 * int(q[3] > -0.467) + int((np.cos(q[4]) > 0) != flip)


def test_panda_q7_branches(run_example) -> None:
    result = run_example("panda_q7_branches")
    text = result.stdout
    vec = r"\[([^\]]*)\] rad"
    q0 = np.array([float(v) for v in re.search(rf"q0 = {vec}", text).group(1).split()])
    q7, branch0 = re.search(rf"q0 has q7 = ({FLOAT}) rad on branch (\d)", text).groups()
    assert float(q7) == pytest.approx(q0[6], abs=1e-6) and int(branch0) == panda_branch(q0)

    robot = qpik.load_robot("panda")  # its MuJoCo twin's site "ee" is the flange: MuJoCo's FK, not qpik's
    model = robot.mj_model()
    data = mujoco.MjData(model)
    site = model.site("ee").id

    def fk(q: np.ndarray) -> np.ndarray:
        for name, value in zip(robot.joint_names, q):
            data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
        mujoco.mj_kinematics(model, data)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = data.site_xmat[site].reshape(3, 3), data.site_xpos[site]
        return T

    def inside(q: np.ndarray) -> bool:
        return bool(np.all(q >= PANDA_Q_MIN) and np.all(q <= PANDA_Q_MAX))

    pose = fk(q0)
    state = r"\((reaches the pose|does not reach the pose)(, inside the limits)?\)"
    rows = re.findall(rf"branch (\d): q = {vec}  {state}", text)
    assert len(rows) == 8
    found = False
    for b, values, reach, within in rows:
        q = np.array([float(v) for v in values.split()])
        if reach == "reaches the pose":
            assert max(pose_gap(fk(q), pose)) < 1e-5 and q[6] == pytest.approx(q0[6], abs=1e-6)
            assert panda_branch(q) == int(b) and bool(within) == inside(q), (b, q)
            found |= int(b) == int(branch0) and np.abs(q - q0).max() < 1e-5
    assert found  # q0 among the branches, under its own number

    intervals = {}
    for b, spans in re.findall(r"  branch (\d): ((?:\[.*?\] ?)+|none)  \(", text):
        intervals[int(b)] = [(float(lo), float(hi)) for lo, hi in re.findall(rf"\[({FLOAT}), ({FLOAT})\]", spans)]
    assert sorted(intervals) == list(range(8)) and "proved: True" in text
    # Dense sampling of q7: every branch that reaches the pose, checked by MuJoCo's FK and the datasheet's limits.
    q7s = np.linspace(-np.pi, np.pi, 2001)
    sols = qpik.ik(robot, np.broadcast_to(pose, (len(q7s), 4, 4)), q7s)
    margin_best = -np.inf
    for col, b in enumerate(sols.branch):
        ok = np.array([sols.valid[i, col] and max(pose_gap(fk(sols.q[i, col]), pose)) < 1e-8 for i in range(len(q7s))])
        assert np.array_equal(ok, sols.valid[:, col])
        feasible = ok & np.array([inside(q) for q in sols.q[:, col]])
        listed = np.zeros(len(q7s), bool)
        edges = [np.inf]
        for lo, hi in intervals[int(b)]:
            listed |= (q7s >= lo) & (q7s <= hi)
            edges += [lo, hi]
        away = np.min(np.abs(q7s[:, None] - np.array(edges)[None]), axis=1) > 1e-4
        assert np.array_equal(listed[away], feasible[away]), f"branch {b}"
        half = 0.5 * (PANDA_Q_MAX - PANDA_Q_MIN)
        for q in sols.q[feasible, col]:
            margin_best = max(margin_best, float(np.min(np.minimum(q - PANDA_Q_MIN, PANDA_Q_MAX - q) / half)))

    b, q7b, margin = re.search(rf"best: branch (\d), q7 = ({FLOAT}) rad, margin ({FLOAT}), maximised", text).groups()
    assert any(lo - 1e-6 <= float(q7b) <= hi + 1e-6 for lo, hi in intervals[int(b)])
    qb = np.array([float(v) for v in re.search(rf"\n  q = {vec}", text).group(1).split()])
    assert "certified" in text.split("best:", 1)[1].splitlines()[0]
    assert max(pose_gap(fk(qb), pose)) < 1e-5 and panda_branch(qb) == int(b) and inside(qb)
    assert qb[6] == pytest.approx(float(q7b), abs=1e-6)
    assert float(margin) >= margin_best - 1e-6  # no sample beats the certified best
    assert_picture(result.out / "selfmotion.png")


# ---- examples/controller_obstacles.py -------------------------------------------------------


def clearances(model, data, qs, ball_c, ball_r, normal, offset):
    """Per record, the smallest distance (m) of links 2-7 to the ball and to the table (closest points here)."""
    names = [f"link{k}_capsule" for k in range(2, 8)]
    out = []
    for q in qs:
        segs, radii = capsule_segments(model, data, q, names)
        ball = min(point_segment_distance(ball_c, a, b) - r for (a, b), r in zip(segs, radii)) - ball_r
        table = min(min(normal @ a, normal @ b) - offset - r for (a, b), r in zip(segs, radii))
        out.append((ball, table))
    return np.array(out)


def test_controller_obstacles(run_example) -> None:
    result = run_example("controller_obstacles")
    text = result.stdout
    run = np.load(result.out / "run.npz")
    model = qpik.load_robot("iiwa14").mj_model()  # the twin, with every link capsule
    data = mujoco.MjData(model)
    obstacle = (run["ball_center"], float(run["ball_radius"]), run["table_normal"], float(run["table_offset"]))

    d = clearances(model, data, run["q"], *obstacle)
    printed = dict(re.findall(rf"^  (ball|table): ({FLOAT}) mm", text, re.M))
    assert abs(float(printed["ball"]) - d[:, 0].min() * 1e3) < 1e-3
    assert abs(float(printed["table"]) - d[:, 1].min() * 1e3) < 1e-3
    d_safe = float(re.search(rf"d_s = ({FLOAT}) mm", text).group(1)) * 1e-3
    assert d.min() >= d_safe - 1e-4  # the velocity damper's promise
    free = clearances(model, data, run["q_free"], *obstacle)
    assert free[:, 0].min() < 0  # without the obstacle limit the same motion hits the ball
    without = float(re.search(rf"min clearance ({FLOAT}) mm", text).group(1))
    assert abs(without - free[:, 0].min() * 1e3) < 1e-3

    pos, rot = pose_gap(mj_site_pose(model, data, run["q"][-1]), run["target"])
    err = re.search(rf"position ({FLOAT}) m, orientation ({FLOAT}) rad", text)
    assert pos == pytest.approx(float(err.group(1)), rel=1e-3, abs=1e-9)
    assert rot == pytest.approx(float(err.group(2)), rel=1e-3, abs=1e-9)
    assert pos < 1e-3 and rot < 1e-2  # reached

    margin = np.minimum(run["q"] + IIWA_Q_MAX, IIWA_Q_MAX - run["q"]).min()
    assert margin > 0
    assert "max violation 0 rad" in text
    assert float(re.search(rf"min margin ({FLOAT}) rad", text).group(1)) == pytest.approx(margin, abs=1e-4)
    ratio = np.abs(run["v"] / IIWA_V_MAX).max()
    assert ratio <= 1 + 1e-9
    assert float(re.search(rf"max \|v\|/v_max = ({FLOAT})", text).group(1)) == pytest.approx(ratio, abs=1e-4)

    assert_picture(result.out / "run.png")
    strip = result.out / "strip.png"
    if "snapshot strip skipped" in text:
        assert not strip.exists()
    else:
        assert_picture(strip)


# ---- examples/clik_comparison.py ------------------------------------------------------------


def test_clik_comparison(run_example) -> None:
    result = run_example("clik_comparison")
    runs = np.load(result.out / "runs.npz")
    chain = qpik.load_robot("zheng7").chain
    # Zheng et al. 2019: the initial configuration, and eq. (19) moved to start at fk(q0)
    np.testing.assert_allclose(runs["q0"], [0.0, 1.0472, -0.5236, -2.0944, 0.0, 1.5708, -1.5708])
    T0 = dh_fk(chain, runs["q0"])
    t = runs["t"]
    path = T0[:3, 3] + np.stack([0.4 * (np.cos(0.5 * t) - 1), 0.4 * np.sin(t), 0.2 * (np.exp(-0.2 * t) - 1)], -1)
    after = t >= float(runs["transient"])

    rows = {}
    for label in runs["labels"]:
        m = re.search(rf"^{re.escape(str(label))}\s+({FLOAT})\s+({FLOAT})\s+({FLOAT})", result.stdout, re.M)
        rows[str(label)] = [float(v) for v in m.groups()]
    worst = {}
    for label, qs in zip(runs["labels"], runs["q"]):
        poses = np.array([dh_fk(chain, q) for q in qs])
        e_pos = np.linalg.norm(poses[:, :3, 3] - path, axis=1)
        e_rot = np.array([rotation_angle(T0[:3, :3].T @ P[:3, :3]) for P in poses])
        max_pos, max_rot, final_pos = rows[str(label)]
        assert max_pos == pytest.approx(e_pos[after].max() * 1e3, rel=1e-4, abs=2e-6)
        assert max_rot == pytest.approx(e_rot[after].max(), rel=1e-2, abs=1e-12)
        assert final_pos == pytest.approx(e_pos[-1] * 1e3, rel=1e-4, abs=2e-6)
        worst[str(label)] = e_pos[after].max()
    qp, pd, vel = (worst[str(label)] for label in runs["labels"])
    assert pd <= 1e-5 and qp <= 1e-5  # Zheng et al. 2019: 0.01 mm with eq. (18)
    assert vel > 10 * pd  # velocity-only feed-forward drifts
    drift = float(re.search(rf"drift: ({FLOAT})x", result.stdout).group(1))
    assert drift == pytest.approx(vel / pd, rel=2e-2)
    assert_picture(result.out / "tracking_errors.png")


# ---- examples/solver_comparison.py ----------------------------------------------------------


def kkt_residual(qp, x: np.ndarray, tol: float = 1e-9) -> tuple[float, float]:
    """(largest constraint violation, stationarity residual with multipliers ≥ 0 on the active bounds)."""
    n = len(x)
    G = np.vstack([np.eye(n), qp["A"]])
    lo, hi = np.concatenate([qp["lb"], qp["l"]]), np.concatenate([qp["ub"], qp["u"]])
    g = G @ x
    violation = float(max(0.0, np.max(lo - g), np.max(g - hi)))
    at_lo, at_hi = np.isfinite(lo) & (g - lo < tol), np.isfinite(hi) & (hi - g < tol)
    # P x + c = Gᵀ_lo λ_lo − Gᵀ_hi λ_hi with λ ≥ 0 (the gradient points into the feasible set)
    M = np.hstack([G[at_lo].T, -G[at_hi].T])
    grad = qp["P"] @ x + qp["c"]
    if M.shape[1] == 0:
        return violation, float(np.linalg.norm(grad))
    _, residual = nnls(M, grad)
    return violation, float(residual)


def test_solver_comparison(run_example) -> None:
    result = run_example("solver_comparison")
    qp = dict(np.load(result.out / "qp.npz"))
    assert np.linalg.eigvalsh(qp["P"]).min() > 0  # strictly convex: one minimiser
    ref = qp["x_daqp"]
    violation, stationarity = kkt_residual(qp, ref)
    assert violation < 1e-9 and stationarity < 1e-8  # DAQP's answer is the optimum
    rows_active = np.isfinite(qp["l"]) & (np.abs(qp["A"] @ ref - qp["l"]) < 1e-9)
    assert rows_active.any()  # the obstacle row the script reports active is active

    answers = {k[2:]: v for k, v in qp.items() if k.startswith("x_")}
    assert {"osqp", "daqp", "mink"} <= set(answers)
    # rows "<solver> [notes]   <max |v - v_daqp|, .2e>   <time, µs>  <what is timed>"
    rows = re.findall(r"^(\S+)[^\n]*?\s(\d\.\d\de[+-]\d\d)\s+\d+\.\d  ", result.stdout, re.M)
    printed = {name: float(dist) for name, dist in rows}
    for name, x in answers.items():
        key = "mink.solve_ik" if name == "mink" else name
        assert np.abs(x - ref).max() < 1e-6, name  # every backend and mink: the same velocity
        assert printed[key] == pytest.approx(np.abs(x - ref).max(), rel=1e-2, abs=1e-15), name
    assert printed["qpik"] < 1e-6  # Controller.step on the same QP
    from qpik.control.solvers import available

    for name in re.findall(r"^(\S+)\s+not installed: skipped", result.stdout, re.M):
        assert name not in available()
    for name in available():
        if name in re.findall(r"^(\S+)", result.stdout, re.M):
            assert name in answers


# ---- examples/custom_dh_arm.py --------------------------------------------------------------


@dataclass
class Chain:
    a: tuple
    d: tuple
    alpha: tuple
    offset: tuple
    base: np.ndarray
    tool: np.ndarray
    convention: str = "standard"


def test_custom_dh_arm(run_example) -> None:
    result = run_example("custom_dh_arm")
    arms = json.loads((result.out / "arms.json").read_text())

    srs = arms["srs"]
    chain = Chain(**srs["dh"], base=np.eye(4), tool=np.eye(4))
    pose = np.array(srs["pose"])
    assert max(pose_gap(dh_fk(chain, srs["q_goal"]), pose)) < 1e-12  # qpik's FK of the user's table
    qs = np.array(srs["q"])
    assert len(qs) == 8 and all(srs["valid"])
    for b, q in zip(srs["branch"], qs):
        assert max(pose_gap(dh_fk(chain, q), pose)) < 1e-9, b
        assert srs_branch(q) == b
    assert np.abs(qs - srs["q_goal"]).max(axis=1).min() < 1e-9  # one branch is q_goal itself
    residuals = re.findall(rf"^\s+(\d)\s+({FLOAT})\s+({FLOAT})$", result.stdout, re.M)
    assert len(residuals) == 8 and all(float(p) < 1e-9 and float(r) < 1e-9 for _, p, r in residuals)

    wrist = arms["offset_wrist"]
    chain = Chain(**wrist["dh"], base=np.eye(4), tool=np.eye(4))
    pose = np.array(wrist["pose"])
    assert max(pose_gap(dh_fk(chain, wrist["q_goal"]), pose)) < 1e-12
    q = np.array(wrist["q"])
    assert max(pose_gap(dh_fk(chain, q), pose)) < 1e-9
    assert np.all((q >= wrist["q_min"]) & (q <= wrist["q_max"]))
    assert "no closed-form IK" in result.stdout


# ---- examples/package_arm.py ----------------------------------------------------------------


def _urdf_with_ball(urdf: Path, centre: np.ndarray, radius: float) -> mujoco.MjModel:
    """The URDF compiled by MuJoCo with a ball geom ``ball`` in the world, its ``package://NAME/...`` mesh
    paths resolved against the folder holding NAME/ (written here, without qpik's loader)."""
    spec = mujoco.MjSpec.from_file(str(urdf))
    root = next(p for p in urdf.parents if (p / "example-robot-data").is_dir())
    for mesh in spec.meshes:
        mesh.file = str(root / re.sub(r"^package:/+", "", mesh.file))
    spec.worldbody.add_geom(name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], pos=centre)
    return spec.compile()


def test_package_arm(run_example) -> None:
    """Limits as the URDF's XML says; the printed clearances recomputed by MuJoCo on the URDF's own meshes."""
    import xml.etree.ElementTree as ET

    result = run_example("package_arm")
    run = np.load(result.out / "run.npz")
    urdf = Path(str(run["model"]))
    limits = {j.get("name"): j.find("limit") for j in ET.parse(urdf).getroot().iter("joint")}
    row = rf"^\s+(\w+)\s+\[\s*({FLOAT}),\s*({FLOAT})\] rad, \|v\| <= ({FLOAT}) rad/s$"
    printed = re.findall(row, result.stdout, re.M)
    assert [name for name, *_ in printed] == [str(n) for n in run["joint_names"]]
    for name, lo, hi, v in printed:
        lim = limits[name]
        want = [float(lim.get("lower")), float(lim.get("upper")), float(lim.get("velocity"))]
        np.testing.assert_allclose([float(lo), float(hi), float(v)], want, atol=5e-5)
    assert "closed form with q7 locked" in result.stdout and "axes 1-2-3 meet" in result.stdout

    model = _urdf_with_ball(urdf, run["ball_center"], float(run["ball_radius"]))
    data = mujoco.MjData(model)
    arm = [model.joint(str(n)).qposadr[0] for n in run["joint_names"]]
    ball = model.geom("ball").id
    meshes = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]

    def clearance(qs: np.ndarray) -> float:
        """Smallest distance (m) from the arm's collision meshes to the ball over the configurations ``qs``."""
        best = np.inf
        for q in qs:
            data.qpos[:] = model.qpos0
            data.qpos[arm] = q
            mujoco.mj_kinematics(model, data)
            best = min(best, *(mujoco.mj_geomDistance(model, data, g, ball, 10.0, None) for g in meshes))
        return best

    found = re.findall(rf"min clearance of the meshes to the ball: ({FLOAT}) mm", result.stdout)
    with_limit, without = (float(x) for x in found)
    assert clearance(run["q"]) * 1e3 == pytest.approx(with_limit, abs=1e-3)
    assert clearance(run["q_free"]) * 1e3 == pytest.approx(without, abs=1e-3)
    assert with_limit > 0 > without


def test_plan_path(run_example) -> None:
    """The iiwa plan's CSV: the DH product of each row reaches the wipe path of the problem file (the formula
    written here from its TOML) to 1e-9 inside the datasheet limits, every capsule of the twin (MuJoCo
    kinematics) 2 cm from the post, consecutive rows within the joint-step bounds; the retimed duration is
    at least what the speed limits allow; the Nammoto lines say δ = 0 leaves the limits and the plan does not."""
    result = run_example("plan_path")
    out = result.stdout
    spec = toml_problem("iiwa_wiping_plan")
    prm, n = spec["target"]["path_params"], spec["solver"]["waypoints"]
    t = np.linspace(0.0, prm["duration"], n)
    w = 2 * np.pi * prm["strokes"] / prm["duration"]
    p = np.asarray(prm["center"]) + np.stack(
        [prm["amplitude"] * np.sin(w * t), -prm["length"] / 2 + prm["length"] * t / prm["duration"], 0 * t], axis=1
    )
    rows = np.loadtxt(result.out / "iiwa_wiping_plan.csv", delimiter=",", skiprows=1)
    q = rows[:, 2:9]
    assert q.shape == (n, 7)
    chain = qpik.load_robot("iiwa14").chain
    for k in range(n):
        T = dh_fk(chain, q[k])
        assert np.abs(T[:3, 3] - p[k]).max() < 1e-9 and np.abs(T[:3, :3] - np.diag([1.0, -1.0, -1.0])).max() < 1e-9
    assert np.all(np.abs(q) <= IIWA_Q_MAX + 1e-12)
    assert np.all(np.abs(np.diff(q, axis=0)) <= np.minimum(0.1, IIWA_V_MAX * (t[1] - t[0])) + 1e-9)
    post = next(o for o in spec["obstacles"] if o["name"] == "post")
    model = qpik.load_robot("iiwa14").mj_model()
    data = mujoco.MjData(model)
    names = [model.geom(i).name for i in range(model.ngeom) if model.geom(i).name.endswith("_capsule")]
    a0, b0 = np.asarray(post["p0"]), np.asarray(post["p1"])
    for qk in q[::5]:
        segs, radii = capsule_segments(model, data, qk, names)
        for (a, b), r in zip(segs, radii):  # segment–segment distance by dense sampling of one of them
            pts = a + np.linspace(0, 1, 401)[:, None] * (b - a)
            d = min(point_segment_distance(x, a0, b0) for x in pts) - r - post["radius"]
            assert d >= 0.02 - 1e-4
    duration = float(re.search(rf"retimed .*?: ({FLOAT}) s", out).group(1))
    travel = np.abs(np.diff(q, axis=0)).sum(axis=0)  # the spline through the rows travels at least this far
    assert duration >= (travel / IIWA_V_MAX).max() - 1e-6
    lines = {m.group(1): int(m.group(2)) for m in re.finditer(r"δ = (0\.\d\d) held on branch 1: (\d+) waypoints", out)}
    assert lines["0.00"] > 0 and lines["0.70"] == 0
    assert "FAIL" not in out


# ---- examples/baxter_search_plan.py ---------------------------------------------------------------------------


def test_baxter_search_plan(run_example) -> None:
    """Baxter's right arm (no closed form, the 1-D search): the slots printed reach the pose (their FK errors and
    the configuration the pose came from among them); the plan's CSV rows reach the example's path (its formula
    written here) by MuJoCo's kinematics of the URDF to 1e-9, inside the URDF's limits (read here from the file) and
    within the joint-step bound."""
    import xml.etree.ElementTree as ET

    from conftest import model_robot, mujoco_poses

    result = run_example("baxter_search_plan")
    out = result.stdout
    assert "family locked_search" in out and "axes 1-2 69 mm apart" in out and "FAIL" not in out
    errors = [float(x) for x in re.findall(rf"FK error ({FLOAT})", out)]
    assert len(errors) >= 2 and max(errors) < 1e-12
    q0 = np.array([0.3, -0.4, 0.5, 1.2, -0.3, 0.8, 0.2])
    slot = re.search(r"came from is slot (\d+) \(to (" + FLOAT + r") rad\)", out)
    assert float(slot.group(2)) < 1e-9
    printed = re.search(rf"slot +{slot.group(1)}: q = \[([^\]]*)\]", out).group(1)
    np.testing.assert_allclose(np.array(printed.split(), float), q0, atol=1e-3)
    robot = model_robot("erd_baxter")
    path = mujoco_poses(robot, q0 + np.linspace(0.0, 1.0, 15)[:, None] * np.array([0.4, 0.3, -0.3, -0.4, 0.3, -0.3,
                                                                                     0.4]))  # fmt: skip
    with open(result.out / "baxter_plan.csv") as f:
        rows = list(csv.reader(f))[1:]
    q = np.array([[float(v) for v in row[2:9]] for row in rows])
    assert q.shape == (15, 7)
    np.testing.assert_allclose(mujoco_poses(robot, q), path, atol=1e-9)
    urdf = ET.parse(robot.model.path).getroot()
    names = ["right_s0", "right_s1", "right_e0", "right_e1", "right_w0", "right_w1", "right_w2"]
    limits = {j.get("name"): j.find("limit") for j in urdf.iter("joint")}
    lo, hi = (np.array([float(limits[n].get(k)) for n in names]) for k in ("lower", "upper"))
    assert np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12)
    assert np.all(np.abs(np.diff(q, axis=0)) <= 0.1 + 1e-9)


# ---- examples/tiago_general_arm.py ----------------------------------------------------------------------------


def test_tiago_general_arm(run_example) -> None:
    """The TIAGo Pro's left arm (the general 6-R family): every slot of its CSV reaches the pose of the example's
    configuration by MuJoCo's kinematics of the URDF to 1e-10, the configuration itself among them; the printed
    sets say they are sampled; the best answer's CSV row reaches the pose inside the limits, its margin (computed
    here) the one printed and at least the configuration's own."""
    from conftest import model_robot, mujoco_poses

    result = run_example("tiago_general_arm")
    out = result.stdout
    assert "family locked_general" in out and "sampled, not proved" in out and "not certified" in out
    robot = model_robot("erd_tiago_pro")
    q0 = np.array([0.4, -0.6, 0.8, 1.1, -0.5, 0.7, 0.3])
    T = mujoco_poses(robot, q0[None])[0]
    slots = np.loadtxt(result.out / "tiago_slots.csv", delimiter=",", skiprows=1, ndmin=2)
    q = slots[:, 1:8]
    np.testing.assert_allclose(mujoco_poses(robot, q), np.broadcast_to(T, (len(q), 4, 4)), atol=1e-10)
    assert np.abs((q - q0 + np.pi) % (2 * np.pi) - np.pi).max(axis=1).min() < 1e-9
    best = np.loadtxt(result.out / "tiago_best.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(mujoco_poses(robot, best[None])[0], T, atol=1e-9)
    half = 0.5 * (robot.q_max - robot.q_min)
    margin = np.min(np.minimum(best - robot.q_min, robot.q_max - best) / half)
    printed = float(re.search(rf"margin ({FLOAT})", out).group(1))
    assert margin == pytest.approx(printed, abs=1e-9) and margin >= 0.0
    assert margin >= np.min(np.minimum(q0 - robot.q_min, robot.q_max - q0) / half) - 1e-9
