r"""The viewer's page: the viser scene and panel of one arm, and how a :class:`~qpik.viewer.state.ViewState` is drawn.

:class:`Page` builds, on a :class:`viser.ViserServer`, the scene (a grid, the arm solid, the best answer in
gold, one translucent ghost per closed-form branch with its label, the link capsules, the obstacles, the
clearance segments and the target's transform controls) and the panel (the δ/ψ slider over the feasible-set
chart, the objective, the obstacles' clearances, the playback and live-mode folders). It keeps the handles
of everything it draws; the viewer (:mod:`qpik.viewer.server`) connects the panel's callbacks.
Positions in the robot's base frame, metres; the slider in radians.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from qpik.geometry.distance import ObstacleSet
from qpik.objectives import NAMES
from qpik.robots.robot import Robot
from qpik.viewer.chart import feasible_chart
from qpik.viewer.geometry import ArmGeometry, Part, capsule_part, shape_part, wxyz
from qpik.viewer.playback import Track
from qpik.viewer.state import ViewState

if TYPE_CHECKING:
    import viser

    from qpik.geometry.distance import Distances

WITHIN, OUTSIDE, BEST = (47, 158, 68), (245, 130, 32), (240, 160, 0)
GHOST_OPACITY = 0.28
OBSTACLE, CAPSULE = (224, 49, 49), (51, 154, 240)


class Page:
    """The scene and panel of one arm on ``server`` (see the module docstring).

    Args:
        server: the viser server the page is drawn on.
        robot: the arm.
        obstacles: the obstacles drawn (base frame).
        d_safe: m, the clearance below which a distance is drawn red.
        pose: (4, 4) where the target's controls start.
        track: what the playback folder plays (None: the folder is hidden).
        objective: the objective first selected (a name of :data:`qpik.objectives.NAMES`).
    """

    def __init__(
        self,
        server: viser.ViserServer,
        robot: Robot,
        obstacles: ObstacleSet,
        d_safe: float,
        pose: np.ndarray,
        track: Track | None,
        objective: str,
    ):
        self.server, self.robot, self.obstacles, self.d_safe = server, robot, obstacles, d_safe
        self._build(pose, track, objective)

    def _build(self, pose: np.ndarray, track: Track | None, objective: str) -> None:
        robot, scene = self.robot, self.server.scene
        # no share button: sharing goes through viser's relay server, off this machine
        self.server.gui.configure_theme(control_width="large", show_share_button=False)
        scene.set_up_direction("+z")
        reach = float(np.linalg.norm(robot.frames(robot.q_home)[:, :3, 3], axis=1).max()) + 0.2
        cam = self.server.initial_camera
        cam.look_at = (0.15 * reach, 0.0, 0.35 * reach)
        cam.position = (1.1 * reach, -0.95 * reach, 0.75 * reach)
        scene.add_grid("/grid", width=2 * reach, height=2 * reach, cell_size=0.1, section_size=0.5)
        self.geometry = ArmGeometry(robot)
        self.arm = self._add_arm("/arm", None, 1.0)
        self.best = self._add_arm("/best", BEST, 0.45, visible=False)
        from qpik.analytic.api import closed_form_for

        self.branch_ids = closed_form_for(robot).branch_array.tolist() if robot.closed_form is not None else []
        self.ghosts = self._add_ghosts(len(self.branch_ids))
        self.labels = [scene.add_label(f"/ghosts/label{b}", f"b{b}", visible=False) for b in self.branch_ids]
        self.capsules = []
        for c, cap in enumerate(robot.capsules):
            part, local = capsule_part(cap, CAPSULE, 0.25)
            self.capsules.append((self._mesh(f"/capsules/c{c}", part), cap.link, local))
        scene.add_frame("/capsules", show_axes=False, visible=len(self.obstacles) > 0)
        for o, shape in enumerate(self.obstacles.shapes):
            part, T = shape_part(shape, OBSTACLE, 0.45)
            self._mesh(f"/obstacles/o{o}", part, T[:3, 3], wxyz(T[:3, :3]))
        count = len(self.obstacles)
        self.clear_lines = scene.add_line_segments("/clearance", np.zeros((max(count, 1), 2, 3)), (0, 0, 0),
                                                   thickness=0.004, visible=count > 0)  # fmt: skip
        self.clear_labels = [scene.add_label(f"/clearance/d{o}", "") for o in range(count)]
        self.target = scene.add_transform_controls("/target", scale=0.18, position=pose[:3, 3], wxyz=wxyz(pose[:3, :3]))
        self._build_panel(track, objective)

    def _add_arm(self, root: str, colour, opacity: float, visible: bool = True) -> list:
        """The arm's parts under ``root``: one frame per body (returned, in :attr:`ArmGeometry.bodies` order)."""
        frames = []
        self.server.scene.add_frame(root, show_axes=False, visible=visible)
        pos, quat = self.geometry.poses(self.robot.q_home)  # a fixed body stays where it is placed here
        for body, p, w in zip(self.geometry.bodies, pos, quat):
            frame = self.server.scene.add_frame(f"{root}/b{body.body}", show_axes=False, position=p, wxyz=w)
            for i, part in enumerate(body.parts):
                if colour is not None:
                    part = Part(part.vertices, part.faces, colour, opacity, part.geom)
                self._mesh(f"{root}/b{body.body}/p{i}", part)
            frames.append(frame)
        return frames

    def _add_ghosts(self, count: int) -> list:
        """The ghosts of ``count`` branches: per part of every body, one batched mesh ``/ghosts/b<body>/p<i>`` of
        ``count`` instances (instance k: branch k, scale 0 while hidden); returns ``(body index, handle)`` pairs."""
        if not count:
            return []
        scene, out = self.server.scene, []
        for j, body in enumerate(self.geometry.bodies):
            for i, part in enumerate(body.parts):
                handle = scene.add_batched_meshes_simple(
                    f"/ghosts/b{body.body}/p{i}", part.vertices, part.faces,
                    batched_wxyzs=np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (count, 1)),
                    batched_positions=np.zeros((count, 3), np.float32), batched_scales=np.zeros(count, np.float32),
                    batched_colors=np.tile(np.array(WITHIN, np.uint8), (count, 1)), opacity=GHOST_OPACITY,
                    lod="off", side="front", cast_shadow=False, receive_shadow=False,
                )  # fmt: skip
                out.append((j, handle))
        return out

    def _mesh(self, name: str, part: Part, position=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0)):
        return self.server.scene.add_mesh_simple(
            name, part.vertices, part.faces, color=part.rgb, opacity=None if part.opacity >= 1.0 else part.opacity,
            position=position, wxyz=quat, side="front",
            cast_shadow=part.opacity >= 1.0, receive_shadow=part.opacity >= 1.0,
        )  # fmt: skip

    def _build_panel(self, track: Track | None, objective: str) -> None:
        robot, gui = self.robot, self.server.gui
        closed, branches = robot.branch_functions, robot.closed_form is not None
        from qpik.analytic.api import closed_form_for
        from qpik.analytic.api import symbol as param_symbol

        # the solver's own parameter: q7, or q1 for an arm read from the flange
        symbol = param_symbol(closed_form_for(robot).param_name) if branches else ""
        self.symbol = symbol
        kind = {"srs": "S-R-S, closed form in the arm angle ψ", "offset_shoulder": "offset shoulder, closed form in δ",
                "locked_joint": f"closed form with {symbol} locked",
                "locked_search": f"no closed form: qpik.ik's branches by a 1-D search at {symbol} (its sampled "
                                 "feasible sets and best answer take seconds a pose: not drawn here)",
                "locked_general": f"a general 6-R with {symbol} locked: qpik.ik's branches from one eigenproblem "
                                  "(its sampled feasible sets and best answer take seconds a pose: not drawn "
                                  "here)"}  # fmt: skip
        what = kind.get(robot.closed_form or "", "no closed form")
        gui.add_markdown(f"**{robot.name}** ({robot.dof} joints): {what}")
        with gui.add_folder("Branches", visible=branches):
            self.slider = gui.add_slider(f"{symbol or 'param'} [rad]", -math.pi, math.pi, 0.001, 0.0,
                                         marks=((-math.pi, "−π"), (0.0, "0"), (math.pi, "π")))  # fmt: skip
            self.chart = gui.add_html("")
            self.ghost_box = gui.add_checkbox("ghosts", True)
            self.branch_md = gui.add_markdown("")
        with gui.add_folder("Best answer" if closed else "Solid arm"):
            self.objective_dd = gui.add_dropdown("objective", NAMES, initial_value=objective, visible=closed)
            self.best_md = gui.add_markdown("")
            self.to_best = gui.add_button(f"{symbol or 'param'} ← best", visible=closed)
        with gui.add_folder("Obstacles", visible=len(self.obstacles) > 0):
            self.capsule_box = gui.add_checkbox("capsules", len(self.obstacles) > 0)
            self.capsule_box.on_update(lambda e: setattr(self.server.scene.get_handle_by_name("/capsules"), "visible",
                                                         e.target.value))  # fmt: skip
            self.clear_md = gui.add_markdown("")
        with gui.add_folder("Playback", visible=track is not None):
            k = max(len(track) - 1, 1) if track is not None else 1
            self.time = gui.add_slider("record", 0, k, 1, 0)
            self.play = gui.add_button("play")
            self.play_md = gui.add_markdown(track.label if track is not None else "")
        with gui.add_folder("Live"):
            self.live_box = gui.add_checkbox("QP controller tracks the target", False)
            self.live_md = gui.add_markdown("off")

    def draw(self, state: ViewState, override: np.ndarray | None) -> None:
        """Draw ``state``: the solid arm at its q, or at ``override`` (n,) (live mode, playback) with the best
        answer in gold beside it; the ghosts, capsules, clearances, feasible-set chart and the answer's text."""
        q = state.q if override is None else override
        self.place(self.arm, q)
        if override is not None and state.best is not None:
            self.place(self.best, state.best.q)
        self.server.scene.get_handle_by_name("/best").visible = override is not None and state.best is not None
        self.draw_ghosts(state, q)
        self.draw_capsules(q, state.clearance if override is None else None)
        self.draw_chart(state)
        self.best_md.content = best_text(state, self.symbol)

    def place(self, frames: list, q: np.ndarray) -> None:
        """Put the moving bodies of an arm (its frames of :meth:`_add_arm`) at configuration q."""
        pos, quat = self.geometry.poses(q)
        for frame, body, p, w in zip(frames, self.geometry.bodies, pos, quat):
            if body.moving:
                frame.position, frame.wxyz = p, w

    def draw_ghosts(self, state: ViewState, solid: np.ndarray) -> None:
        """A ghost per branch that reaches the pose, but not one that is the solid arm itself; a label per place
        (branches whose middle link frames coincide, as the shoulder and wrist flips of an S-R-S arm do, share one);
        ``solid``: (n,) the solid arm's configuration. One message per part and property for every branch at once
        (:meth:`_add_ghosts`)."""
        sol = state.branches
        if sol is None:
            return
        show = sol.valid & self.ghost_box.value & (np.abs(sol.q - solid).max(axis=1) > 1e-9)
        # the labels sit at the middle link's frame; one configuration at a time is the compiled FK (a batch this
        # small is slower through the numpy path)
        spots = np.array([self.robot.frames(q)[(self.robot.dof + 1) // 2, :3, 3] for q in sol.q])
        count, bodies = len(self.branch_ids), len(self.geometry.bodies)
        pos = np.zeros((count, bodies, 3), np.float32)
        quat = np.zeros((count, bodies, 4), np.float32)
        quat[..., 0] = 1.0
        texts: dict[int, list[str]] = {}
        for k in np.flatnonzero(show):
            pos[k], quat[k] = self.geometry.poses(sol.q[k])
            first = next((j for j in texts if np.linalg.norm(spots[j] - spots[k]) < 0.01), k)
            texts.setdefault(first, []).append(f"b{self.branch_ids[k]}")
        colours = np.where(sol.within_limits[:, None], WITHIN, OUTSIDE).astype(np.uint8)
        scales = show.astype(np.float32)
        for j, handle in self.ghosts:
            handle.batched_positions, handle.batched_wxyzs, handle.batched_scales = pos[:, j], quat[:, j], scales
            if not np.array_equal(handle.batched_colors, colours):
                handle.batched_colors = colours
        for k, label in enumerate(self.labels):
            label.visible = k in texts
            if k in texts:
                label.text, label.position = " ".join(texts[k]), spots[k]
        within, valid = int(sol.within_limits.sum()), int(sol.valid.sum())
        self.branch_md.content = (f"{self.symbol} = {state.param:.3f} rad: {valid} of {len(sol.valid)} branches reach"
                                  f" the pose, {within} inside the joint limits (ghosts: green inside, orange"
                                  " outside)")  # fmt: skip

    def draw_chart(self, state: ViewState) -> None:
        """The feasible sets of every branch under the slider, the parameter and the best answer marked."""
        if state.intervals is None:
            return
        best = state.best
        mark = (best.branch, best.param) if best is not None and best.status == "optimal" else None
        self.chart.content = feasible_chart(state.intervals, state.param, mark, self.symbol)

    def draw_capsules(self, q: np.ndarray, dist: Distances | None) -> None:
        """The capsules at q (n,) and, per obstacle, the segment to its nearest capsule with the distance:
        ``dist`` (computed at q when None). Nothing without obstacles: the capsules are shown only with them."""
        if not len(self.obstacles):
            return
        F = self.robot.frames(q)
        for handle, link, local in self.capsules:
            T = F[link] @ local
            handle.position, handle.wxyz = T[:3, 3], wxyz(T[:3, :3])
        if dist is None:
            from qpik.geometry.distance import distances

            dist = distances(self.robot.capsule_segments(q), self.robot.capsule_radii, self.obstacles)
        moving = np.flatnonzero(~self.robot.fixed_capsules)
        points, colours, lines = [], [], []
        for o, (shape, label) in enumerate(zip(self.obstacles.shapes, self.clear_labels)):
            c = moving[np.argmin(dist.d[moving, o])]
            d = float(dist.d[c, o])
            a, b = dist.p_link[c, o], dist.p_obs[c, o]
            points.append((a, b))
            colours.append(OBSTACLE if d < self.d_safe else WITHIN)
            label.text = f"{d * 1e3:.0f} mm"
            label.position = 0.5 * (a + b)
            name = shape.name or f"obstacle {o}"
            lines.append(f"{name}: {d * 1e3:.1f} mm from capsule {c + 1} (link {self.robot.capsules[c].link})")
        self.clear_lines.points = np.array(points, dtype=np.float32)
        self.clear_lines.colors = np.repeat(np.array(colours, dtype=np.uint8)[:, None], 2, axis=1)
        self.clear_md.content = "  \n".join([f"clearance (d_safe = {self.d_safe * 1e3:.0f} mm):", *lines])


def best_text(state: ViewState, symbol: str) -> str:
    """The panel's lines on the solid arm's answer (``symbol``: δ, ψ or q7)."""
    if state.numerical is not None:
        r = state.numerical
        return (f"numerical IK (Levenberg–Marquardt from the last configuration): **{r.status}**, "
                f"pose error {r.residual:.2e} (m, rad)")  # fmt: skip
    if state.slot is not None:
        b = int(state.branches.branch[state.slot])
        return (f"solid arm: branch **{b}** at {symbol} = {state.param:.4f} rad, the branch inside the joint limits "
                "nearest the last configuration")  # fmt: skip
    best = state.best
    if best.status != "optimal":
        return f"**{best.status}**: {best.summary()}"
    if best.certified:
        cert = f"**certified** global optimum (gap {best.gap:.1e})"
    elif not state.certify:
        cert = "certificate: follows when the target rests"
    else:
        cert = f"not certified: {best.message}"
    clear = f", clearance {best.clearance * 1e3:.1f} mm" if math.isfinite(best.clearance) else ""
    value = best.quantity.text(best.objective)  # the margin as itself, not the −margin qpik minimises
    return (f"solid arm: branch **{best.branch}**, {symbol} = {best.param:.4f} rad, {value}, {best.quantity.sense}"
            f"{clear}  \n{cert} ({best.method}, {best.time * 1e3:.1f} ms)")  # fmt: skip
