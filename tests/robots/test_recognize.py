"""Closed forms found in loaded chains: which arms are recognised (and why not), and the closed form through
the joint map — branches checked by MuJoCo's FK of the model, against redundancy_parameter, single against
batch, and feasible intervals against dense sampling, also with joint-axis flips, zero offsets and limits
wider than ±π.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import MADE, MODEL_DIR, MODELS, model_robot, mujoco_poses, random_q

import qpik
from qpik.core.errors import NoClosedFormError
from qpik.robots.model_files import MeshOptions
from qpik.robots.recognize import recognize


@pytest.mark.parametrize("name", ["iiwa14", "nammoto7"])
def test_catalog_tables_are_recognised_as_themselves(name):
    robot = qpik.load_robot(name)
    found, why = recognize(robot.chain)
    assert why == "" and found.kind == robot.closed_form and found.joints.identity
    for field in ("a", "d", "alpha", "offset"):
        np.testing.assert_allclose(getattr(found.table, field), getattr(robot.chain, field), atol=1e-12)


def test_the_kuka_urdf_is_the_catalog_iiwa14():
    """pybullet's KUKA URDF (joint signs as KUKA's) maps to iiwa14's table without flips or shifts."""
    robot, iiwa = model_robot("pybullet_iiwa"), qpik.load_robot("iiwa14")
    assert robot.closed_form == "srs" and robot.canonical.joints.identity
    np.testing.assert_allclose(robot.canonical.table.d[:6], iiwa.chain.d[:6], atol=1e-9)


@pytest.mark.parametrize(
    ("key", "redundancy", "why"),
    [
        ("xarm7_offset", "psi", "not srs: axes 1-2-3 do not intersect"),
        ("erd_tiago_pro", "delta", "not offset-shoulder: axes 1-2-3 do not intersect (offsets 0.02 m)"),
    ],
)
def test_other_arms_say_why(key, redundancy, why):
    """Asked for a parameter of a family they do not fit, arms say why (the TIAGo Pro's own family is the general one,
    :mod:`qpik.analytic.general_solver`)."""
    path, options = (MODELS | MADE)[key]()
    robot = qpik.load_robot(path, redundancy=redundancy, **options)
    assert robot.closed_form is None and why in robot.notes
    with pytest.raises(NoClosedFormError, match=why.split(":")[1].strip()[:20]):
        qpik.ik(robot, robot.fk(robot.q_home), 0.0)


def test_the_pusher_is_an_offset_shoulder_arm_with_flips_and_offsets():
    found = model_robot("pusher").canonical
    assert found.kind == "offset_shoulder"
    assert (found.joints.sign == -1).any() and (found.joints.shift != 0).any()


def modified_iiwa(tmp_path) -> qpik.Robot:
    """robosuite's iiwa with joints 2 and 5 turned the other way, zero offsets (``ref``) on joints 3 and 6,
    joint 1 over [-1, 6.5] rad and joint 7 continuous."""
    text = (MODEL_DIR / "robosuite_iiwa/robot.xml").read_text()
    meshdir = MODEL_DIR / "robosuite_iiwa"
    text = text.replace('<compiler angle="radian"/>', f'<compiler angle="radian" meshdir="{meshdir}"/>')
    for name, old, new in [
        ("joint_2", 'axis="0 0 1"', 'axis="0 0 -1"'),
        ("joint_5", 'axis="0 0 1"', 'axis="0 0 -1"'),
        ("joint_3", 'pos="0 0 0"', 'pos="0 0 0" ref="0.7"'),
        ("joint_6", 'pos="0 0 0"', 'pos="0 0 0" ref="-1.9"'),
        ("joint_1", 'range="-2.96706 2.96706"', 'range="-1 6.5"'),
        ("joint_7", 'limited="true"', 'limited="false"'),
    ]:
        head, tail = text.split(f'name="{name}"', 1)
        end = tail.index("/>")
        text = head + f'name="{name}"' + tail[:end].replace(old, new) + tail[end:]
    path = tmp_path / "iiwa_modified.xml"
    path.write_text(text)
    return qpik.load_robot(
        path, meshes=MeshOptions(collision_only=True, allow_outside=True)
    )  # its meshdir is the original folder


@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    return {
        "pybullet_iiwa": model_robot("pybullet_iiwa"),
        "robosuite_iiwa": model_robot("robosuite_iiwa"),
        "modified_iiwa": modified_iiwa(tmp_path_factory.mktemp("iiwa")),
        "pusher": model_robot("pusher"),
    }


@pytest.mark.parametrize("key", ["pybullet_iiwa", "robosuite_iiwa", "modified_iiwa", "pusher"])
def test_branches_reach_random_poses_by_mujoco(arms, key):
    """Every valid branch of every pose reaches it to 1e-9 by MuJoCo's FK; the configuration the pose came
    from is the branch redundancy_parameter names; single = batch."""
    robot = arms[key]
    Q = random_q(robot, 100, 11)
    T = mujoco_poses(robot, Q)
    param, branch = qpik.redundancy_parameter(robot, Q)
    sols = qpik.ik(robot, T, param)
    reached = mujoco_poses(robot, sols.q[sols.valid])
    np.testing.assert_allclose(reached, np.repeat(T, sols.valid.sum(1), axis=0), atol=1e-9)
    own = sols.q[np.arange(len(Q)), [np.flatnonzero(sols.branch == b)[0] for b in branch]]
    np.testing.assert_allclose(np.cos(own - Q), 1.0, atol=1e-12)  # the same angles, up to 2πk
    one = qpik.ik(robot, T[0], float(param[0]))
    np.testing.assert_allclose(one.q, sols.q[0], atol=1e-12)
    np.testing.assert_array_equal(one.within_limits, sols.within_limits[0])


def test_wide_limits_give_the_representative_inside(arms):
    """Joint 1 spans [-1, 6.5] rad, joint 7 is continuous (±2π): a branch is within limits iff some q + 2πk is."""
    robot = arms["modified_iiwa"]
    assert robot.q_max[0] == 6.5 and robot.q_max[6] == pytest.approx(2 * np.pi)
    Q = random_q(robot, 200, 12)
    T = robot.fk(Q)
    sols = qpik.ik(robot, T, np.random.default_rng(0).uniform(-np.pi, np.pi, 200))
    q = sols.q[sols.valid]
    k = np.arange(-2, 3) * 2 * np.pi
    moved = q[..., None] + k
    some = np.all(np.any((moved >= robot.q_min[:, None]) & (moved <= robot.q_max[:, None]), -1), -1)
    np.testing.assert_array_equal(sols.within_limits[sols.valid], some)
    assert robot.within_limits(q[sols.within_limits[sols.valid]]).all()
    assert (np.abs(q[:, 0]) > np.pi).any()  # representatives beyond ±π were used


@pytest.mark.parametrize("key", ["modified_iiwa", "pusher", "pybullet_iiwa"])
def test_feasible_intervals_match_dense_sampling(arms, key):
    robot = arms[key]
    params = np.linspace(-np.pi, np.pi, 3001)
    for q in random_q(robot, 4, 13):
        T = robot.fk(q)
        fi = qpik.feasible_intervals(robot, T)
        sols = qpik.ik(robot, np.repeat(T[None], len(params), 0), params)
        for i, b in enumerate(sols.branch):
            inside = fi.contains(b, params)
            near = np.zeros(len(params), bool)
            for lo, hi in fi[b]:
                near |= (np.abs(params - lo) < 1e-6) | (np.abs(params - hi) < 1e-6)
            np.testing.assert_array_equal(inside[~near], sols.within_limits[~near, i])


def test_limit_overrides_keep_the_map():
    robot = model_robot("robosuite_iiwa")
    narrow = dataclasses.replace(robot, q_max=robot.q_max * 0.5, q_min=robot.q_min * 0.5)
    T = robot.fk(robot.q_home + 0.3)
    assert qpik.ik(narrow, T, 0.2).within_limits.sum() <= qpik.ik(robot, T, 0.2).within_limits.sum()


def _meeting_point(model, data, i: int, j: int) -> np.ndarray:
    """The midpoint of the common normal of joints i and j's axis lines (0-based, MuJoCo's world frame)."""
    p, u, q, v = data.xanchor[i], data.xaxis[i], data.xanchor[j], data.xaxis[j]
    A = np.array([[u @ u, -(u @ v)], [u @ v, -(v @ v)]])
    s, t = np.linalg.solve(A, [(q - p) @ u, (q - p) @ v])
    return 0.5 * (p + s * u + q + t * v)


@pytest.mark.parametrize("key", ["pybullet_iiwa", "robosuite_iiwa"])
def test_an_srs_files_notes_give_its_lengths(key):
    """The notes of a loaded S-R-S arm name the family, its parameter and solver, and its upper arm and forearm in mm:
    the distances between the points where axes 1 and 2, 3 and 4, 5 and 6 meet, by MuJoCo's own axes at q = 0."""
    import mujoco  # here: qpik chooses MuJoCo's GL backend before mujoco is imported

    robot = model_robot(key)
    model = robot.mj_model()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ids = [model.joint(n).id for n in robot.joint_names]
    S, E, W = (_meeting_point(model, data, ids[i], ids[i + 1]) for i in (0, 2, 4))
    assert robot.notes.startswith("closed form along the arm angle ψ (parameter psi, 8 branches")
    assert "qpik.analytic.srs" in robot.notes
    for name, length in (("shoulder to elbow", np.linalg.norm(E - S)), ("elbow to wrist", np.linalg.norm(W - E))):
        said = float(robot.notes.split(f"{name} ")[1].split(" mm")[0])
        assert said == pytest.approx(1e3 * length, abs=0.05), (name, said, length)


def test_an_offset_shoulder_files_notes_give_its_offset():
    """The gymnasium pusher's notes name the offset-shoulder family, δ and its solver, and the offset in mm: the
    length of the common normal of axes 1 and 2 by MuJoCo's own axes at q = 0."""
    import mujoco

    robot = model_robot("pusher")
    model = robot.mj_model()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    i, j = (model.joint(n).id for n in robot.joint_names[:2])
    u, v = data.xaxis[i], data.xaxis[j]
    n = np.cross(u, v)
    offset = abs((data.xanchor[j] - data.xanchor[i]) @ n) / np.linalg.norm(n)
    assert robot.notes.startswith("closed form along δ (parameter delta, 16 branches")
    assert "qpik.analytic.offset_shoulder" in robot.notes
    said = float(robot.notes.split("shoulder offset ")[1].split(" mm")[0])
    assert said == pytest.approx(1e3 * offset, abs=0.05)
