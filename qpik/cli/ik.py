"""``qpik ik``: every closed-form branch for one pose, with its forward-kinematics residual.

The pose is given as 16 numbers (row-major 4x4), as a position and a rotation
(9 numbers, rows), or as joint angles (the pose is then ``fk(q)``). With
``--q`` and no ``--param`` the parameter of ``q`` itself is used, so one branch
gives back ``q``.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from qpik.cli.args import Subcommands, add_robot, floats, robot_from_args
from qpik.core.errors import InputError


def register(sub: Subcommands) -> None:
    p = sub.add_parser(
        "ik", help="closed-form IK: all branches at one redundancy parameter, checked by forward kinematics"
    )
    add_robot(p)
    add_pose(p)
    p.add_argument(
        "--param",
        "-p",
        type=float,
        help="redundancy parameter, rad: δ (offset shoulder), ψ (S-R-S) or the locked joint's angle (q7 or q1, as "
        "the output names it); default with --q: the parameter of q",
    )
    p.set_defaults(func=_run)


def add_pose(p: argparse.ArgumentParser) -> Any:
    """The pose options shared by ``qpik ik`` and ``qpik plot``; returns their exclusive group."""
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--pose", type=floats, help="16 numbers, the 4x4 pose row by row (m)")
    g.add_argument("--position", type=floats, help="x,y,z of the end effector (m); with --rotation")
    g.add_argument("--q", type=floats, help="joint angles (rad); the pose is fk(q)")
    p.add_argument("--rotation", type=floats, help="9 numbers, the rotation row by row (default: identity)")
    p.add_argument("--project", action="store_true", help="project a non-orthonormal rotation onto SO(3)")
    return g


def pose_from_args(args: argparse.Namespace, robot) -> np.ndarray:
    """The (4, 4) pose named by the :func:`add_pose` options (not yet validated)."""
    if args.pose is not None:
        if args.pose.size != 16:
            raise InputError(f"--pose needs 16 numbers, got {args.pose.size}")
        return args.pose.reshape(4, 4)
    if args.q is not None:
        if args.rotation is not None:
            raise InputError("--rotation goes with --position, not --q")
        return robot.fk(args.q)
    if args.position.size != 3:
        raise InputError(f"--position needs 3 numbers, got {args.position.size}")
    R = np.eye(3) if args.rotation is None else args.rotation
    if R.size != 9:
        raise InputError(f"--rotation needs 9 numbers, got {R.size}")
    T = np.eye(4)
    T[:3, :3] = R.reshape(3, 3)
    T[:3, 3] = args.position
    return T


def _run(args: argparse.Namespace) -> int:
    from qpik import feasible_intervals, ik, redundancy_parameter
    from qpik.analytic.api import symbol
    from qpik.core.validate import pose as check_pose
    from qpik.problems.ik import branch_table

    robot = robot_from_args(args)
    T, _ = check_pose(pose_from_args(args, robot), "pose", args.project)
    param = args.param
    if param is None:
        if args.q is None:
            raise InputError("--param is required (unless --q is given: then the parameter of q is used)")
        param, branch = redundancy_parameter(robot, args.q)
        print(f"parameter of the given q: {param:.6f} rad (branch {branch})")
    sols = ik(robot, T, param)
    sym = symbol(sols.param_name)
    p = np.array2string(T[:3, 3], precision=4)
    print(f"{robot.name}: {len(sols)} branches at {sym} = {param:.6f} rad; p = {p} m")
    print(branch_table(robot, sols, T))
    fi = feasible_intervals(robot, T)
    ok = [f"{b}" for b in fi.branch if fi.measure(int(b)) > 0]
    proof = "" if fi.proved else " (not proved: qpik.feasible_intervals)"
    print(f"branches with a feasible {sym} range inside the limits: {', '.join(ok) or 'none'}{proof}")
    return 0
