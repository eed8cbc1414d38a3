"""``qpik best``: the globally best closed-form branch and redundancy parameter (δ, ψ, or a locked joint's angle) for
one pose, with the per-branch table.

The pose options are those of ``qpik ik``. Obstacles come from a problem file (``--problem``,
its obstacles only) or from ``--sphere x,y,z,r`` options (m, world frame). ``--plot FILE``
also draws the objective against the parameter for every branch (:mod:`qpik.plots.objective`).

The 1-D search's arms (the Sawyer, Baxter) are sampled along their locked joint and polished, never certified
(:mod:`qpik.nlp.best_sampled`). An arm without a closed form gets the joint-space NLP instead
(:func:`qpik.nlp.solve_full`: the best of its starts, a local optimum, never certified), and the output says so and
why.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from qpik.cli.args import Subcommands, add_robot, floats, robot_from_args
from qpik.cli.ik import add_pose, pose_from_args
from qpik.nlp.options import BestOptions
from qpik.scene import Scene


def register(sub: Subcommands) -> None:
    from qpik.objectives import NAMES

    p = sub.add_parser(
        "best",
        help="the globally best branch and redundancy parameter for a pose (certified NLP over every branch; the "
        "joint-space NLP on an arm without a closed form)",
    )
    add_robot(p)
    add_pose(p)
    p.add_argument(
        "--objective",
        default="margin",
        choices=NAMES,
        help="the joint-limit margin, manipulability or clearance (maximised), or the distance to --q-ref "
        "(minimised); default: margin",
    )
    p.add_argument("--q-ref", type=floats, help="7 joint angles (rad): the reference of --objective distance")
    p.add_argument(
        "--sphere", type=floats, action="append", default=[], help="an obstacle: x,y,z,radius (m; repeatable)"
    )
    p.add_argument("--problem", help="take the obstacles of this problem file (or shipped problem name)")
    p.add_argument(
        "--d-safe",
        type=float,
        default=0.02,
        help="smallest capsule–obstacle distance allowed, and between the arm's own capsules (m; default: 0.02)",
    )
    p.add_argument(
        "--no-self-collision", action="store_true", help="let the arm's own capsules come closer than --d-safe"
    )
    p.add_argument("--tol", type=float, default=1e-4, help="the certificate's relative tolerance (default: 1e-4)")
    p.add_argument("--no-certify", action="store_true", help="skip the certificate of global optimality")
    p.add_argument(
        "--method",
        default="auto",
        choices=("auto", "levelset", "search", "ipopt"),
        help="auto: the margin's level sets for the margin alone, else the search (default: auto)",
    )
    p.add_argument("--plot", type=Path, help="also write the objective against the redundancy parameter (PNG)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from qpik import solve_best
    from qpik.core.errors import InputError, NoClosedFormError
    from qpik.core.validate import pose as check_pose
    from qpik.geometry import Sphere

    robot = robot_from_args(args)
    T, _ = check_pose(pose_from_args(args, robot), "pose", args.project)
    obstacles = []
    if args.problem:
        from qpik.problems import find_problem, load

        obstacles += list(load(find_problem(args.problem)).obstacles)
    for s in args.sphere:
        if s.size != 4:
            raise InputError(f"--sphere: expected x,y,z,radius (4 numbers), got {s.size}")
        obstacles.append(Sphere(s[:3], s[3]))
    scene = Scene.of(robot, obstacles, d_safe=args.d_safe, objective=args.objective, q_ref=args.q_ref,
                     self_collision=not args.no_self_collision)  # fmt: skip
    p = np.array2string(T[:3, 3], precision=4)
    extra = f", {len(obstacles)} obstacle(s), d_s = {args.d_safe:g} m" if obstacles else ""
    try:
        best = solve_best(scene, T, options=BestOptions(certify=not args.no_certify, tol=args.tol, method=args.method))
    except NoClosedFormError as exc:
        return _joint_space(scene, T, f"{robot.name}: {scene.objective.quantity.goal} at p = {p} m{extra}", exc, args)
    print(f"{robot.name}: {best.quantity.goal} at p = {p} m{extra}")
    print(best.table())
    print(best.summary())
    if best.status == "optimal":
        print("q* = " + np.array2string(best.q, precision=6, max_line_width=200) + " rad")
    if args.plot:
        from qpik.plots import save
        from qpik.plots.objective import objective_map

        save(objective_map(scene, T, best), args.plot)
        print(f"{best.quantity.name} against the redundancy parameter written to {args.plot}")
    return 0 if best.status in ("optimal", "no feasible branch", "unreachable") else 2


def _joint_space(scene: Scene, T, head: str, why: Exception, args: argparse.Namespace) -> int:
    """``qpik best`` on an arm without a closed form: :func:`qpik.nlp.solve_full`."""
    import numpy as np

    from qpik.nlp import solve_full

    print(head)
    print(f"no search over the redundancy parameter: {why}")
    ignored = [name for name, given in (("--plot", args.plot), ("--no-certify", args.no_certify)) if given]
    ignored += ["--method"] if args.method != "auto" else []
    if ignored:
        print(f"ignored here: {', '.join(ignored)} (they apply to the search over the parameter)")
    full = solve_full(scene, T)
    print(f"joint-space NLP (qpik.nlp.solve_full, {full.starts} starts): a local optimum, not certified")
    if full.status != "optimal":
        print(f"{full.status}: {full.message or 'no start reached the pose inside the limits'}")
        return 0 if full.status == "unreachable" else 2
    quantity = scene.objective.quantity
    print(f"best: {quantity.text(full.objective, '.10g')}, {quantity.sense}; pose error {full.pose_error:.1e}")
    print("q* = " + np.array2string(full.q, precision=6, max_line_width=200) + " rad")
    return 0
