"""``qpik render``: a PNG of one or several configurations of an arm."""

from __future__ import annotations

import argparse
from pathlib import Path

from qpik.cli.args import Subcommands, add_robot, at_least_one, floats, robot_from_args, whole


def register(sub: Subcommands) -> None:
    p = sub.add_parser("render", help="draw configurations of an arm to a PNG (MuJoCo, offscreen)")
    add_robot(p)
    p.add_argument(
        "--q",
        action="append",
        type=floats,
        metavar="Q",
        help='joint angles in rad, "q1,...,q7" (repeat for more; default: home)',
    )
    p.add_argument("-o", "--out", type=Path, default=Path("pose.png"), help="PNG file to write (default: pose.png)")
    p.add_argument("--overlay", action="store_true", help="draw every configuration in one picture")
    p.add_argument("--cols", type=int, default=None, help="tiles per row (default: about the square root of the count)")
    p.add_argument("--size", type=floats, default=None, metavar="W,H", help="tile size in pixels (default: 480,400)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from qpik.core.errors import InputError
    from qpik.render.pictures import RenderUnavailable, Tiles, render_configurations

    robot = robot_from_args(args)
    bad = [q.shape[0] for q in args.q or () if q.shape != (robot.dof,)]
    if bad:
        raise InputError(f"--q: expected {robot.dof} angles, got {bad[0]}")
    qs = np.array(args.q) if args.q else robot.q_home[None]
    size = (480, 400) if args.size is None else tuple(whole(args.size, "--size"))
    if len(size) != 2:
        raise InputError(f"--size: expected W,H, got {args.size}")
    if args.cols is not None:
        at_least_one(args.cols, "--cols")
    try:
        render_configurations(robot, qs, args.out, tiles=Tiles(cols=args.cols, size=size, overlay=args.overlay))
    except RenderUnavailable as exc:  # the one line of qpik.cli.main, exit code 2
        raise RenderUnavailable(f"nothing drawn, no OpenGL: {exc}") from None
    print(f"wrote {args.out} ({len(qs)} configuration{'s' if len(qs) > 1 else ''} of {robot.name})")
    return 0
