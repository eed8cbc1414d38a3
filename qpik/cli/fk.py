"""``qpik fk``: the end-effector pose of one configuration, with its Jacobian's conditioning.

Prints the 4x4 pose (base frame), the position, the rotation as roll-pitch-yaw
(``R = Rz(yaw) Ry(pitch) Rx(roll)``) and the manipulability.
"""

from __future__ import annotations

import argparse

import numpy as np

from qpik.cli.args import Subcommands, add_robot, floats, robot_from_args


def register(sub: Subcommands) -> None:
    p = sub.add_parser("fk", help="forward kinematics: pose, position, roll-pitch-yaw of a configuration")
    add_robot(p)
    p.add_argument(
        "--q", type=floats, required=True, help='joint angles, e.g. "0 0.5 0 -1.2 0 0.9 0" or --q=-0.5,0,...'
    )
    p.add_argument("--deg", action="store_true", help="--q is in degrees")
    p.set_defaults(func=_run)


def roll_pitch_yaw(R: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) in rad with ``R = Rz(yaw) Ry(pitch) Rx(roll)``; pitch in [-π/2, π/2]."""
    return np.array(
        [np.arctan2(R[2, 1], R[2, 2]), np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0])), np.arctan2(R[1, 0], R[0, 0])]
    )


def _run(args: argparse.Namespace) -> int:
    robot = robot_from_args(args)
    q = np.deg2rad(args.q) if args.deg else args.q
    T = robot.fk(q)  # validates q (shape, finite)
    rpy = roll_pitch_yaw(T[:3, :3])
    fmt = {"float_kind": lambda x: f"{x: .6f}"}
    print(f"{robot.name} at q = {np.array2string(q, precision=4)} rad")
    if not robot.within_limits(q):
        print("  (q is outside the joint limits)")
    print("pose (base frame):")
    print(np.array2string(T, formatter=fmt))
    print(f"position (m):           {np.array2string(T[:3, 3], formatter=fmt)}")
    print(f"roll, pitch, yaw (rad): {np.array2string(rpy, formatter=fmt)}")
    print(f"roll, pitch, yaw (deg): {np.array2string(np.rad2deg(rpy), formatter=fmt)}")
    print(f"manipulability: {robot.manipulability(q):.6g} (translational {robot.manipulability(q, True):.6g})")
    return 0
