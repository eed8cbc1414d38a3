"""The web viewer from Python: the iiwa14 over a table past a ball, its 8 branches, the best ψ, pictures of the page.

``qpik.view`` starts the viewer (viser, ``pip install 'qpik[view]'``) on a free local port without
blocking; the script then moves the target through three poses as a drag would, prints for each how
many branches reach it and stay inside the joint limits, the best answer of ``qpik.solve_best`` with its
certificate and the smallest clearance, and writes a picture of the page at the second pose (``view.png``),
rendered by the machine's headless Chromium (skipped, with one line, where there is none).

    python examples/view_branches.py [OUT]    # OUT: qpik-out/examples/view_branches/

To look at it yourself: ``qpik view --problem iiwa_obstacle_reach`` and open http://127.0.0.1:8080.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import qpik
from qpik.problems import find_problem, load
from qpik.viewer import ViewerError


def main(out: Path) -> None:
    problem = load(find_problem("iiwa_obstacle_reach"))
    robot, start = problem.robot, problem.poses[0]
    viewer = qpik.view(robot, start, problem.obstacles, "margin", d_safe=0.03,
                       options=qpik.ViewOptions(port=0, block=False))  # fmt: skip
    try:
        viewer.wait()  # the first pose's certificate
        print(f"viewer of {robot.name} at {viewer.url}, {len(viewer.obstacles)} obstacles")
        for k, shift in enumerate([(0.0, 0.0, 0.0), (-0.10, -0.15, 0.10), (0.05, -0.30, 0.20)]):
            pose = start.copy()
            pose[:3, 3] += shift
            state = viewer.set_target(pose)
            viewer.set_param(state.best.param)  # the ghosts at the best ψ
            sol = viewer.state.branches
            print(f"pose {k}: target at {np.round(pose[:3, 3], 3).tolist()} m; at ψ = {state.best.param:.4f} rad "
                  f"{int(sol.valid.sum())} of {len(sol)} branches reach it, {int(sol.within_limits.sum())} inside the "
                  f"limits; {state.best.summary()}")  # fmt: skip
            if np.isfinite(state.best.clearance):
                print(f"  clearance of the best answer to the obstacles: {state.best.clearance * 1e3:.1f} mm")
            if k == 1:  # half the branches outside the limits: orange ghosts
                try:
                    viewer.screenshot(out / "view.png")
                    print(f"  wrote {out / 'view.png'}")
                except ViewerError as exc:
                    print(f"  {exc}: picture skipped")
    finally:
        viewer.close()


if __name__ == "__main__":
    try:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "qpik-out/examples/view_branches"))
    except ViewerError as exc:  # viser is not installed
        print(exc, file=sys.stderr)
        sys.exit(1)
