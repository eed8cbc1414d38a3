"""A problem's pieces as one value: the arm, its obstacles, the clearance kept, the objective, q_ref, the capsule
pairs of the arm kept apart."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from qpik.core.errors import InputError
from qpik.core.validate import finite_array, number
from qpik.geometry.distance import ObstacleSet
from qpik.geometry.shapes import Shape
from qpik.native.compiled import RowMap
from qpik.objectives import Context, Objective, clearance, pair_count, resolve
from qpik.robots.robot import Robot, as_robot
from qpik.robots.self_pairs import Pair, candidate_pairs, checked_pairs, never_apart
from qpik.scene.bounds import BoundFunction, bound_function
from qpik.scene.evaluator import Evaluator


@dataclass(frozen=True, eq=False)
class Scene:
    """What a problem is about, checked and converted once (:meth:`of`), then handed to every solver.

    :func:`qpik.solve_best`, :func:`qpik.nlp.solve_full`, :func:`qpik.checks.crosscheck.crosscheck`,
    :func:`qpik.plan_self_motion` and :func:`qpik.plots.objective.objective_map` take it, so the arm, the
    obstacles and the objective mean the same to all of them.

    Attributes:
        robot: the arm.
        obstacles: the obstacles, packed once (:class:`~qpik.geometry.distance.ObstacleSet`; base frame, m).
        d_safe: the clearance every link capsule keeps from every obstacle, and the capsules of every pair of
            :attr:`self_pairs` from each other, m (≥ 0).
        objective: the cost minimised over the redundancy (:mod:`qpik.objectives`), or None.
        q_ref: (n,) the reference configuration of a :class:`~qpik.objectives.ReferenceDistance` term and of
            the controller's posture task, rad (None: the arm's home configuration).
        self_pairs: the pairs ``(c, e)`` of the arm's own capsules (indices of ``robot.capsules``) kept ≥ d_safe
            apart (:func:`~qpik.robots.self_pairs.checked_pairs`, by default); () when self-collision is turned
            off.
    """

    robot: Robot
    obstacles: ObstacleSet
    d_safe: float
    objective: Objective | None
    q_ref: np.ndarray | None
    self_pairs: tuple[Pair, ...] = ()

    @classmethod
    def of(
        cls,
        robot: Robot,
        obstacles: Sequence[Shape] | ObstacleSet = (),
        *,
        d_safe: float = 0.02,
        objective: Objective | str | None = None,
        q_ref: np.ndarray | None = None,
        self_collision: bool | Sequence[Pair] = True,
    ) -> Scene:
        """The scene of ``robot`` with the arguments checked (:class:`~qpik.core.errors.InputError` naming the one that
        is not right) and the obstacles packed.

        Args:
            robot: the arm (:func:`qpik.load_robot`).
            obstacles: shapes of :mod:`qpik.geometry` or an ObstacleSet (base frame, m).
            d_safe: clearance, m (finite, ≥ 0).
            objective: an :class:`~qpik.objectives.Objective`, a name of :data:`qpik.objectives.NAMES`, or None
                (none: each solver's own default, e.g. the joint-limit margin for :func:`qpik.solve_best`).
            q_ref: (n,) reference configuration, rad, or None.
            self_collision: keep the arm's own capsules ≥ d_safe apart: True (the default) for the pairs of
                :func:`~qpik.robots.self_pairs.checked_pairs` (the non-adjacent pairs minus the default allowed
                list) less those never d_safe apart (:func:`~qpik.robots.self_pairs.never_apart`: every
                configuration would violate them), or the capsule pairs to keep apart (e.g.
                ``checked_pairs(robot, srdf=...)``); False: none.
                On by default because an answer is a configuration sent to the arm, and a 7-DOF arm's best
                configuration for a pose can fold two of its links into each other; see :attr:`self_pairs`.
        """
        robot = as_robot(robot)
        packed = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
        d_safe = number(d_safe, "d_safe")
        if q_ref is not None:
            q_ref = finite_array(q_ref, "q_ref", (robot.dof,)).copy()
            q_ref.flags.writeable = False
        return cls(robot, packed, d_safe, None if objective is None else resolve(objective), q_ref,
                   _self_pairs(robot, self_collision, d_safe))  # fmt: skip

    def __post_init__(self) -> None:
        if not isinstance(self.robot, Robot) or not isinstance(self.obstacles, ObstacleSet):
            raise InputError("Scene: build it with Scene.of(robot, obstacles, ...), which checks its arguments")

    def replace(self, **changes: object) -> Scene:
        """A scene with some of :meth:`of`'s arguments changed (checked again); the compiled functions of the
        same robot, objective form and obstacle families are shared, not rebuilt."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        fields["self_collision"] = fields.pop("self_pairs")
        fields.update(changes)
        robot = fields.pop("robot")
        return Scene.of(robot, fields.pop("obstacles"), **fields)

    @property
    def reference(self) -> np.ndarray:
        """(n,) :attr:`q_ref`, or the arm's home configuration without one, rad."""
        return self.robot.q_home if self.q_ref is None else self.q_ref

    @property
    def pairs(self) -> int:
        """The number of (link capsule, obstacle) pairs kept apart: those of the capsules a joint moves."""
        return pair_count(self.robot, self.obstacles)

    def with_objective(self, default: Objective | str) -> Scene:
        """This scene, or with ``default`` as its objective when it has none."""
        return self if self.objective is not None else self.replace(objective=default)

    @cached_property
    def evaluator(self) -> Evaluator:
        """The objective and the clearances at many configurations (compiled once per robot and form)."""
        return Evaluator(self.robot, self.objective, self.obstacles, self.self_pairs)

    @cached_property
    def bounds(self) -> BoundFunction | None:
        """The objective's Taylor-model bounds (the certificate of :func:`qpik.solve_best`), or None when the
        objective has none."""
        return bound_function(self.robot, self.objective, self.obstacles, self.self_pairs)

    def clearance(self, q: np.ndarray) -> np.ndarray:
        """(M,) the smallest distance of the pairs (:attr:`pairs`) at configurations q (M, n), m; inf without any."""
        q = finite_array(q, "q", (None, self.robot.dof))
        return clearance(self.robot, q, self.obstacles)

    @property
    def self_distances(self) -> RowMap:
        """The signed distances (P,) of the capsule pairs :attr:`self_pairs` at one configuration (n,), m
        (:attr:`~qpik.objectives.Context.self_distances`), compiled over rows on its first call (or
        :meth:`~qpik.native.compiled.RowMap.build`): ``self_distances(q)[0]`` is (M, P) for q (M, n); one map per
        robot and pairs, kept in the robot's cache (so the scene still pickles)."""
        return self.robot.cache.get(("self distances", self.self_pairs), _self_distance_map, self.robot,
                                    self.self_pairs)  # fmt: skip

    def self_clearance(self, q: np.ndarray) -> np.ndarray:
        """(M,) the smallest distance of the capsule pairs :attr:`self_pairs` at configurations q (M, n), m
        (:attr:`self_distances`); inf without any."""
        q = finite_array(q, "q", (None, self.robot.dof))
        if not self.self_pairs or not len(q):
            return np.full(len(q), np.inf)
        return self.self_distances(q)[0].min(axis=1)


def _self_distance_map(robot: Robot, pairs: tuple[Pair, ...]) -> RowMap:
    """:attr:`Scene.self_distances` of ``robot``'s capsule ``pairs``."""
    q = ca.SX.sym("q", robot.dof)
    ctx = Context(robot, q, q, ObstacleSet(()), ca.SX(0, 1), self_pairs=pairs)
    return RowMap(ca.Function(f"self_distances_{robot.identifier}", [q], [ctx.self_distances]), chunks=(128, 16))


def _self_pairs(robot: Robot, self_collision: bool | Sequence[Pair], d_safe: float) -> tuple[Pair, ...]:
    """:attr:`Scene.self_pairs` from :meth:`Scene.of`'s ``self_collision`` (checked: candidate pairs only) and
    ``d_safe`` (m)."""
    if isinstance(self_collision, (bool, np.bool_)):
        if not self_collision:
            return ()
        never = never_apart(robot, d_safe)
        return tuple(p for p in checked_pairs(robot) if p not in never)
    try:
        pairs = tuple(sorted({tuple(sorted((int(c), int(e)))) for c, e in self_collision}))
    except (TypeError, ValueError):
        raise InputError("self_collision: expected a bool or a sequence of capsule index pairs (c, e)") from None
    bad = sorted(set(pairs) - set(candidate_pairs(robot)))
    if bad:
        raise InputError(f"self_collision: {bad} are not candidate pairs (capsules of non-adjacent links)")
    return pairs  # type: ignore[return-value]


def scene_of(
    robot: Robot | Scene,
    obstacles: Sequence[Shape] | ObstacleSet | None = None,
    d_safe: float | None = None,
    objective: Objective | str | None = None,
    q_ref: np.ndarray | None = None,
) -> Scene:
    """The scene a public call works in: ``robot`` itself when it is a :class:`Scene` (then none of the other
    arguments may be given: they are the scene's), else :meth:`Scene.of` of them (defaults: no obstacles,
    d_safe 0.02 m, no objective, no q_ref).

    Raises:
        InputError: a piece given both in the scene and as an argument (named), or a bad piece.
    """
    if isinstance(robot, Scene):
        given = {"obstacles": obstacles, "d_safe": d_safe, "objective": objective, "q_ref": q_ref}
        for name, value in given.items():
            if value is not None:
                held = f"{getattr(robot, name)!r:.60}"
                raise InputError(
                    f"{name}: a Scene carries its own (here {held}); give it with scene.replace({name}=...), not also "
                    "as an argument"
                )
        return robot
    return Scene.of(robot, () if obstacles is None else obstacles, d_safe=0.02 if d_safe is None else d_safe,
                    objective=objective, q_ref=q_ref)  # fmt: skip
