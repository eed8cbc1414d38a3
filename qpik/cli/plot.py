"""``qpik plot``: pictures of the closed form for one pose.

- ``selfmotion``: every joint against the redundancy parameter (δ, ψ or a locked joint's angle) over (-π, π], one
  curve per branch, joint limits, the ranges where the shaded branch leaves the limits, singular values;
- ``branches``: every valid branch at one parameter value (MuJoCo picture, or stick figures); with ``--q`` and no
  ``--param``, q's own.

The pose comes from the pose options of ``qpik ik`` or from a problem file
(its robot, first pose and first parameter value).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from qpik.cli.args import Subcommands, add_robot, floats, robot_from_args, whole
from qpik.cli.ik import add_pose, pose_from_args


def register(sub: Subcommands) -> None:
    p = sub.add_parser("plot", help="self-motion map or branch poses of one pose (PNG)")
    p.add_argument("what", choices=("selfmotion", "branches"), help="which picture")
    add_robot(p, required=False)
    g = add_pose(p)
    g.add_argument("--problem", help="problem file (or shipped problem name): its robot, first pose and parameter")
    p.add_argument(
        "--param",
        "-p",
        type=float,
        help="the redundancy parameter (rad) for 'branches' (default with --q: the parameter of q)",
    )
    p.add_argument("--branches", type=floats, help="branch ids to draw in 'selfmotion' (default: all)")
    p.add_argument(
        "--shade", type=int, help="branch whose infeasible parameter ranges are shaded (default: first drawn)"
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="PNG file to write")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from qpik import ik, redundancy_parameter
    from qpik.core.errors import InputError
    from qpik.core.validate import pose as check_pose
    from qpik.plots import save
    from qpik.plots.closed_form import branch_pictures, selfmotion_map

    param = args.param
    if args.problem:
        from qpik.problems import find_problem, load

        problem = load(find_problem(args.problem))
        if problem.poses is None:
            raise InputError(f"--problem: {problem.name} has a path target, not a pose")
        robot, T = problem.robot, problem.poses[0]
        if param is None and problem.params is not None:
            param = float(problem.params[0])
    else:
        if args.robot is None:
            raise InputError("--robot is required unless --problem is given")
        robot = robot_from_args(args)
        T, _ = check_pose(pose_from_args(args, robot), "pose", args.project)
    if args.what == "selfmotion":
        branches = None if args.branches is None else whole(args.branches, "--branches")
        save(selfmotion_map(robot, T, branches=branches, shade_branch=args.shade), args.out)
        print(f"self-motion map of {robot.name} written to {args.out}")
        return 0
    if param is None and getattr(args, "q", None) is not None:
        param = float(redundancy_parameter(robot, args.q)[0])  # as qpik ik: the parameter of the given q
    if param is None:
        raise InputError("branches: --param is required (unless --q is given: then the parameter of q is used)")
    how = branch_pictures(robot, ik(robot, T, param), args.out)
    print(f"branch poses of {robot.name} at {param:.4f} rad written to {args.out} ({how})")
    return 0
