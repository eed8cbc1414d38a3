"""``qpik view``: the arm in a web browser (viser): drag the target, see every branch, its feasible set, the best.

``qpik view [ROBOT|FILE]`` serves ``http://127.0.0.1:8080`` until Ctrl-C (``pip install 'qpik[view]'``);
``--problem NAME`` takes the robot, first target and obstacles of a problem file, ``--play FILE`` plays
the plan file (``*_plan.npz``) of ``qpik plan``, ``--live`` starts the QP controller, and
``--screenshot out.png`` writes the page as rendered by a headless browser instead of serving it.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from qpik.cli.args import Subcommands, add_robot, floats, robot_from_args, whole

DEFAULT_ROBOT = "iiwa14"


def register(sub: Subcommands) -> None:
    p = sub.add_parser("view", help="show an arm in a web browser: drag the target, see every branch (viser)")
    p.add_argument("arm", nargs="?", metavar="ROBOT|FILE",
                   help=f"arm of the catalog or an MJCF/URDF file (default: {DEFAULT_ROBOT}; or --robot)")  # fmt: skip
    add_robot(p, required=False)
    p.add_argument("--problem", metavar="NAME|FILE", help="robot, first target and obstacles of a problem file")
    p.add_argument("--play", type=Path, metavar="PLAN.npz", help="play back the plan file that qpik plan writes")
    p.add_argument("--objective", default="margin", help="solve_best's objective (default: margin)")
    p.add_argument("--d-safe", type=float, default=0.02, help="clearance to the obstacles, m (default: 0.02)")
    p.add_argument("--live", action="store_true", help="start with the QP controller tracking the target")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    p.add_argument("--port", type=int, default=8080, help="port to listen on (default: 8080)")
    p.add_argument("--screenshot", type=Path, metavar="PNG", help="write the page as a PNG (headless browser) and exit")
    p.add_argument("--size", type=floats, default=None, metavar="W,H", help="screenshot size in pixels (1280,800)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from qpik.core.errors import InputError
    from qpik.viewer import view
    from qpik.viewer.options import ViewOptions

    if args.arm is not None and args.robot is not None and args.arm != args.robot:
        raise InputError(f"ROBOT: given twice, {args.arm!r} and --robot {args.robot!r}")
    args.robot = args.arm or args.robot
    target, obstacles = None, ()
    if args.problem is not None:
        from qpik.problems import find_problem, load

        problem = load(find_problem(args.problem))
        if args.robot is not None:
            raise InputError(f"--problem: {problem.name} names its robot ({problem.robot.name}); leave out ROBOT")
        robot = problem.robot
        target = problem.poses[0] if problem.poses is not None else None
        obstacles = problem.obstacles
    else:
        args.robot = args.robot or DEFAULT_ROBOT
        robot = robot_from_args(args)
    size = (1280, 800) if args.size is None else tuple(whole(args.size, "--size"))
    if len(size) != 2:
        raise InputError(f"--size: expected W,H, got {args.size}")
    if args.screenshot is not None and args.screenshot.suffix.lower() != ".png":
        raise InputError(f"--screenshot: the picture is PNG, so the name must end in .png: {args.screenshot}")
    replaced = args.screenshot is not None and args.screenshot.exists()
    options = ViewOptions(live=args.live, host=args.host, port=args.port, block=False)
    common = dict(d_safe=args.d_safe, play=args.play)
    if args.screenshot is not None:
        shot = dataclasses.replace(options, screenshot=args.screenshot, size=size)
        view(robot, target, obstacles, args.objective, options=shot, **common)
        print(f"wrote {args.screenshot} ({size[0]}x{size[1]}, {robot.name}){' (replaced)' if replaced else ''}")
        return 0
    viewer = view(robot, target, obstacles, args.objective, options=options, **common)
    print(f"qpik view: {robot.name} at {viewer.url} (Ctrl-C stops; from another machine: "
          f"ssh -L {viewer.port}:localhost:{viewer.port} THIS_HOST)", flush=True)  # fmt: skip
    viewer.serve_forever()
    return 0
