"""Shared fixtures, hypothesis strategies and finite-difference helpers.

Use them from any test module (pytest imports this file automatically; import
the helpers with ``from conftest import ...``):

- ``ARMS``: the names of the built-in arms; the ``robot`` fixture is
  parametrised over them (``def test_x(robot): ...`` runs once per arm).
- ``MODELS``: arms from model files written by others (URDFs of the ``pybullet`` and
  ``example-robot-data`` packages of the test extra, MJCF copied into ``tests/models``);
  ``model_robot(key)`` loads one (cached), the ``loaded`` fixture is parametrised over them. ``MADE``: files
  made from them, ``"xarm7_offset"`` (an arm of no closed-form family), ``"gen3_spherical"`` (the Gen3 with a
  spherical wrist) and ``"sawyer_exact"`` (the Sawyer's quaternions unrounded), which ``model_robot`` loads too.
- ``random_q(robot, n, seed, margin=0.0)``: ``(n, 7)`` configurations drawn
  uniformly inside ``[q_min + margin, q_max - margin]`` (a numpy generator
  seeded with ``seed``). Draw many at once so that 10,000 configurations cost
  one batched call; hypothesis then draws the *seed*::

      @settings(max_examples=5, deadline=None)
      @given(seed=SEEDS)
      def test_something(robot, seed):
          q = random_q(robot, 2000, seed)

- ``random_robot(seed, convention)``: a 7-joint DH arm (``"standard"`` or ``"modified"``)
  with random lengths, twists, offsets, limits, base and tool transforms.
- ``q_within_limits(robot)``: a hypothesis strategy of one ``(7,)``
  configuration inside the limits (shrinks joint by joint), for tests that
  need single draws.
- ``matrix_function(name)``: a small CasADi function with non-symmetric matrix inputs and
  outputs, for the compiled-call tests (a row/column-major mix-up changes its answer).
- ``LARGE``: true with ``QPIK_TESTS_LARGE=1``: the sweeps that take a seeded subset by default
  (episodes, fuzzed plans, solve_best poses) then run their full count.
- ``fd(f, q, eps=1e-6)``: central finite differences of any ``f(q) -> array``;
  works on one ``q`` (n,) and on a batch ``(N, n)`` when ``f`` is batched.
  Returns ``(..., n)`` with the derivative index last: for ``f`` returning
  (N, 4, 4), the result is (N, 4, 4, n).
- ``fd_geometric_jacobian(fk, q, eps=1e-6)``: the geometric Jacobian
  ``[v; ω]`` (base frame) from FK alone: ``v = ∂p/∂q``, and the angular part
  from the rotation derivative, ``[ω_k]_× = (∂R/∂q_k) Rᵀ``. Shapes as ``fk``:
  (6, n) for one q, (N, 6, n) for a batch.

Central differences with ``eps = 1e-6`` have truncation error ~eps² and
round-off ~1e-16/eps, so agreement to 1e-6 (absolute) is a meaningful test.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

# The suite's matrices are a few rows wide: a BLAS thread pool in each pytest worker only oversubscribes the cores
# (then one scipy.linalg.expm of a 4 × 4 waits on threads for milliseconds). Set before numpy is first imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
# gcc's -O0 for every generated library: the same IEEE arithmetic as the default -O2 in a third of -O1's compile
# time; the suite builds hundreds of small libraries from an empty compile cache and runs most of them a few times.
# `qpik demo` in CI part 1 compiles with the defaults.
os.environ.setdefault("QPIK_OPTIMISE", "-O0")

import casadi as ca
import numpy as np
import pytest
from hypothesis import settings
from hypothesis import strategies as st

import qpik  # first: it chooses MuJoCo's GL backend before any test module imports mujoco
from qpik.core.validate import project_to_so3
from qpik.robots.dh import DHChain
from qpik.robots.model_files import MeshOptions
from qpik.robots.robot import Robot, default_capsules

ARMS = ("nammoto7", "iiwa14", "zheng7", "panda")
LARGE = os.environ.get("QPIK_TESTS_LARGE", "") not in ("", "0")
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)
MODEL_DIR = Path(__file__).parent / "models"

# "reproducible" (the default): every run draws the same examples (a seed per test), so a CI run on a
# clean checkout repeats the last one; HYPOTHESIS_PROFILE=explore draws new examples on every run.
settings.register_profile("reproducible", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "reproducible"))


def matrix_function(name: str = "f") -> ca.Function:
    """Non-symmetric matrix and vector in; matrix, vector and row out: catches row/column-major mix-ups."""
    A = ca.SX.sym("A", 2, 3)
    x = ca.SX.sym("x", 3)
    return ca.Function(name, [A, x], [ca.mtimes(A, x), ca.sin(A).T @ A, ca.sum1(x) * ca.DM([[1, 2, 3]])])


def packaged(key: str) -> Path:
    """A model file of another package (qpik.robots.packaged); skips when the test extra is missing."""
    from qpik.core.errors import InputError
    from qpik.robots.packaged import packaged_model

    try:
        return packaged_model(key)
    except InputError as exc:
        pytest.skip(str(exc))


_SCRATCH: list = []


def scratch(prefix: str) -> Path:
    """A new folder for a model variant written by a test, inside one temporary folder removed when the session ends."""
    import tempfile

    if not _SCRATCH:
        _SCRATCH.append(tempfile.TemporaryDirectory(prefix="qpik-tests-"))
    return Path(tempfile.mkdtemp(prefix=prefix, dir=_SCRATCH[0].name))


def xarm7_offset() -> tuple[Path, dict]:
    """example-robot-data's xArm7 with joint 3 moved 1 mm along link 2's x (axis 3 then passes 1 mm from the shoulder
    point, twice the near tolerance): a 7-R arm of no closed-form family, written to a temporary folder."""
    path = packaged("erd/xarm7")
    text = path.read_text()
    joint3 = '<origin rpy="1.5708 0 0" xyz="0 -0.293 0"/>'
    assert text.count(joint3) == 1
    out = scratch("xarm7-offset-") / "xarm7_offset.urdf"
    out.write_text(text.replace(joint3, '<origin rpy="1.5708 0 0" xyz="0.001 -0.293 0"/>'))
    return out, {"meshes": MeshOptions(package_map={"example-robot-data": path.parents[3]})}


def robosuite(arm: str) -> tuple[Path, dict]:
    """A robosuite arm copied into tests/models (its visual meshes left out) and its load options."""
    return MODEL_DIR / f"robosuite_{arm}/robot.xml", {"meshes": MeshOptions(collision_only=True)}


def gen3_spherical() -> tuple[Path, dict]:
    """robosuite's Kinova Gen3 with the 0.175 mm offsets of joints 6 and 7 removed (axes 5, 6, 7 then meet in one
    point, the spherical wrist of Kinova's DH table) and its quarter turns exact (the file's quaternions, such as
    (0.707105, 0.707108, 0, 0), are 4e-6 rad off): an exact member of the locked-q1 family, written with its meshes to
    a temporary folder."""
    import shutil

    source = MODEL_DIR / "robosuite_gen3"
    text = (source / "robot.xml").read_text()
    offsets = {
        'pos="0 0.00017505 -0.10593"': 'pos="0 0 -0.10593"',
        'pos="0 -0.10593 -0.00017505"': 'pos="0 -0.10593 0"',
        'quat="-3.67321e-06 1 0 0"': 'quat="0 1 0 0"',
        'quat="0 0.707105 -0.707108 0"': 'quat="0 1 -1 0"',
    }
    folder = scratch("gen3-spherical-")
    shutil.copytree(source / "meshes", folder / "meshes")
    for old, new in offsets.items():
        assert text.count(old) == 1
        text = text.replace(old, new)
    text = text.replace('quat="0.707105 0.707108 0 0"', 'quat="1 1 0 0"').replace(
        'quat="0.707105 -0.707108 0 0"', 'quat="1 -1 0 0"'
    )
    (folder / "robot.xml").write_text(text)
    return folder / "robot.xml", robosuite("gen3")[1]


def sawyer_exact() -> tuple[Path, dict]:
    """robosuite's Sawyer with joint 7's quaternion written exactly ((0.06163, 0.06163, -0.704416, 0.704416) for the
    file's 0.0616248 first entry, whose rounding puts axes 6 and 7 0.8 µm apart): an exact member of the geometry of
    the 1-D search (qpik.analytic.locked_search), written to a temporary folder."""
    text = (MODEL_DIR / "robosuite_sawyer/robot.xml").read_text()
    old = 'quat="0.0616248 0.06163 -0.704416 0.704416"'
    assert text.count(old) == 1
    out = scratch("sawyer-exact-") / "robot.xml"
    out.write_text(text.replace(old, 'quat="0.06163 0.06163 -0.704416 0.704416"'))
    return out, robosuite("sawyer")[1]


MODELS: dict[str, Callable[[], tuple[Path, dict]]] = {
    "pybullet_iiwa": lambda: (packaged("pybullet/iiwa"), {}),
    "pybullet_panda": lambda: (packaged("pybullet/panda"), {}),
    "erd_panda": lambda: (packaged("erd/panda"), {}),
    "erd_xarm7": lambda: (packaged("erd/xarm7"), {}),
    "erd_talos": lambda: (packaged("erd/talos"), {"base": "torso_2_link", "tip": "arm_left_7_link"}),
    "erd_tiago_pro": lambda: (packaged("erd/tiago_pro"), {"base": "torso_lift_link", "tip": "arm_left_tool_link"}),
    "erd_baxter": lambda: (packaged("erd/baxter"), {"base": "right_arm_mount", "tip": "right_wrist"}),
    "robosuite_iiwa": lambda: robosuite("iiwa"),
    "robosuite_gen3": lambda: robosuite("gen3"),
    "robosuite_sawyer": lambda: robosuite("sawyer"),
    "robosuite_jaco": lambda: robosuite("jaco"),
    "pusher": lambda: (MODEL_DIR / "gymnasium_pusher/pusher_v5.xml", {"tip": "tips_arm"}),
}
MADE: dict[str, Callable[[], tuple[Path, dict]]] = {
    "xarm7_offset": xarm7_offset,
    "gen3_spherical": gen3_spherical,
    "sawyer_exact": sawyer_exact,
}
"""Model files made for the tests (``model_robot`` loads them too; not among the ``loaded`` arms)."""
_loaded: dict[str, qpik.Robot] = {}


def model_robot(key: str) -> qpik.Robot:
    """The arm of ``MODELS[key]`` or ``MADE[key]`` (loaded once per session)."""
    if key not in _loaded:
        path, options = (MODELS | MADE)[key]()
        _loaded[key] = qpik.load_robot(path, **options)
    return _loaded[key]


@pytest.fixture(params=list(MODELS), scope="session")
def loaded(request: pytest.FixtureRequest) -> qpik.Robot:
    """Each arm of ``MODELS`` in turn."""
    return model_robot(request.param)


@pytest.fixture(params=ARMS, scope="session")
def robot(request: pytest.FixtureRequest) -> qpik.Robot:
    """Each built-in arm in turn (session scope: robots are immutable, so hypothesis may reuse it)."""
    return qpik.load_robot(request.param)


def random_q(robot: qpik.Robot, n: int, seed: int, margin: float = 0.0) -> np.ndarray:
    """``(n, dof)`` configurations uniform in ``[q_min + margin, q_max - margin]`` (rad)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.q_min + margin, robot.q_max - margin, size=(n, robot.dof))


def random_robot(seed: int, convention: str) -> Robot:
    """A DH arm with random lengths, twists, offsets, base and tool transforms."""
    rng = np.random.default_rng(seed)
    n = 7

    def transform() -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = project_to_so3(rng.normal(size=(3, 3)))
        T[:3, 3] = rng.uniform(-0.3, 0.3, 3)
        return T

    chain = DHChain(
        a=tuple(rng.uniform(-0.3, 0.3, n)),
        d=tuple(rng.uniform(-0.4, 0.4, n)),
        alpha=tuple(rng.uniform(-np.pi, np.pi, n)),
        offset=tuple(rng.uniform(-np.pi, np.pi, n)),
        convention=convention,
        base=transform(),
        tool=transform(),
    )
    lim = rng.uniform(1.0, 3.0, n)
    return Robot(
        name=f"random_{convention}",
        chain=chain,
        q_min=-lim,
        q_max=lim,
        v_max=np.ones(n),
        q_home=np.zeros(n),
        capsules=default_capsules(chain, tuple(rng.uniform(0.02, 0.08, n))),
    )


def q_within_limits(robot: qpik.Robot) -> st.SearchStrategy[np.ndarray]:
    """Hypothesis strategy: one configuration ``(dof,)`` inside the joint limits."""
    joints = [st.floats(lo, hi, allow_nan=False) for lo, hi in zip(robot.q_min, robot.q_max)]
    return st.tuples(*joints).map(np.array)


def fd(f: Callable[[np.ndarray], np.ndarray], q: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Central differences ``∂f/∂q_k``, stacked on a new last axis: (..., n)."""
    q = np.asarray(q, dtype=float)
    cols = []
    for k in range(q.shape[-1]):
        dq = np.zeros_like(q)
        dq[..., k] = eps
        cols.append((np.asarray(f(q + dq)) - np.asarray(f(q - dq))) / (2 * eps))
    return np.stack(cols, axis=-1)


def fd_geometric_jacobian(fk: Callable[[np.ndarray], np.ndarray], q: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Geometric Jacobian ``[v; ω]`` (base frame) by central differences of ``fk``: (6, n) or (N, 6, n)."""
    T = fk(q)
    dT = fd(fk, q, eps)  # (..., 4, 4, n)
    Jv = dT[..., :3, 3, :]
    # W_k = (∂R/∂q_k) Rᵀ is skew: W = [ω]_×, ω = (W21, W02, W10)
    W = np.einsum("...ijk,...lj->...kil", dT[..., :3, :3, :], T[..., :3, :3])  # (..., n, 3, 3)
    Jw = np.stack([W[..., 2, 1], W[..., 0, 2], W[..., 1, 0]], axis=-2)
    return np.concatenate([Jv, Jw], axis=-2)


def mujoco_poses(robot: qpik.Robot, Q: np.ndarray, model=None, body: str | None = None) -> np.ndarray:
    """Poses (N, 4, 4) by MuJoCo's own kinematics of a loaded arm's model (default ``robot.mj_model()``):
    of the end-effector site, or of ``body``; the model's other joints at their reference."""
    import mujoco  # here, not at the top: qpik must choose MuJoCo's GL backend before mujoco is imported

    model = robot.mj_model() if model is None else model
    data = mujoco.MjData(model)
    adr = [model.jnt_qposadr[model.joint(n).id] for n in robot.joint_names]
    out = np.zeros((len(Q), 4, 4))
    for i, q in enumerate(np.atleast_2d(Q)):
        data.qpos[:] = model.qpos0
        data.qpos[adr] = q
        mujoco.mj_kinematics(model, data)
        if body is None:
            R, p = data.site_xmat[model.site(robot.site).id], data.site_xpos[model.site(robot.site).id]
        else:
            R, p = data.xmat[model.body(body).id], data.xpos[model.body(body).id]
        out[i, :3, :3], out[i, :3, 3], out[i, 3, 3] = R.reshape(3, 3), p, 1.0
    return out
