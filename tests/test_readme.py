"""The README's promises: its first two commands, .ci/run, its Python examples (each on its own) and its
list of examples."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def sections() -> dict[str, str]:
    """The README's ``## `` sections by heading (headings inside code blocks are output, not sections)."""
    out: dict[str, list[str]] = {}
    heading, fence = "", False
    for line in README.splitlines():
        fence ^= line.startswith("```")
        if not fence and line.startswith("## "):
            heading = line[3:].strip()
        else:
            out.setdefault(heading, []).append(line)
    return {k: "\n".join(v) for k, v in out.items()}


BLOCKS = [
    (heading, i, block)
    for heading, text in sections().items()
    for i, block in enumerate(re.findall(r"```python\n(.*?)```", text, re.S))
]


def test_readme_opens_with_the_two_setup_commands_and_ci_runs_the_test_one() -> None:
    first_block = re.search(r"```bash\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert first_block == ["pip install . && qpik demo", 'pip install -e ".[test]" && pytest']
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install -e ".[test]" && pytest' in ci


def check_closed_form(ns: dict) -> None:
    robot, sols = ns["robot"], ns["sols"]
    assert sols.q.shape == (16, 7) and sols.valid.all()
    # every branch reaches the (projected) pose by FK, independent of the closed form
    R = np.linalg.svd(ns["pose"][:3, :3])
    pose = ns["pose"].copy()
    pose[:3, :3] = R[0] @ R[2]
    assert np.abs(robot.fk(sols.q) - pose).max() < 1e-9


def check_qp_controller(ns: dict) -> None:
    robot = ns["robot"]
    # solve_ik reached its target (FK, independent of the controller)
    assert np.abs(robot.fk(ns["q_star"]) - ns["target"]).max() < 1e-9
    assert ns["v"].shape == (7,) and np.all(np.abs(ns["v"]) <= robot.v_max + 1e-9)
    # from rest, the first command of the arm with acceleration limits is within one step of them
    panda = ns["panda"]
    assert np.all(np.abs(ns["v_safe"]) <= panda.a_max * 0.002 + 1e-12) and np.isfinite(
        ns["safe"].last.min_self_distance
    )


def check_nlp(ns: dict) -> None:
    robot, best, arm = ns["robot"], ns["best"], ns["arm"]
    assert np.abs(robot.fk(best.q) - ns["target"]).max() < 1e-9 and robot.within_limits(best.q)
    # the full-joint NLP reached its pose (FK of the zheng7 model)
    assert np.abs(arm.fk(ns["full"].q) - arm.fk(arm.q_home + 0.1)).max() < 1e-8


def check_numerical_ik(ns: dict) -> None:
    panda, q_ik = ns["panda"], ns["q_ik"]
    assert np.abs(panda.fk(q_ik) - ns["goal"]).max() < 1e-9 and panda.within_limits(q_ik)
    assert ns["res"].status == "ok" and np.array_equal(ns["res"].q, q_ik)


def check_self_motion_planning(ns: dict) -> None:
    # the plan reaches every waypoint inside the limits, and its retiming respects v_max
    arm, plan, timed = ns["arm"], ns["plan"], ns["timed"]
    assert plan.ok and np.abs(arm.fk(plan.q) - ns["way"]).max() < 1e-9 and arm.within_limits(plan.q).all()
    assert (np.abs(timed.qd) / arm.v_max).max() < 1.01


def check_bring_your_own_arm(ns: dict) -> None:
    arm, sols = ns["iiwa_urdf"], ns["iiwa_sols"]
    assert arm.closed_form == "srs" and sols.valid.any()
    assert np.abs(arm.fk(sols.q[sols.valid]) - arm.fk(arm.q_home + 0.3)).max() < 1e-9


def check_planning_on_a_cluster(ns: dict) -> None:
    # plan_many's plans, in order, are the plans of a loop (checked by FK against each path's own waypoints)
    arm, plans, paths = ns["arm"], ns["plans"], ns["paths"]
    assert len(plans) == len(paths) and all(p.ok and p.robot is arm for p in plans)
    for plan, path in zip(plans, paths, strict=True):
        assert np.abs(arm.fk(plan.q) - path).max() < 1e-9


CHECKS = {
    "Closed form": check_closed_form,
    "QP controller": check_qp_controller,
    "NLP": check_nlp,
    "Numerical IK": check_numerical_ik,
    "Self-motion planning": check_self_motion_planning,
    "Planning on a cluster": check_planning_on_a_cluster,
    "Bring your own arm": check_bring_your_own_arm,
}


def test_every_python_block_is_checked() -> None:
    assert sorted({h for h, _, _ in BLOCKS}) == sorted(CHECKS)
    assert len(BLOCKS) == len(CHECKS)  # one block per section: CHECKS reads that block's names


@pytest.mark.parametrize(("heading", "block"), [(h, b) for h, _, b in BLOCKS], ids=[f"{h}-{i}" for h, i, _ in BLOCKS])
def test_python_block_runs_on_its_own_and_means_what_it_says(heading: str, block: str) -> None:
    ns: dict = {"__name__": "__readme__"}  # a fresh namespace: the block imports what it uses
    exec(compile(block, f"README.md ({heading})", "exec"), ns)
    CHECKS[heading](ns)


def test_every_readme_section_is_a_docs_page() -> None:
    """Each ``## `` section starts at a ``<!-- docs:NAME -->`` marker that docs/guide/NAME.md includes from."""
    lines, fence, pages = README.splitlines(), False, []
    for i, line in enumerate(lines):
        fence ^= line.startswith("```")
        if not fence and line.startswith("## "):
            marker = re.fullmatch(r"<!-- docs:([a-z0-9-]+) -->", lines[i - 1])
            assert marker, f"no docs marker before {line!r}"
            pages.append(marker.group(1))
    index = (ROOT / "docs" / "index.md").read_text()
    for name in pages:
        page = (ROOT / "docs" / "guide" / f"{name}.md").read_text()
        assert f":start-after: <!-- docs:{name} -->" in page and f"\nguide/{name}\n" in index


def test_readme_links_every_example() -> None:
    text = sections()["Examples"]
    linked = re.findall(r"\[examples/([\w.]+)\]\(examples/([\w.]+)\)", text)
    assert all(a == b for a, b in linked), linked
    assert sorted(a for a, _ in linked) == sorted(p.name for p in (ROOT / "examples").glob("*.py"))
