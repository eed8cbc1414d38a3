"""The ``qpik`` command never shows a traceback: every error is one line ``qpik CMD: ...`` with exit code 2.

:data:`ISSUE_CASES` are the command lines that gave a traceback (issue 13); the property test then draws
command lines from every cheap subcommand with its options set to bad values (NaN, inf, huge, text,
empty, negative, out-of-range branch ids, files that are not pictures), through :func:`qpik.cli.main`
with stderr captured. A run either succeeds (exit 0), or fails in one line ``qpik CMD: ...`` (exit 2,
never ``internal error``), or is refused by argparse (SystemExit 2: usage and message).
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from qpik.cli import main
from qpik.problems import find_problem

Q = "0 0.5 0 -1.2 0 0.9 0"
REACH = find_problem("iiwa_obstacle_reach").read_text()


def run(argv: list[str]) -> tuple[int, str, str]:
    """``main(argv)``: (exit code, stdout, stderr); argparse's SystemExit gives its code."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def assert_clean(argv: list[str], code: int, err: str) -> None:
    """Exit 0; or exit 2 with one line ``qpik CMD: ...`` that is not a bug; or argparse's usage error."""
    assert "Traceback" not in err and "internal error" not in err, (argv, err)
    if code == 0:
        return
    assert code == 2, (argv, code, err)
    if err.startswith("usage:"):  # argparse: usage, then "qpik CMD: error: ..."
        assert err.strip().splitlines()[-1].startswith("qpik "), err
        return
    assert err.count("\n") == 1 and err.startswith(f"qpik {argv[0]}: "), (argv, err)


def _problem(tmp: Path, old: str, new: str) -> str:
    f = tmp / "p.toml"
    f.write_text(REACH.replace(old, new))
    return str(f)


ISSUE_CASES = {
    "dt fast": lambda tmp: ["run", _problem(tmp, "dt = 0.002", 'dt = "fast"'), "-o", str(tmp / "o")],
    "solver typo": lambda tmp: ["run", _problem(tmp, "d_safe = 0.03", "d_saef = 0.03"), "-o", str(tmp / "o")],
    "plot branches 99": lambda tmp: ["plot", "selfmotion", "-r", "iiwa14", "--q", Q, "--branches", "99", "-o",
                                     str(tmp / "a.png")],
    "plot shade 99": lambda tmp: ["plot", "selfmotion", "-r", "iiwa14", "--q", Q, "--shade", "99", "-o",
                                  str(tmp / "a.png")],
    "plot -o x.txt": lambda tmp: ["plot", "selfmotion", "-r", "iiwa14", "--q", Q, "-o", str(tmp / "x.txt")],
    "plot branches -o x.txt": lambda tmp: ["plot", "branches", "-r", "iiwa14", "--q", Q, "-p", "0.1", "-o",
                                           str(tmp / "x.txt")],
    "bench --repeat 0": lambda tmp: ["bench", "kinematics", "--repeat", "0"],
    "render --cols 0": lambda tmp: ["render", "-r", "iiwa14", "--cols", "0", "-o", str(tmp / "r.png")],
    "render --size": lambda tmp: ["render", "-r", "iiwa14", "--size", "0,-5", "-o", str(tmp / "r.png")],
    "ik project reflection": lambda tmp: ["ik", "-r", "iiwa14", "--position", "0.5 0 0.5", "--rotation",
                                          "-1 0 0 0 -1 0 0 0 -1", "-p", "0", "--project"],
    "ik huge position": lambda tmp: ["ik", "-r", "nammoto7", "--position", "1e155 0 0", "-p", "0"],
    "fk complex-looking": lambda tmp: ["fk", "-r", "iiwa14", "--q", "nan 0 0 0 0 0 0"],
    "run a folder": lambda tmp: ["run", str(tmp)],
    "plot a path problem": lambda tmp: ["plot", "selfmotion", "--problem", "zheng2019_clik", "-o", str(tmp / "a.png")],
}  # fmt: skip


@pytest.mark.parametrize("case", list(ISSUE_CASES))
def test_issue_cases_fail_in_one_line(tmp_path, case):
    argv = ISSUE_CASES[case](tmp_path)
    code, _, err = run(argv)
    assert code == 2 and err.count("\n") == 1 and err.startswith(f"qpik {argv[0]}: "), (argv, err)
    assert "internal error" not in err


def test_reach_without_obstacles_reports(tmp_path):
    """A reach problem without [[obstacles]] crashed after simulating (a zero-size minimum); it reports now."""
    text = REACH.split("[[obstacles]]")[0] + "[solver]" + REACH.split("[solver]")[1]
    text = text.replace("duration = 5.0", "duration = 0.1")
    f = tmp_path / "bare.toml"
    f.write_text(text)
    code, out, err = run(["run", str(f), "-o", str(tmp_path / "out")])
    assert code == 0, err
    assert "clearance ≥ d_s" not in out and "Overall:" in out  # no clearance checks without obstacles
    assert (tmp_path / "out" / "report.md").is_file()


BAD = ["nan", "inf", "-inf", "1e300", "-1", "0", "abc", "", "99", "1.5", "0,0", "1 2 3", "1j", "-0.07", "7"]
TOKENS = st.sampled_from(BAD)


def _argv(tmp: Path) -> st.SearchStrategy:
    """A command line of fk, ik, plot or render with one option replaced by a bad token (or all good)."""
    png = str(tmp / "f.png")
    commands = [
        ["fk", "-r", "panda", "--q", Q],
        ["fk", "-r", "iiwa14", "--q", Q, "--deg"],
        ["ik", "-r", "iiwa14", "--q", Q],
        ["ik", "-r", "nammoto7", "--position", "0.4 0.1 0.5", "--rotation", "1 0 0 0 1 0 0 0 1", "-p", "0.3"],
        ["ik", "-r", "iiwa14", "--pose", "1 0 0 0.4 0 1 0 0 0 0 1 0.6 0 0 0 1", "-p", "0.1", "--project"],
        ["plot", "selfmotion", "-r", "iiwa14", "--q", Q, "--branches", "0,2", "--shade", "2", "-o", png],
        ["plot", "branches", "-r", "nammoto7", "--q", Q, "-p", "0.2", "-o", png],
        ["render", "-r", "panda", "--q", Q, "--cols", "1", "--size", "32,32", "-o", png],
    ]

    def replace(cmd: list[str], i: int, token: str) -> list[str]:
        values = [k for k in range(1, len(cmd)) if not cmd[k].startswith("-") and cmd[k - 1].startswith("-")]
        if not values:
            return cmd
        k = values[i % len(values)]
        return [*cmd[:k], token, *cmd[k + 1 :]]

    return st.one_of(
        st.sampled_from(commands),
        st.builds(replace, st.sampled_from(commands), st.integers(0, 10), TOKENS),
    )


@settings(max_examples=80, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(data=st.data())
def test_command_lines_never_show_a_traceback(tmp_path, data):
    argv = data.draw(_argv(tmp_path))
    code, _, err = run(argv)
    assert_clean(argv, code, err)
