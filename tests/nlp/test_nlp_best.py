"""qpik.solve_best against dense sampling, on seeded random reachable poses per closed-form arm (100 by default,
500 with ``QPIK_TESTS_LARGE=1``).

The reference is independent of the search: every branch's closed form (the batched numpy path,
:meth:`AnalyticSolver.solve_batch`) at 10,000 values of δ/ψ, the joint-limit margin computed in
numpy from its definition, the clearance from :func:`qpik.geometry.distances`. The answer must
reach the pose (forward kinematics), lie inside the limits and clear of the obstacles, and be
at least as good as every sample (to 1e-8).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import casadi as ca
import numpy as np
import pytest
from conftest import LARGE, random_q

import qpik
from qpik.analytic import closed_form_for
from qpik.core.errors import InputError, NoClosedFormError
from qpik.geometry import Sphere, distances
from qpik.nlp import BestResults, solve_best
from qpik.nlp.options import BestOptions
from qpik.nlp.run import BestRun
from qpik.nlp.search import Pieces, roots, sample, singular_ends
from qpik.nlp.selfmotion import selfmotion_of
from qpik.objectives import Expression, resolve
from qpik.scene import Scene
from qpik.scene.evaluator import Evaluator

POSES = 500 if LARGE else 100
DENSE = 10_000
ARMS = ("iiwa14", "nammoto7")
OBSTACLES = [Sphere((0.35, 0.25, 0.6), 0.1), Sphere((0.3, -0.35, 0.45), 0.1)]
D_SAFE = 0.02


def _poses(robot, n, seed):
    return robot.fk(random_q(robot, n, seed))


def _margin(robot, q):
    half = 0.5 * (robot.q_max - robot.q_min)
    return -np.minimum((q - robot.q_min) / half, (robot.q_max - q) / half).min(axis=-1)


def _dense(robot, T, num=DENSE, block=10):
    """For each pose: (q (num, B, n), feasible (num, B)) of every branch at ``num`` parameters, in blocks: inside the
    limits, with the capsule pairs solve_best keeps apart by default ≥ d_s apart (the compiled kernel of
    :attr:`Scene.self_distances`, checked against numpy's in tests/scene and MuJoCo's in test_nlp_best_self.py:
    numpy's is too slow for a million samples)."""
    solver = closed_form_for(robot)
    own = Scene.of(robot)
    psi = np.linspace(-np.pi, np.pi, num, endpoint=False)
    for start in range(0, len(T), block):
        Tb = T[start : start + block]
        sol = solver.solve_batch(np.repeat(Tb, num, axis=0), np.tile(psi, len(Tb)))
        for k in range(len(Tb)):
            q, ok = sol.q[k * num : (k + 1) * num], sol.within_limits[k * num : (k + 1) * num].copy()
            ok[ok] = own.self_clearance(q[ok]) >= D_SAFE
            yield q, ok


def _check_answer(robot, T, res, obstacles=()):
    assert res.status == "optimal", res.summary()
    np.testing.assert_allclose(robot.fk(res.q), T, atol=1e-9)
    assert robot.within_limits(res.q)
    if obstacles:
        d = distances(robot.capsule_segments(res.q), robot.capsule_radii, obstacles).d
        assert d.min() >= D_SAFE - 1e-9


@pytest.mark.parametrize("name", ARMS)
def test_margin_is_global_on_random_poses_with_and_without_obstacles(name):
    """Without obstacles (the default certificate on): at least as good as every dense sample inside the
    limits and clear of itself (self-collision is on by default). With two spheres (certificate off: the search
    alone): clear of them on every pose, and no dense sample inside the limits and clear of them is better.

    The dense samples' clearances come from the compiled capsule–obstacle distances of
    :class:`qpik.scene.evaluator.Evaluator` (the kernels of :mod:`qpik.geometry.distance`, checked against
    scipy and MuJoCo in tests/geometry/test_geometry_distance.py): numpy's path is too slow for the millions
    of samples that beat an answer pushed back by the obstacles.
    """
    robot = qpik.load_robot(name)
    T = _poses(robot, POSES, 11)
    free = solve_best(robot, T)
    blocked = solve_best(robot, T, "margin", OBSTACLES, d_safe=D_SAFE, options=BestOptions(certify=False))
    assert isinstance(free, BestResults) and len(free) == POSES
    clearance = Evaluator(robot, resolve("margin"), OBSTACLES)
    certified = 0
    for k, (q, ok) in enumerate(_dense(robot, T)):
        if not ok.any():  # every configuration of the pose brings two capsules closer than d_s
            assert free[k].status == "no feasible branch", free[k].summary()  # proved by the certificate
            assert blocked[k].status == "not found", blocked[k].summary()  # certify=False: nothing proved
            continue
        f = np.where(ok, _margin(robot, q), np.inf)
        res = free[k]
        _check_answer(robot, T[k], res)
        assert res.objective <= f.min() + 1e-8, (k, res.objective, f.min())
        assert res.objective == pytest.approx(_margin(robot, res.q), abs=1e-14)
        certified += res.certified
        if res.certified:
            assert res.gap <= 1e-4 * max(1.0, abs(res.objective))
        res = blocked[k]
        if res.status == "optimal":
            _check_answer(robot, T[k], res, OBSTACLES)
        else:
            assert res.status == "not found" and res.violation > 0 and "certify=False" in res.message, res.summary()
        better = np.argwhere(f < (res.objective if res.status == "optimal" else np.inf) - 1e-8)
        if len(better):  # every configuration better than the answer must come closer than d_s
            d = clearance(q[better[:, 0], better[:, 1]])[2]
            assert d.min(axis=1).max() < D_SAFE, (k, res.summary())
    assert certified >= 0.8 * POSES  # the margin's minima are mostly kinks, which the certificate proves cheaply


@pytest.mark.parametrize(
    "name, objective",
    [
        ("iiwa14", "smooth-margin"),
        ("nammoto7", "distance"),
        ("iiwa14", "manipulability"),
        ("nammoto7", "smooth-clearance"),
    ],
)
def test_other_objectives_against_dense_samples(name, objective):
    robot = qpik.load_robot(name)
    T = _poses(robot, 25, 13)
    obstacles = OBSTACLES if "clearance" in objective else ()
    results = solve_best(
        robot, T, objective, obstacles, q_ref=robot.q_home, d_safe=D_SAFE, options=BestOptions(certify=False)
    )
    ev = Evaluator(robot, resolve(objective), obstacles)
    for k, ((q, ok), res) in enumerate(zip(_dense(robot, T, num=3000), results)):
        if not ok.any():  # every configuration of the pose brings two capsules closer than d_s
            assert res.status == "not found", (k, res.summary())  # certify=False: nothing proved
            continue
        f, _, d, _ = ev(q[ok], robot.q_home)
        clear = d.min(axis=1) >= D_SAFE if d.shape[1] else np.ones(len(f), bool)
        if not clear.any():
            continue
        _check_answer(robot, T[k], res, obstacles)
        assert res.objective <= f[clear].min() + 1e-8, (k, res.objective, f[clear].min())


@pytest.mark.parametrize("name", ARMS)
def test_sample_rows_equal_full_rows_and_derivatives_match_differences(name):
    """The search's cheap sample rows (Scene.values) give the same q, f, clearance and distances as its full
    rows (Scene.evaluate; the split and the polish compare values of both), and the full rows' dq/dψ and f'
    match central differences of the cheap rows."""
    robot = qpik.load_robot(name)
    sm = selfmotion_of(robot)
    T = _poses(robot, 20, 31)
    objective = resolve("smooth-margin") + 0.1 * resolve("smooth-clearance")
    scene = BestRun(
        Scene.of(robot, OBSTACLES, d_safe=D_SAFE, objective=objective), sm, T, np.zeros((len(T), robot.dof))
    )
    rng = np.random.default_rng(3)
    pose = np.repeat(np.arange(len(T)), 50)
    row, psi = rng.integers(0, sm.searched, len(pose)), rng.uniform(-np.pi, np.pi, len(pose))
    full, cheap = scene.evaluate(pose, row, psi), scene.values(pose, row, psi)
    for key in ("q", "valid", "f", "c", "d"):
        np.testing.assert_array_equal(getattr(cheap, key), getattr(full, key), err_msg=key)
    h = 1e-6
    up, down = scene.values(pose, row, psi + h), scene.values(pose, row, psi - h)
    dq = (up.q - down.q) / (2 * h)
    ok = full.valid & up.valid & down.valid & (np.abs(full.dq).max(axis=1) < 1e3) & (np.abs(dq).max(axis=1) < 1e3)
    assert ok.mean() > 0.5
    np.testing.assert_allclose(full.dq[ok], dq[ok], atol=1e-5, rtol=1e-5)
    np.testing.assert_allclose(full.df[ok], ((up.f - down.f) / (2 * h))[ok], atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("name", ARMS)
def test_clearance_roots_are_met_faster_than_by_bisection(name):
    """Every sign change of the clearance between two samples is refined to a root: a point on the feasible
    side with |c| below 1e-9 m, in fewer evaluations per root than bisection to 1e-13 rad would need."""
    robot = qpik.load_robot(name)
    sm = selfmotion_of(robot)
    T = _poses(robot, 30, 41)
    scene = BestRun(Scene.of(robot, OBSTACLES, d_safe=D_SAFE, objective="margin"), sm, T, np.zeros((len(T), robot.dof)))
    sets = [sm.solver.feasible_intervals(pose).intervals[: sm.searched] for pose in T]
    pieces = [(i, b, lo, hi) for i, fi in enumerate(sets) for b, s in enumerate(fi) for lo, hi in s]
    pose, row, lo, hi = (np.array(x) for x in zip(*pieces))
    pts, piece = sample(scene, Pieces(pose.astype(int), row.astype(int), lo, hi), 0.05)
    ok = pts.c >= 0
    change = np.flatnonzero((piece[1:] == piece[:-1]) & (ok[1:] != ok[:-1]))
    assert len(change) >= 20
    left, right = (scene.evaluate(pts.pose[k], pts.row[k], pts.psi[k]) for k in (change, change + 1))
    before = scene.evaluations
    found = roots(scene, left, right)
    assert np.all(found.c >= 0) and np.all(found.c < 1e-9)
    assert np.all((found.psi >= left.psi) & (found.psi <= right.psi))
    bisection = 3 * np.log2(0.05 / 1e-13)  # three trials a round, one halving
    assert (scene.evaluations - before) / len(change) < 0.5 * bisection


def test_singular_ends_are_the_ends_at_a_singular_parameter_of_the_same_pose_and_branch():
    """Ends at a singular parameter (to 1e-9) are flagged; the same parameter of another pose or branch, or
    1e-6 rad away, is not."""
    rng = np.random.default_rng(7)
    P = 300
    pose, row = rng.integers(0, 40, P), rng.integers(0, 8, P)
    lo = rng.uniform(-np.pi, 0.0, P)
    hi = lo + rng.uniform(0.0, np.pi, P)
    expected = rng.random((P, 2)) < 0.3
    ends = np.stack([lo, hi], axis=1)
    value = ends[expected] + rng.uniform(-1e-9, 1e-9, expected.sum())
    s_pose, s_row = np.repeat(pose, 2)[expected.ravel()], np.repeat(row, 2)[expected.ravel()]
    decoys = ~expected & (rng.random((P, 2)) < 0.5)  # another pose, another row, or off by 1e-6 rad
    kind = rng.integers(0, 3, decoys.sum())
    d_pose = np.repeat(pose, 2)[decoys.ravel()] + (kind == 0) * 41
    d_row = np.repeat(row, 2)[decoys.ravel()] + (kind == 1) * 9
    d_value = ends[decoys] + (kind == 2) * 1e-6
    pieces = Pieces(pose, row, lo, hi)
    found = singular_ends(pieces, np.r_[s_pose, d_pose], np.r_[s_row, d_row], np.r_[value, d_value])
    np.testing.assert_array_equal(found, expected)


@pytest.mark.parametrize("name", ARMS)
def test_ipopt_per_branch_reaches_no_better_optimum(name):
    """method="ipopt" (one IPOPT solve per feasible interval) never beats the search, and often meets it."""
    robot = qpik.load_robot(name)
    T = _poses(robot, 4, 14)
    for k in range(len(T)):
        search = solve_best(robot, T[k], options=BestOptions(certify=False))
        ipopt = solve_best(robot, T[k], options=BestOptions(certify=False, method="ipopt"))
        _check_answer(robot, T[k], ipopt)
        assert search.objective <= ipopt.objective + 1e-9


def test_statuses_and_the_least_violating_branch():
    robot = qpik.load_robot("iiwa14")
    far = np.eye(4)
    far[:3, 3] = (2.0, 0.0, 0.5)
    res = solve_best(robot, far)
    assert res.status == "unreachable" and res.objective == np.inf and not any(b.feasible for b in res.branches)
    # q: the closed form's nearest configuration (stretched toward the pose), its pose error the violation
    reach = np.linalg.norm(robot.fk(res.q)[:3, 3] - far[:3, 3])
    assert np.isfinite(res.q).all() and res.violation >= reach > 0.5
    # ... and no closed-form configuration on a dense grid of ψ comes closer
    psi = np.linspace(-np.pi, np.pi, 2000, endpoint=False)
    Q = closed_form_for(robot).solve_batch(np.broadcast_to(far, (len(psi), 4, 4)), psi).q.reshape(-1, robot.dof)
    T = np.stack([robot.fk(q) for q in Q])
    angle = np.arccos(np.clip((np.einsum("ij,mij->m", far[:3, :3], T[:, :3, :3]) - 1) / 2, -1, 1))
    dense = np.sqrt(((T[:, :3, 3] - far[:3, 3]) ** 2).sum(axis=1) + angle**2).min()
    assert res.violation <= dense + 1e-6
    assert all(b.q is None and b.param is None and b.objective == np.inf for b in res.branches)
    # the elbow (q4, which no arm angle changes) beyond its limit: reachable, no branch feasible
    q = np.array([0.3, 0.5, 0.0, 2.5, 0.2, 0.5, 0.0])
    res = solve_best(robot, robot.fk(q))
    assert res.status == "no feasible branch"
    np.testing.assert_allclose(robot.fk(res.q), robot.fk(q), atol=1e-9)  # the least-violating configuration
    assert res.violation == pytest.approx(2.5 - robot.q_max[3], abs=1e-6)
    # inside the limits, but an obstacle around the whole arm: the least violating clearance
    res = solve_best(robot, robot.fk(robot.q_home), obstacles=[Sphere((0, 0, 0.6), 0.5)], d_safe=0.01)
    assert res.status == "no feasible branch" and res.violation > 0.01


def test_no_feasible_branch_is_claimed_only_with_a_proof(monkeypatch):
    """Poses every configuration of which brings two capsules closer than d_s: ``"no feasible branch"`` comes with the
    certificate's proof (run with f* = +inf, every cell cut off by a clearance), which dense samples confirm; a
    certificate that cannot finish leaves ``"not found"`` with its reason."""
    import qpik.nlp.certificate as certificate

    robot = qpik.load_robot("nammoto7")
    T = _poses(robot, 100, 0)
    found = solve_best(robot, T)
    none = [k for k, r in enumerate(found) if r.status != "optimal"]
    assert none and all(found[k].status == "no feasible branch" for k in none), [found[k].summary() for k in none]
    for k, (_, ok) in zip(none, _dense(robot, T[none])):
        assert not ok.any(), k
    monkeypatch.setattr(certificate, "MAX_CELLS", 1)
    for res in solve_best(robot, T[none]):
        assert res.status == "not found" and "within 1 cells" in res.message, res.summary()
        assert np.isfinite(res.q).all() and res.objective == np.inf


@pytest.mark.parametrize("method", ["levelset", "search"])
def test_a_numerical_failure_is_a_status(monkeypatch, method):
    """A compiled evaluation that fails (the level sets' rounds in Python, or the search) gives a status."""
    import qpik.nlp.run
    from qpik.nlp import levelset

    robot = qpik.load_robot("iiwa14")

    def broken(self, pose, row, psi):
        raise RuntimeError("CasADi: evaluation failed")

    monkeypatch.setattr(qpik.nlp.run.BestRun, "evaluate", broken)
    monkeypatch.setattr(levelset, "_native", lambda selfmotion: None)
    res = solve_best(robot, robot.fk(robot.q_home), options=BestOptions(method=method))
    assert res.status == "solver failed" and "evaluation failed" in res.message


def test_bad_input_names_the_argument():
    robot = qpik.load_robot("iiwa14")
    T = robot.fk(robot.q_home)
    bad = T.copy()
    bad[0, 3] = np.nan
    with pytest.raises(InputError, match="pose"):
        solve_best(robot, bad)
    with pytest.raises(InputError, match="pose"):
        solve_best(robot, T[:3])
    with pytest.raises(InputError, match="q_ref"):
        solve_best(robot, T, "distance")
    with pytest.raises(InputError, match="q_ref"):
        solve_best(robot, T, "distance", q_ref=np.zeros(6))
    with pytest.raises(InputError, match="objective"):
        solve_best(robot, T, "comfort")
    with pytest.raises(InputError, match="d_safe"):
        solve_best(robot, T, d_safe=np.inf)
    with pytest.raises(InputError, match="branches"):
        solve_best(robot, T, options=BestOptions(branches=[9]))
    with pytest.raises(InputError, match="obstacles"):
        solve_best(robot, T, obstacles=["ball"])
    with pytest.raises(NoClosedFormError):
        solve_best(qpik.load_robot("zheng7"), T)


def test_branch_table_restriction_and_mirrored_branches():
    robot = qpik.load_robot("nammoto7")
    q = np.array([0.57, -0.96, -1.91, -2.01, 1.3, 1.21, 0.46])
    T = robot.fk(q)
    res = solve_best(robot, T, options=BestOptions(certify=False))
    rows = {b.branch: b for b in res.branches}
    # the table, built when first read: the best branch's row holds the answer, the times share the pose's
    assert rows[res.branch].objective == res.objective and rows[res.branch].param == pytest.approx(res.param)
    assert sum(b.time for b in res.branches) == pytest.approx(res.time, rel=1e-9)
    assert sum(b.evaluations for b in res.branches) > 0
    for k in range(1, 9):  # branch k + 8 at δ is branch k at δ + π: the same configurations
        if rows[k].feasible:
            np.testing.assert_allclose(rows[k].q, rows[k + 8].q)
            assert np.angle(np.exp(1j * (rows[k + 8].param - rows[k].param - np.pi))) == pytest.approx(0, abs=1e-12)
    own = qpik.redundancy_parameter(robot, q)[1]
    only = solve_best(robot, T, options=BestOptions(branches=[own], certify=False))
    assert only.branch in (own, own + 8 if own <= 8 else own - 8)
    assert [b.searched for b in only.branches].count(True) == 2
    assert "skipped" in only.table() and only.objective >= res.objective - 1e-12


def test_user_expressions_are_certified_when_every_operation_has_a_taylor_rule():
    """A user expression made of +, −, ×, sin, ... is certified like a built-in objective; one with an
    operation without a Taylor-model rule (erf) is optimised but never certified, and the message says why."""
    robot = qpik.load_robot("iiwa14")
    T = robot.fk(robot.q_home)
    ((q, ok),) = _dense(robot, T[None], num=3000)
    user = Expression(lambda q: ca.sumsqr(q[:3] - 0.3), name="shoulder")
    res = solve_best(robot, T, user)
    assert res.status == "optimal" and res.certified
    assert res.objective <= (((q[ok][:, :3] - 0.3) ** 2).sum(axis=1)).min() + 1e-8
    erf = solve_best(robot, T, Expression(lambda q: ca.erf(q[0] - 0.3), name="erf"))
    assert erf.status == "optimal" and not erf.certified and "lower bound" in erf.message
    assert erf.objective <= np.asarray(ca.erf(q[ok][:, 0] - 0.3)).min() + 1e-8


def test_a_floor_under_the_base_constrains_only_the_moving_links():
    """A floor at the base plane overlaps iiwa14's first capsule, which no joint moves: the answer is the one
    without the floor wherever every moving capsule clears it, and its clearance is theirs (z minus radius), or the
    arm's own where its capsule pairs come closer."""
    from qpik.geometry import HalfSpace

    robot = qpik.load_robot("iiwa14")
    floor = HalfSpace(np.array([0.0, 0.0, 1.0]), 0.0, name="floor")
    checked = 0
    for q in random_q(robot, 12, 5, margin=0.1):
        T = robot.fk(q)
        res, free = solve_best(robot, T, obstacles=[floor]), solve_best(robot, T)
        lowest = robot.capsule_segments(res.q)[..., 2].min(axis=1) - robot.capsule_radii  # m, per capsule
        above = lowest[~robot.fixed_capsules].min()
        own = Scene.of(robot).self_clearance(res.q[None])[0]  # and the arm's own capsule pairs
        assert lowest[0] < 0 and res.status == "optimal"
        assert res.clearance == pytest.approx(min(above, own), abs=1e-9)
        if above > 0.05:  # the floor is not active: the same optimum
            assert res.objective == pytest.approx(free.objective, abs=1e-8)
            checked += 1
    assert checked >= 6


def test_threads_sharing_an_arm_get_the_answers_of_one_thread() -> None:
    """Four threads calling ``solve_best`` on one robot at once (margin, and manipulability with an obstacle) get
    exactly what one thread gets: it holds the arm's lock around its compiled calls."""
    robot = qpik.load_robot("iiwa14")
    T = robot.fk(np.random.default_rng(8).uniform(robot.q_min, robot.q_max, (8, robot.dof)))
    obstacles = [Sphere((0.45, 0.3, 0.6), 0.08)]

    def answers(k: int) -> list:
        out = []
        for i in range(k, len(T), 4):
            out.append(solve_best(robot, T[i]).q.tolist())
            out.append(solve_best(robot, T[i], objective="manipulability", obstacles=obstacles).q.tolist())
        return out

    serial = [answers(k) for k in range(4)]
    with ThreadPoolExecutor(4) as pool:
        for _ in range(2):
            assert list(pool.map(answers, range(4))) == serial


def test_the_margin_is_reported_as_itself_and_the_table_shows_it():
    """The margin objective minimises −margin; the result and its table report the margin: positive, and equal to
    the smallest distance to a limit over the half range, computed here from q."""
    for name in ARMS:
        robot = qpik.load_robot(name)
        T = _poses(robot, 3, 31)
        for method in ("levelset", "search"):
            results = solve_best(robot, T, "margin", options=BestOptions(method=method))
            for res in results:
                margin = -_margin(robot, res.q)
                assert res.reported > 0 and res.reported == pytest.approx(margin, abs=1e-12)
                assert res.objective == pytest.approx(-margin, abs=1e-12)
                assert f"margin {res.reported:.10g}, maximised" in res.summary()
                for row in res.branches:
                    if row.feasible:
                        assert res.quantity.value(row.objective) == pytest.approx(-_margin(robot, row.q), abs=1e-12)
                head, *rows = res.table().splitlines()
                assert head.split()[4] == "margin"  # branch, feasible, ψ* [rad], margin, ...
                shown = [float(r.split()[3]) for r in rows if r.split()[0].isdigit() and r.split()[1] == "yes"]
                assert shown and min(shown) > 0 and max(shown) == pytest.approx(res.reported, rel=1e-7)
            np.testing.assert_allclose(results.reported, -_margin(robot, results.q), atol=1e-12)


@pytest.mark.parametrize("method, objective, obstacles", [("levelset", "margin", ()), ("search", "margin", OBSTACLES),
                                                           ("ipopt", "smooth-margin", ())])  # fmt: skip
def test_the_time_is_the_solve_not_the_building_of_its_functions(monkeypatch, method, objective, obstacles):
    """On a fresh arm every function is built (traced, compiled or loaded) within the call; the reported time counts
    none of it: no compiled function or IPOPT solver is made while a solve's clock runs, the reported time is at most
    the call's wall time less the time spent making compiled functions, and the branch times add up to it."""
    import time

    import casadi

    from qpik.core.stopwatch import Stopwatch
    from qpik.native.compiled import Compiled
    from qpik.robots.catalog import CATALOG

    watches, built = [], []
    make_watch, make_compiled, make_nlp = Stopwatch.__init__, Compiled.__init__, casadi.nlpsol

    def watch(self):
        make_watch(self)
        watches.append(self)

    def compiled(self, *args, **kwargs):
        start = time.perf_counter()
        make_compiled(self, *args, **kwargs)
        built.append((any(w.running for w in watches), time.perf_counter() - start))

    def nlpsol(*args, **kwargs):
        built.append((any(w.running for w in watches), 0.0))
        return make_nlp(*args, **kwargs)

    monkeypatch.setattr(Stopwatch, "__init__", watch)
    monkeypatch.setattr(Compiled, "__init__", compiled)
    monkeypatch.setattr(casadi, "nlpsol", nlpsol)
    robot = CATALOG["iiwa14"]()  # a new object: none of its functions is built yet
    T = _poses(robot, 2, 41)
    start = time.perf_counter()
    results = solve_best(robot, T, objective, obstacles, options=BestOptions(method=method, certify=method != "ipopt"))
    wall = time.perf_counter() - start
    assert built and watches  # the call built functions, and timed its solve
    assert not [b for b in built if b[0]], "a function was built while the clock ran"
    making = sum(seconds for _, seconds in built)
    for res in results:
        assert res.status == "optimal"
        assert 0 < res.time * len(T) <= wall - making
        assert sum(b.time for b in res.branches) == pytest.approx(res.time, rel=1e-9)
