"""Closed-form IK of the offset-shoulder arm (nammoto7): checked by FK, finite differences and dense δ sweeps."""

import dataclasses
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import SEEDS, model_robot, random_q
from hypothesis import given, settings
from hypothesis import strategies as st

import qpik
from qpik.analytic.api import closed_form_for
from qpik.analytic.intervals import shrunk_limits, wrap
from qpik.analytic.offset_shoulder_intervals import DeltaIntervals
from qpik.problems import load as load_problem

ROOT = Path(__file__).resolve().parents[2]
ROBOT = qpik.load_robot("nammoto7")
SOLVER = closed_form_for(ROBOT)


def pose_error(T: np.ndarray, T_ref: np.ndarray) -> np.ndarray:
    """Max position error (m) and max rotation-entry error, (...,) each."""
    return np.abs(T[..., :3, 3] - T_ref[..., :3, 3]).max(-1), np.abs(T[..., :3, :3] - T_ref[..., :3, :3]).max((-2, -1))


def well_conditioned(q: np.ndarray, tol: float = 1e-2) -> np.ndarray:
    """Away from the elbow (cos θ4 = 0), shoulder (cos θ3 cos θ4 = 0) and wrist (sin θ6 = 0) singularities
    and from the base axis: there a joint error of 1e-8 is ill-conditioning, not a bug."""
    w = ROBOT.frames(q)[:, 5, :3, 3]
    c3, c4, s6 = np.cos(q[:, 2]), np.cos(q[:, 3]), np.sin(q[:, 5])
    return (np.abs(c4) > tol) & (np.abs(c3 * c4) > tol) & (np.abs(s6) > tol) & (np.hypot(w[:, 0], w[:, 1]) > tol)


# ---- Nammoto & Kosuge 2012, Table 4 -----------------------------------------------------


def test_table4_reproduced():
    problem = load_problem(ROOT / "problems" / "nammoto2012_table4.toml")
    T, delta = problem.poses[0], float(problem.params[0])
    sol = qpik.ik(problem.robot, T, delta)
    expected = np.asarray(problem.expected["q"], float)
    assert list(sol.branch) == list(problem.expected["branches"])
    assert sol.valid.all()
    assert np.abs(wrap(sol.q - expected)).max() <= problem.expected["tolerance"]
    dp, dR = pose_error(ROBOT.fk(sol.q), T)  # T is the projected pose
    assert dp.max() < 1e-9 and dR.max() < 1e-9


# ---- FK, round trip, inverse map -------------------------------------------


@settings(max_examples=5, deadline=None)
@given(SEEDS)
def test_every_valid_branch_reproduces_the_pose(seed):
    q = random_q(ROBOT, 2000, seed)
    T = ROBOT.fk(q)
    delta = np.random.default_rng(seed).uniform(-np.pi, np.pi, len(q))  # any δ, not only the generating one
    sol = qpik.ik(ROBOT, T, delta)
    assert np.all(np.isfinite(sol.q))
    assert np.all((sol.q > -np.pi) & (sol.q <= np.pi))
    F = ROBOT.fk(sol.q.reshape(-1, 7)).reshape(len(q), 16, 4, 4)
    dp, dR = pose_error(F, T[:, None])
    assert dp[sol.valid].max() < 1e-9 and dR[sol.valid].max() < 1e-9
    assert sol.valid.any(axis=1).mean() > 0.5


@settings(max_examples=5, deadline=None)
@given(SEEDS)
def test_generating_configuration_is_a_branch_at_its_delta(seed):
    q = random_q(ROBOT, 2000, seed)
    delta, branch = qpik.redundancy_parameter(ROBOT, q)
    assert np.all((delta > -np.pi / 2) & (delta <= np.pi / 2))
    sol = qpik.ik(ROBOT, ROBOT.fk(q), delta)
    Q = sol.q[np.arange(len(q)), branch - 1]
    good = well_conditioned(q)
    assert good.mean() > 0.8
    assert sol.valid[np.arange(len(q)), branch - 1].all()
    assert np.abs(wrap(Q - q))[good].max() < 1e-8
    # near-singular ones: the branch still reproduces the pose
    dp, dR = pose_error(ROBOT.fk(Q), ROBOT.fk(q))
    assert dp.max() < 1e-9 and dR.max() < 1e-9


@settings(max_examples=3, deadline=None)
@given(SEEDS)
def test_redundancy_parameter_inverts_ik(seed):
    rng = np.random.default_rng(seed)
    T = ROBOT.fk(random_q(ROBOT, 500, seed))
    delta = rng.uniform(-np.pi, np.pi, len(T))
    sol = qpik.ik(ROBOT, T, delta)
    n, k = np.nonzero(sol.valid)
    q = sol.q[n, k]
    d2, b2 = qpik.redundancy_parameter(ROBOT, q)
    # (δ, k) and (δ + π, k ± 8) are the same configuration; the map returns |δ| <= π/2
    same = (np.abs(wrap(d2 - delta[n])) < 1e-9) & (b2 == k + 1)
    shifted = (np.abs(wrap(d2 - delta[n] - np.pi)) < 1e-9) & (b2 == (k + 8) % 16 + 1)
    good = well_conditioned(q)
    assert np.all((same | shifted)[good])


# ---- near-singular and singular configurations -----------------------------


def _near(seed: int, n: int, joint: int, centre: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = random_q(ROBOT, n, seed)
    eps = 10.0 ** rng.uniform(-7, -3, n) * rng.choice([-1, 1], n)
    q[:, joint] = centre + eps
    return q


@pytest.mark.parametrize(("joint", "centre"), [(5, 0.0), (3, np.pi / 2), (3, -np.pi / 2), (2, np.pi / 2)])
def test_near_singular_configurations(joint, centre):
    q = _near(joint, 2000, joint, centre)
    T = ROBOT.fk(q)
    delta, branch = qpik.redundancy_parameter(ROBOT, q)
    sol = qpik.ik(ROBOT, T, delta)
    idx = (np.arange(len(q)), branch - 1)
    assert sol.valid[idx].all()
    dp, dR = pose_error(ROBOT.fk(sol.q[idx]), T)
    assert dp.max() < 1e-9 and dR.max() < 1e-9


@pytest.mark.parametrize(("joint", "value"), [(5, 0.0), (3, np.pi / 2), (3, -np.pi / 2)])
def test_exactly_singular_configurations_are_flagged(joint, value):
    q = random_q(ROBOT, 500, 7)
    q[:, joint] = value
    T = ROBOT.fk(q)
    delta, branch = qpik.redundancy_parameter(ROBOT, q)
    sol = qpik.ik(ROBOT, T, delta)
    idx = (np.arange(len(q)), branch - 1)
    assert sol.singular[idx].all()
    dp, dR = pose_error(ROBOT.fk(sol.q[idx]), T)  # sqrt(eps)-conditioned at the singularity
    assert dp.max() < 1e-7 and dR.max() < 1e-7


def test_wrist_centre_on_or_near_the_base_axis():
    rng = np.random.default_rng(3)
    n = 400
    R = ROBOT.fk(random_q(ROBOT, n, 3))[:, :3, :3]
    off = np.zeros((n, 2))
    off[n // 2 :] = rng.normal(size=(n - n // 2, 2)) * 10.0 ** rng.uniform(-12, -4, (n - n // 2, 1))
    w = np.column_stack([off, rng.uniform(0.0, 0.6, n)])
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = w - 0.065 * R[:, :, 2]  # eq. (5): w = p + d7 b, d7 = 0.065
    delta = rng.uniform(-np.pi, np.pi, n)
    sol = qpik.ik(ROBOT, T, delta)
    assert np.all(np.isfinite(sol.q)) and sol.valid.any()
    assert sol.singular[: n // 2].all()  # exactly on the axis
    F = ROBOT.fk(sol.q.reshape(-1, 7)).reshape(n, 16, 4, 4)
    dp, dR = pose_error(F, T[:, None])
    assert dp[sol.valid].max() < 1e-9 and dR[sol.valid].max() < 1e-9
    # on the axis atan2(wy, wx) := 0, so θ1[1] = δ (documented convention)
    assert np.abs(wrap(sol.q[: n // 2, :8, 0] - delta[: n // 2, None])).max() < 1e-12


# ---- three evaluations agree; exact derivatives ----------------------------


def test_batch_single_and_casadi_agree():
    q = random_q(ROBOT, 20, 11)
    T = ROBOT.fk(q)
    delta = np.random.default_rng(11).uniform(-np.pi, np.pi, len(q))
    Qb, vb, sb, wb = SOLVER.solve_batch(T, delta)
    assert np.array_equal(wb, vb & ROBOT.within_limits(Qb.reshape(-1, 7)).reshape(vb.shape))
    for i in range(len(q)):
        Q1, v1, s1, w1 = SOLVER.solve_one(T[i], delta[i])
        Qc, vc, _ = SOLVER.casadi_function(ca.DM(T[i]), ca.DM(delta[i]))
        assert np.abs(wrap(Q1 - Qb[i])).max() < 1e-12
        assert np.abs(wrap(np.array(Qc) - Qb[i])).max() < 1e-12
        assert np.array_equal(v1, vb[i]) and np.array_equal(np.array(vc).ravel() > 0.5, vb[i])
        assert np.array_equal(s1, sb[i]) and np.array_equal(w1, wb[i])
    Qm, vm, sm, wm = SOLVER.solve_many(T[0], delta)
    Qr, vr, sr, wr = SOLVER.solve_batch(np.broadcast_to(T[0], T.shape), delta)
    assert np.abs(wrap(Qm - Qr)).max() < 1e-12 and np.array_equal(vm, vr) and np.array_equal(sm, sr)
    assert np.array_equal(wm, wr)


def test_casadi_jacobian_wrt_delta_matches_finite_differences():
    Ts = ca.SX.sym("T", 4, 4)
    d = ca.SX.sym("d")
    Q = SOLVER.casadi_function(Ts, d)[0]
    dQ = ca.Function("dQ", [Ts, d], [ca.jacobian(ca.vec(Q), d)])
    q = random_q(ROBOT, 10, 5)
    q = q[well_conditioned(q, 0.1)]
    checked = 0
    for Ti, di in zip(ROBOT.fk(q), qpik.redundancy_parameter(ROBOT, q)[0]):
        _, valid, sing, _ = SOLVER.solve_one(Ti, di)
        J = np.array(dQ(Ti, di)).reshape(7, 16).T  # column-major vec of (16, 7)
        h = 1e-6
        fd = wrap(SOLVER.solve_one(Ti, di + h)[0] - SOLVER.solve_one(Ti, di - h)[0]) / (2 * h)
        ok = valid & ~sing
        assert np.abs(J[ok] - fd[ok]).max() < 1e-5 * max(1.0, np.abs(fd[ok]).max())
        checked += ok.sum()
    assert checked >= 20


# ---- feasible δ intervals ---------------------------------------------------


def _sweep_check(T: np.ndarray, n_delta: int, intervals=None) -> None:
    fi = qpik.feasible_intervals(ROBOT, T) if intervals is None else intervals(T)
    d = np.linspace(-np.pi, np.pi, n_delta)
    q, valid, _, _ = SOLVER.solve_batch(np.broadcast_to(T, (n_delta, 4, 4)), d)
    ok = valid & np.all((q >= ROBOT.q_min) & (q <= ROBOT.q_max), axis=-1)
    for k in range(16):
        ivs = fi.intervals[k]
        inside = fi.contains(k + 1, d)
        ends = np.array([x for iv in ivs for x in iv if abs(abs(x) - np.pi) > 1e-12])
        far = np.abs(d[:, None] - ends[None]).min(axis=1) > 1e-6 if ends.size else np.ones(n_delta, bool)
        assert np.array_equal(inside[far], ok[far, k]), f"branch {k + 1}"
        if ends.size:  # every boundary is a true change of feasibility (at ±1e-6, or closer for a short interval)
            # distances to the neighbouring boundaries on the circle: the split of a set at ±π is not one
            order = np.argsort(ends)
            after = np.diff(np.append(ends[order], ends[order][0] + 2 * np.pi))
            h = np.empty(ends.size)
            h[order] = np.minimum(1e-6, 0.4 * np.minimum(after, np.roll(after, 1)))
            e = np.concatenate([ends - h, ends + h])
            qe, ve, _, _ = SOLVER.solve_many(T, e)
            oke = ve & np.all((qe >= ROBOT.q_min) & (qe <= ROBOT.q_max), axis=-1)
            m = ends.size
            assert np.all(oke[:m, k] != oke[m:, k]), f"branch {k + 1}: a boundary is not a feasibility change"
        for lo, hi in ivs:
            assert -np.pi <= lo <= hi <= np.pi


@settings(max_examples=50, deadline=None)
@given(SEEDS)
def test_feasible_intervals_exact_on_random_poses(seed):
    for T in ROBOT.fk(random_q(ROBOT, 10, seed)):  # 500 poses in all, 10,000 values of δ each
        _sweep_check(T, 10000)


def _same_sets(a, b) -> None:
    """Two results (sets, singular values) per row: the same pieces and values to 1e-12 rad."""
    assert [len(x) for x in a[0]] == [len(x) for x in b[0]] and [len(x) for x in a[1]] == [len(x) for x in b[1]]
    for x, y in zip(a[0] + a[1], b[0] + b[1]):
        assert np.allclose(np.array(x, float).ravel(), np.array(y, float).ravel(), rtol=0, atol=1e-12)


def _lists_in_python():
    """nammoto7's feasible-interval solver built as without the compiled extension: result lists made in Python."""
    from qpik.analytic import intervals
    from qpik.analytic.offset_shoulder_intervals import DeltaIntervals

    real, intervals.extension = intervals.extension, lambda: None
    try:
        return DeltaIntervals(SOLVER)
    finally:
        intervals.extension = real


LISTS_IN_PYTHON = _lists_in_python()


@settings(max_examples=10, deadline=None)
@given(SEEDS)
def test_one_c_call_agrees_with_its_steps(seed):
    """The C path in one call (qpik_delta_sets; its lists built by the compiled extension or in Python) gives the
    sets of its steps taken one by one: :meth:`DeltaIntervals.breakpoints`, then the SetAssembler; with a margin too."""
    native = DeltaIntervals(SOLVER)
    if native._fixed.native is None:
        pytest.skip("no C compiler: the numpy path only (test_feasible_intervals_exact_without_a_c_compiler)")
    limits = shrunk_limits(ROBOT.q_min, ROBOT.q_max, 0.3)
    for T in ROBOT.fk(random_q(ROBOT, 10, seed)):
        one = native(T)
        _same_sets((one.intervals, one.singular), native._assemble(T, *native.breakpoints(T)))
        again = LISTS_IN_PYTHON(T)
        assert again.intervals == one.intervals and again.singular == one.singular
        one = native(T, 0.3)  # the shrunk limits' function, its limits shared by the IK
        _same_sets((one.intervals, one.singular), native._assemble(T, *native.breakpoints(T, limits), limits=limits))


def test_feasible_intervals_exact_without_a_c_compiler(monkeypatch):
    """With no C compiler (no cc, or QPIK_NATIVE=0) the wrist roots come from eigenvalues and the gaps are
    classified in numpy (:class:`qpik.analytic.intervals.SetAssembler`): the same sets."""
    from qpik.analytic import arm_sets, intervals, polyroots
    from qpik.analytic.offset_shoulder_intervals import DeltaIntervals

    monkeypatch.setattr(polyroots, "_library", lambda: None)
    monkeypatch.setattr(intervals, "_library", lambda: None)
    monkeypatch.setattr(arm_sets, "_delta_library", lambda: None)
    without = DeltaIntervals(SOLVER)
    assert without._assemble._native is None and without._fixed.native is None
    for T in ROBOT.fk(random_q(ROBOT, 20, 7)):
        _sweep_check(T, 2000, without)


def test_feasible_intervals_table4_and_singular_points():
    problem = load_problem(ROOT / "problems" / "nammoto2012_table4.toml")
    T = problem.poses[0]
    _sweep_check(T, 10000)
    fi = qpik.feasible_intervals(ROBOT, T)
    assert fi.contains(1, -0.80)  # Table 4's rows are within the catalog limits
    for k in range(16):
        if fi.singular[k]:
            _, v, s, _ = SOLVER.solve_many(T, np.array(fi.singular[k]))
            assert np.all(v[:, k] & s[:, k])


# ---- feasible δ intervals with a margin -------------------------------------------------


def _joint_margin(q: np.ndarray, robot: qpik.Robot = ROBOT) -> np.ndarray:
    """The joint-limit margin min_j min(q_j − l_j, u_j − q_j) / ρ_j, ρ_j = (u_j − l_j)/2, of q (..., n): (...)."""
    lo, hi = robot.q_min, robot.q_max
    return (np.minimum(q - lo, hi - q) / (0.5 * (hi - lo))).min(axis=-1)


def _far_from_ends(ivs, d: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """Which of the values d (M,) lie farther than ``tol`` from every end of the pieces ``ivs`` (the split at ±π
    is not an end)."""
    ends = np.array([x for iv in ivs for x in iv if abs(abs(x) - np.pi) > 1e-12])
    return np.abs(d[:, None] - ends[None]).min(axis=1) > tol if ends.size else np.ones(d.size, bool)


def _margin_sweep_check(T: np.ndarray, margin: float, fi, n_delta: int = 20000, robot: qpik.Robot = ROBOT) -> None:
    """Dense sampling of δ: samples inside a set are valid with a margin of at least ``margin`` (to 1e-9); valid
    samples with a margin above ``margin`` + 1e-6 are inside the set (both away from its ends)."""
    d = np.linspace(-np.pi, np.pi, n_delta)
    q, valid, _, _ = closed_form_for(robot).solve_batch(np.broadcast_to(T, (n_delta, 4, 4)), d)
    mu = _joint_margin(q, robot)  # (n_delta, 16)
    for k in range(16):
        inside, far = fi.contains(k + 1, d), _far_from_ends(fi.intervals[k], d)
        assert np.all(valid[inside & far, k]), f"branch {k + 1}: an invalid δ in the set"
        assert np.all(mu[inside & far, k] >= margin - 1e-9), f"branch {k + 1}: a δ of a smaller margin in the set"
        assert np.all(inside[far & valid[:, k] & (mu[:, k] > margin + 1e-6)]), f"branch {k + 1}: a δ missing"


def _contained(small, big, tol: float = 1e-9) -> bool:
    """Every piece of the set ``small`` lies within a piece of the set ``big`` (to ``tol``)."""
    return all(any(c - tol <= a and b <= d + tol for c, d in big) for a, b in small)


def _close_sets(a, b, tol: float) -> None:
    """Two results per branch: the same number of pieces, their ends within ``tol``."""
    assert [len(x) for x in a.intervals] == [len(x) for x in b.intervals]
    for x, y in zip(a.intervals, b.intervals):
        assert np.allclose(np.array(x, float).ravel(), np.array(y, float).ravel(), rtol=0, atol=tol)


def _poses(seed: int, n: int) -> np.ndarray:
    """n poses (n, 4, 4): fk of configurations inside the limits, the second half with some joints near a limit."""
    rng = np.random.default_rng(seed)
    q = random_q(ROBOT, n, seed)
    lo, hi = ROBOT.q_min, ROBOT.q_max
    edge = rng.uniform(0.0, 0.15, q.shape) * (hi - lo)  # up to 15 % of the range from a limit
    near = np.where(rng.random(q.shape) < 0.5, lo + edge, hi - edge)
    q[n // 2 :] = np.where(rng.random(q.shape) < 0.4, near, q)[n // 2 :]
    return ROBOT.fk(q)


def _numpy_path():
    """nammoto7's feasible-interval solver without a C compiler, as ``QPIK_NATIVE=0`` builds it (gaps classified in
    numpy), its shrunk limits' function built too."""
    from qpik.analytic import arm_sets, intervals, polyroots
    from qpik.analytic.offset_shoulder_intervals import DeltaIntervals

    with pytest.MonkeyPatch.context() as mp:
        for module, name in ((polyroots, "_library"), (intervals, "_library"), (arm_sets, "_delta_library")):
            mp.setattr(module, name, lambda: None)
        without = DeltaIntervals(SOLVER)
        assert without._shrunk.native is None and without._assemble._native is None
    return without


NUMPY_PATH = _numpy_path()


@settings(max_examples=5, deadline=None)
@given(SEEDS, st.floats(0.01, 0.8))
def test_feasible_intervals_with_a_margin_exact_on_random_poses(seed, margin):
    """Dense sampling of each branch at 20,000 values of δ on both paths (C and numpy), which agree."""
    from qpik.analytic import polyroots

    for T in _poses(seed, 4):
        fi = qpik.feasible_intervals(ROBOT, T, margin=margin)
        _margin_sweep_check(T, margin, fi)
        with pytest.MonkeyPatch.context() as mp:  # the wrist roots from eigenvalues, as without a C compiler
            mp.setattr(polyroots, "_library", lambda: None)
            without = NUMPY_PATH(T, margin)
        _margin_sweep_check(T, margin, without)
        _close_sets(fi, without, 1e-7)


@settings(max_examples=10, deadline=None)
@given(SEEDS, st.floats(0.0, 0.7), st.floats(0.001, 0.3))
def test_feasible_intervals_shrink_as_the_margin_grows(seed, margin, more):
    for T in _poses(seed, 4):
        small, big = SOLVER.feasible_intervals(T, margin + more), SOLVER.feasible_intervals(T, margin)
        assert all(_contained(x, y) for x, y in zip(small.intervals, big.intervals))


@settings(max_examples=10, deadline=None)
@given(SEEDS)
def test_a_tiny_margin_gives_the_sets_of_margin_zero(seed):
    """The shrunk limits' function at margin 1e-12 against the robot's limits' (nammoto7's limits are inside ±π)."""
    for T in _poses(seed, 4):
        _close_sets(SOLVER.feasible_intervals(T, 1e-12), SOLVER.feasible_intervals(T), 1e-6)


@settings(max_examples=3, deadline=None)
@given(SEEDS, st.floats(0.01, 0.8))
def test_feasible_intervals_with_a_margin_through_a_joint_map(seed, margin):
    """gymnasium's pusher: nammoto7's table with joints turned the other way and shifted (its levels map by the
    joint map's sign and shift), one limit at 0."""
    robot = model_robot("pusher")
    assert robot.canonical.kind == "offset_shoulder" and not robot.canonical.joints.identity
    for T in robot.fk(random_q(robot, 2, seed)):
        _margin_sweep_check(T, margin, qpik.feasible_intervals(robot, T, margin=margin), robot=robot)


def _wide(robot: qpik.Robot) -> qpik.Robot:
    """``robot`` with joint 1 over [-1, 6.5] rad and joint 7 over ±2π: limits past ±π (representatives q + 2πk)."""
    q_min, q_max = robot.q_min.copy(), robot.q_max.copy()
    q_min[[0, 6]], q_max[[0, 6]] = (-1.0, -2 * np.pi), (6.5, 2 * np.pi)
    return dataclasses.replace(robot, q_min=q_min, q_max=q_max)


@settings(max_examples=3, deadline=None)
@given(SEEDS, st.floats(0.01, 0.8))
def test_feasible_intervals_with_a_margin_for_limits_past_pi(seed, margin):
    """Joint 1's representative jumps at its limits -1 and 6.5 − 2π, in or out of the shrunk limits."""
    robot = _wide(ROBOT)
    for T in robot.fk(random_q(robot, 2, seed)):
        _margin_sweep_check(T, margin, qpik.feasible_intervals(robot, T, margin=margin), robot=robot)


def test_margin_above_one_empties_every_set():
    T = ROBOT.fk(np.zeros((1, 7)))[0]
    assert any(qpik.feasible_intervals(ROBOT, T).intervals)
    assert not any(qpik.feasible_intervals(ROBOT, T, margin=1.01).intervals)


@pytest.mark.parametrize("margin", [np.nan, -0.1, "a"])
def test_bad_margin_is_an_input_error(margin):
    with pytest.raises(qpik.InputError, match="margin"):
        qpik.feasible_intervals(ROBOT, ROBOT.fk(np.zeros((1, 7)))[0], margin=margin)


# ---- bad input ---------------------------------------------------------------


def test_unreachable_pose_is_invalid_not_an_error():
    T = np.eye(4)
    T[:3, 3] = (3.0, 0.0, 0.5)
    sol = qpik.ik(ROBOT, T, 0.3)
    assert not sol.valid.any() and np.all(np.isfinite(sol.q))
    sols = qpik.ik(ROBOT, np.stack([T, T]), np.array([0.0, 1.0]))
    assert not sols.valid.any() and np.all(np.isfinite(sols.q))
    fi = qpik.feasible_intervals(ROBOT, T)
    assert all(iv == [] for iv in fi.intervals)


def test_chain_structure_is_checked():
    from qpik.analytic.offset_shoulder import OffsetShoulderSolver

    other = dataclasses.replace(ROBOT, chain=qpik.load_robot("iiwa14").chain)
    with pytest.raises(qpik.NoClosedFormError, match="offset-shoulder"):
        OffsetShoulderSolver(other)
