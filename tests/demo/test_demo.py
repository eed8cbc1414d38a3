"""qpik.demo: the first run says that it compiles, later runs do not (the sections themselves run in CI's part 1)."""

from __future__ import annotations

import pytest

from qpik.demo import run_all
from qpik.native.build import compiler


@pytest.mark.skipif(compiler() is None, reason="no C compiler: nothing is compiled")
def test_the_first_run_says_it_compiles(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("QPIK_CACHE", str(tmp_path / "cache"))
    run_all(tmp_path / "out", only=["no such section"])
    assert "first run: qpik compiles" in capsys.readouterr().out
    (tmp_path / "cache").mkdir()
    (tmp_path / "cache" / "fk_iiwa14.so").write_bytes(b"")
    run_all(tmp_path / "out", only=["no such section"])
    assert "first run" not in capsys.readouterr().out


def test_the_sweep_text_agrees_with_a_limit_check_at_every_p_z(tmp_path, capsys):
    """What the closed-form section prints about θ6 at δ = 0 and δ = 0.70 against a check written here: branch 1 on a
    p_z grid five times finer, each configuration on its pose (FK), θ6 against the arm's limit. The printed run past
    the limit is the fine grid's to one coarse step, the printed peak the fine grid's to 0.01 rad, and the verdict says
    "still past" exactly when the check finds δ = 0.70 past the limit somewhere."""
    import re

    import numpy as np

    import qpik
    from qpik.demo.closed_form import _pz_sweep
    from qpik.problems import find_problem, load

    problem = load(find_problem("nammoto2012_joint_limits"))
    robot, poses = problem.robot, problem.poses
    _pz_sweep(tmp_path)
    out = capsys.readouterr().out
    pz = np.linspace(poses[0, 2, 3], poses[-1, 2, 3], 5 * (len(poses) - 1) + 1)
    T = np.repeat(poses[:1], len(pz), axis=0)
    T[:, 2, 3] = pz
    step = abs(poses[1, 2, 3] - poses[0, 2, 3])
    past_at = {}
    for delta in problem.params:
        sols = qpik.ik(robot, T, np.full(len(pz), delta))
        q = sols.q[:, list(sols.branch).index(1)]
        np.testing.assert_allclose(robot.fk(q), T, atol=1e-9)
        past = pz[(q[:, 5] > robot.q_max[5]) | (q[:, 5] < robot.q_min[5])]
        past_at[float(delta)] = past
        (line,) = [ln for ln in out.splitlines() if ln.strip().startswith(f"δ = {delta:.2f}:")]
        assert abs(float(re.search(r"largest ([+-][\d.]+) rad", line).group(1)) - q[:, 5].max()) <= 0.01
        if not len(past):
            assert "inside its limits" in line and "past" not in line
            continue
        lo, hi = (float(v) for v in re.search(r"for p_z from ([\d.]+) to ([\d.]+) m", line).groups())
        assert abs(lo - past.min()) <= step + 1e-9 and abs(hi - past.max()) <= step + 1e-9
    (verdict,) = [ln for ln in out.splitlines() if ln.strip().startswith("here:")]
    assert ("still past" in verdict) == bool(len(past_at[0.70]))
    assert ("choosing δ avoids the limit" in verdict) == (not len(past_at[0.70]))
