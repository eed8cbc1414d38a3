r"""The viewer's web server: a viser scene of the arm, its branches, its best answer and its obstacles.

The page (viser's client, served on ``http://HOST:PORT``) shows:

- the arm drawn solid (:mod:`qpik.viewer.geometry`): :func:`qpik.solve_best`'s answer for the target
  (the numerical IK's for an arm without a closed form), the controller's configuration in live mode,
  the played configuration in playback;
- a target frame to drag (viser's transform controls); every drag update recomputes the branches, the
  feasible sets and the best answer without its certificate, and the certificate follows when the drag
  ends (:data:`Viewer.latencies` times each drag update from its callback to the flushed scene messages);
- every closed-form branch at the slider's δ/ψ as a translucent ghost labelled with its branch id: green
  where it is inside the joint limits, orange where it reaches the pose outside them (a branch that does
  not reach the pose is hidden);
- the slider of δ/ψ with the exact feasible sets of every branch under it (:mod:`qpik.viewer.chart`);
- the obstacles (red), the link capsules (blue) and, per obstacle, the segment from it to the nearest
  capsule with the distance in mm, red when it is below ``d_safe``;
- a playback folder with a time slider (:mod:`qpik.viewer.playback`) and a live folder: the QP
  controller (:meth:`qpik.Controller.for_robot`, posture toward the best answer) tracks the target in
  real time, integrated at its control period ``dt``, with its status.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import io
import math
import socket
import threading
import time

import numpy as np
import viser

from qpik.analytic.intervals import wrap
from qpik.core.errors import InputError, ViewerError
from qpik.core.validate import number
from qpik.core.validate import pose as check_pose
from qpik.geometry.distance import ObstacleSet
from qpik.objectives import NAMES
from qpik.robots.robot import Robot, as_robot
from qpik.viewer.chart import feasible_chart
from qpik.viewer.geometry import ArmGeometry, Part, capsule_part, rotation, shape_part, wxyz
from qpik.viewer.options import ViewOptions
from qpik.viewer.playback import Track, as_track
from qpik.viewer.state import ViewState, prepare_search, solve_view

WITHIN, OUTSIDE, BEST = (47, 158, 68), (245, 130, 32), (240, 160, 0)
GHOST_OPACITY = 0.28
OBSTACLE, CAPSULE = (224, 49, 49), (51, 154, 240)
FRAME_RATE = 30.0
"""Hz: how often live mode and playback redraw the scene."""
LATENCIES = 1000
"""Drag updates whose latency :attr:`Viewer.latencies` keeps."""


def port_free(host: str, port: int) -> bool:
    """Whether a server can listen on ``host:port`` now (binding as asyncio's servers do, with SO_REUSEADDR)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


class Viewer:
    """A running viewer of one arm; see the module docstring and :func:`qpik.view`.

    Args:
        robot: any arm.
        target: (4, 4) the first target pose (default the end effector at the home configuration).
        obstacles: shapes of :mod:`qpik.geometry` (world frame).
        objective: a name of :data:`qpik.objectives.NAMES`, :func:`qpik.solve_best`'s objective.
        d_safe: m, the clearance :func:`qpik.solve_best` and the controller keep.
        play: a :class:`qpik.Plan`, a :class:`qpik.sim.SimLog` or a plan file to play back.
        options: live mode, the controller's period (s) in it, and the address
            (:class:`~qpik.viewer.options.ViewOptions`; default its defaults).

    Raises:
        ViewerError: the port is taken.
        InputError: bad arguments (naming them).
    """

    def __init__(
        self,
        robot: Robot,
        target: np.ndarray | None = None,
        obstacles=(),
        objective: str = "margin",
        *,
        d_safe: float = 0.02,
        play=None,
        options: ViewOptions | None = None,
    ):
        options = ViewOptions() if options is None else options
        if not isinstance(options, ViewOptions):
            raise InputError(f"options: expected ViewOptions, got {type(options).__name__}")
        live, host, port, dt = options.live, options.host, options.port, options.dt
        self.robot = robot = as_robot(robot)
        self.obstacles = obstacles if isinstance(obstacles, ObstacleSet) else ObstacleSet(obstacles)
        if not isinstance(objective, str) or objective not in NAMES:
            raise InputError(f"objective: expected one of {list(NAMES)}, got {objective!r}")
        self.d_safe = number(d_safe, "d_safe")
        self.dt = number(dt, "dt")
        if self.dt <= 0:
            raise InputError(f"dt: must be > 0, got {dt}")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise InputError(f"port: expected an integer in 0..65535, got {port!r}")
        pose = robot.fk(robot.q_home) if target is None else target
        self.track: Track | None = None if play is None else as_track(play, robot)
        self._pose = check_pose(pose, "target")[0]
        if self._pose.ndim != 2:
            raise InputError(f"target: expected one pose (4, 4), got shape {self._pose.shape}")
        self._objective = objective
        self._param = 0.0
        self._lock = threading.RLock()
        self._pending: tuple[np.ndarray, float] | None = None
        self._busy = False
        self._pending_lock = threading.Lock()
        self._override: np.ndarray | None = None  # the solid arm's q in live mode and playback
        self._live: threading.Thread | None = None
        self._playing: threading.Thread | None = None
        self._stop = threading.Event()
        self.latencies: collections.deque[float] = collections.deque(maxlen=LATENCIES)
        """Seconds from each drag update's callback to its scene messages flushed (the latest :data:`LATENCIES`)."""
        self.updates = 0
        """Drag updates drawn."""
        self._state: ViewState | None = None

        if port and not port_free(host, port):
            raise ViewerError(_taken(host, port))
        with contextlib.redirect_stdout(io.StringIO()):  # viser's banner: the caller prints the address
            self.server = viser.ViserServer(host=host, port=port, label=f"qpik · {robot.name}", verbose=False)
        if port and self.server.get_port() != port:  # taken between the check and the start
            self._stop_server()
            raise ViewerError(_taken(host, port))
        self.host, self.port = host, self.server.get_port()
        self._certifier: threading.Thread | None = None
        try:
            self._build()
            first = self.update(certify=False)
            if first.best is not None and first.best.status == "optimal":
                self.set_param(first.best.param)
            self._certify_later()
            if live:
                self.live = True
        except BaseException:
            self._stop_server()
            raise

    # ---- public API -------------------------------------------------------

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "::", "") else self.host
        return f"http://{host}:{self.port}"

    @property
    def state(self) -> ViewState:
        """The answers drawn last."""
        return self._state

    @property
    def pose(self) -> np.ndarray:
        """(4, 4) the current target."""
        return self._pose.copy()

    def set_target(self, pose: np.ndarray, certify: bool = True) -> ViewState:
        """Move the target to ``pose`` (4, 4) and redraw everything (as when a drag ends); returns the answers."""
        T = check_pose(pose, "pose")[0]
        if T.ndim != 2:
            raise InputError(f"pose: expected one pose (4, 4), got shape {T.shape}")
        self._target.position, self._target.wxyz = T[:3, 3], wxyz(T[:3, :3])
        return self.update(T, certify=certify)

    def set_param(self, value: float) -> None:
        """Put the ghosts at redundancy parameter ``value`` (rad, wrapped to (−π, π])."""
        self._slider.value = float(wrap(number(value, "value", None)))  # the slider's callback redraws

    def update(self, pose: np.ndarray | None = None, certify: bool = True) -> ViewState:
        """Recompute and redraw the answers for ``pose`` (default: the current target); returns them."""
        with self._lock:
            if pose is not None:
                self._pose = pose
            seed = self._override if self._override is not None else self._state.q if self._state else None
            state = solve_view(self.robot, self._pose, self._param, self._objective, self.obstacles, self.d_safe,
                               certify, seed)  # fmt: skip
            self._state = state
            with self.server.atomic():
                self._draw(state)
            self.server.flush()
        return state

    @property
    def live(self) -> bool:
        """Whether the QP controller tracks the target (set it to start or stop)."""
        return self._live is not None

    @live.setter
    def live(self, on: bool) -> None:
        if bool(on) == self.live:
            return
        if on:
            self._stop_playing()
            self._live = threading.Thread(target=self._run_live, name="qpik-view-live", daemon=True)
            self._live.start()
        else:
            thread, self._live = self._live, None
            thread.join()
            self._override = None
            self.update()
        if self._live_box.value != bool(on):
            self._live_box.value = bool(on)

    def seek(self, k: int) -> None:
        """Show record ``k`` of the playback (its configuration solid, its pose as the target)."""
        if self.track is None:
            raise InputError("seek: this viewer has nothing to play back")
        k = int(np.clip(k, 0, len(self.track) - 1))
        with self._lock:
            self._override = self.track.q[k]
            if self.track.param is not None:
                self._param = float(self.track.param[k])
                self._slider.value = round(self._param, 4)
            T = self.track.poses[k]
            self._target.position, self._target.wxyz = T[:3, 3], wxyz(T[:3, :3])
            self.update(T, certify=False)
            status = f", status {self.track.status[k]}" if self.track.status is not None else ""
            branch = f", branch {self.track.branch[k]}" if self.track.branch is not None else ""
            self._play_md.content = f"record {k + 1}/{len(self.track)}, t = {self.track.t[k]:.3f} s{branch}{status}"

    def screenshot(self, path, size: tuple[int, int] = (1280, 800)) -> np.ndarray:
        """Render the page in a headless browser and write it as PNG to ``path``; returns the image (H, W, 3).

        Raises:
            ViewerError: no headless browser (:mod:`qpik.viewer.browser`).
        """
        from qpik.viewer.browser import screenshot

        self.wait()
        return screenshot(self, path, size)

    def serve_forever(self) -> None:
        """Block until Ctrl-C, then stop the server."""
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def close(self) -> None:
        """Stop live mode, playback and the server."""
        self._stop.set()
        for thread in (self._live, self._playing):
            if thread is not None:
                thread.join()
        self._live = self._playing = None
        self.wait()
        self._stop_server()

    def wait(self) -> None:
        """Wait until the certificate of the first pose is drawn."""
        if self._certifier is not None:
            self._certifier.join()

    def _certify_later(self) -> None:
        """Certify the current pose in a thread of its own (its first certificate builds the arm's bounds); where
        the level sets certified it, build the search instead (:func:`~qpik.viewer.state.prepare_search`)."""
        state = self._state
        if state.best is None:
            return
        work = self.update
        if state.best.certified:
            work = functools.partial(prepare_search, self.robot, state, self._objective, self.obstacles, self.d_safe)
        self._certifier = threading.Thread(target=work, name="qpik-view-certify", daemon=True)
        self._certifier.start()

    def _stop_server(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(Exception):  # "Server stopped"; stopped
            self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- scene ------------------------------------------------------------

    def _build(self) -> None:
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
        self._arm = self._add_arm("/arm", None, 1.0)
        self._best = self._add_arm("/best", BEST, 0.45, visible=False)
        closed = robot.closed_form is not None
        from qpik.analytic.api import closed_form_for

        self._branch_ids = closed_form_for(robot).branch_array.tolist() if closed else []
        self._ghosts = [self._add_arm(f"/ghost{b}", WITHIN, GHOST_OPACITY, visible=False) for b in self._branch_ids]
        self._ghost_colour = [WITHIN] * len(self._ghosts)
        self._labels = [scene.add_label(f"/ghost{b}/label", f"b{b}", visible=False) for b in self._branch_ids]
        self._capsules = []
        for c, cap in enumerate(robot.capsules):
            part, local = capsule_part(cap, CAPSULE, 0.25)
            self._capsules.append((self._mesh(f"/capsules/c{c}", part), cap.link, local))
        scene.add_frame("/capsules", show_axes=False, visible=len(self.obstacles) > 0)
        for o, shape in enumerate(self.obstacles.shapes):
            part, T = shape_part(shape, OBSTACLE, 0.45)
            self._mesh(f"/obstacles/o{o}", part, T[:3, 3], wxyz(T[:3, :3]))
        count = len(self.obstacles)
        self._clear_lines = scene.add_line_segments("/clearance", np.zeros((max(count, 1), 2, 3)), (0, 0, 0),
                                                    thickness=0.004, visible=count > 0)  # fmt: skip
        self._clear_labels = [scene.add_label(f"/clearance/d{o}", "") for o in range(count)]
        T = self._pose
        self._target = scene.add_transform_controls("/target", scale=0.18, position=T[:3, 3], wxyz=wxyz(T[:3, :3]))
        self._target.on_update(self._on_drag)
        self._build_panel()

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

    def _mesh(self, name: str, part: Part, position=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0)):
        return self.server.scene.add_mesh_simple(
            name, part.vertices, part.faces, color=part.rgb, opacity=None if part.opacity >= 1.0 else part.opacity,
            position=position, wxyz=quat, side="front",
            cast_shadow=part.opacity >= 1.0, receive_shadow=part.opacity >= 1.0,
        )  # fmt: skip

    def _build_panel(self) -> None:
        robot, gui = self.robot, self.server.gui
        closed = robot.closed_form is not None
        symbol = {"srs": "ψ", "offset_shoulder": "δ", "locked_joint": "q7"}.get(robot.closed_form or "", "")
        self._symbol = symbol
        kind = {"srs": "S-R-S, closed form in the arm angle ψ", "offset_shoulder": "offset shoulder, closed form in δ",
                "locked_joint": "closed form with q7 locked"}  # fmt: skip
        what = kind.get(robot.closed_form or "", "no closed form")
        gui.add_markdown(f"**{robot.name}** ({robot.dof} joints): {what}")
        with gui.add_folder("Branches", visible=closed):
            self._slider = gui.add_slider(f"{symbol or 'param'} [rad]", -math.pi, math.pi, 0.001, 0.0,
                                          marks=((-math.pi, "−π"), (0.0, "0"), (math.pi, "π")))  # fmt: skip
            self._slider.on_update(lambda _: self._on_param())
            self._chart = gui.add_html("")
            self._ghost_box = gui.add_checkbox("ghosts", True)
            self._ghost_box.on_update(lambda _: self._draw_ghosts(self._state))
            self._branch_md = gui.add_markdown("")
        with gui.add_folder("Best answer" if closed else "Numerical IK"):
            self._objective_dd = gui.add_dropdown("objective", NAMES, initial_value=self._objective, visible=closed)
            self._objective_dd.on_update(lambda _: self._on_objective())
            self._best_md = gui.add_markdown("")
            self._to_best = gui.add_button(f"{symbol or 'param'} ← best", visible=closed)
            self._to_best.on_click(lambda _: self._go_to_best())
        with gui.add_folder("Obstacles", visible=len(self.obstacles) > 0):
            self._capsule_box = gui.add_checkbox("capsules", len(self.obstacles) > 0)
            self._capsule_box.on_update(lambda e: setattr(self.server.scene.get_handle_by_name("/capsules"), "visible",
                                                          e.target.value))  # fmt: skip
            self._clear_md = gui.add_markdown("")
        with gui.add_folder("Playback", visible=self.track is not None):
            k = max(len(self.track) - 1, 1) if self.track is not None else 1
            self._time = gui.add_slider("record", 0, k, 1, 0)
            self._time.on_update(lambda e: self.seek(e.target.value) if self._playing is None or e.client else None)
            self._play = gui.add_button("play")
            self._play.on_click(lambda _: self._toggle_play())
            self._play_md = gui.add_markdown(self.track.label if self.track is not None else "")
        with gui.add_folder("Live"):
            self._live_box = gui.add_checkbox("QP controller tracks the target", False)
            self._live_box.on_update(lambda e: setattr(self, "live", e.target.value))
            self._live_md = gui.add_markdown("off")

    # ---- callbacks --------------------------------------------------------

    def _on_drag(self, event) -> None:
        """A drag update (or its end, which draws the certificate too)."""
        received = time.perf_counter()
        if event.phase == "end":
            self.update(certify=True)
            return
        if event.phase != "update":
            return
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = rotation(event.target.wxyz), event.target.position
        self.receive(T, received)

    def receive(self, pose: np.ndarray, received: float) -> None:
        """Handle a target pose (4, 4) received at ``received`` (``time.perf_counter()``) during a drag: draw it
        without the certificate, or hand it to the thread drawing (the latest pose wins)."""
        with self._pending_lock:
            self._pending = (pose, received)
            if self._busy:
                return
            self._busy = True
        while True:
            with self._pending_lock:
                item, self._pending = self._pending, None
                if item is None:
                    self._busy = False
                    return
            self.update(item[0], certify=False)
            self.latencies.append(time.perf_counter() - item[1])
            self.updates += 1

    def _on_param(self) -> None:
        with self._lock:
            self._param = float(self._slider.value)
            state = self._state
            if state.branches is None:
                return
            from qpik.analytic import ik

            state.branches, state.param = ik(self.robot, state.pose, self._param), self._param
            with self.server.atomic():
                self._draw_ghosts(state)
                self._draw_chart(state)
            self.server.flush()

    def _go_to_best(self) -> None:
        best = self._state.best
        if best is not None and best.status == "optimal":
            self.set_param(best.param)

    def _on_objective(self) -> None:
        self._objective = self._objective_dd.value
        self.update(certify=True)

    # ---- drawing ----------------------------------------------------------

    def _draw(self, state: ViewState) -> None:
        q = state.q if self._override is None else self._override
        self._place(self._arm, q)
        if self._override is not None and state.best is not None:
            self._place(self._best, state.best.q)
        self.server.scene.get_handle_by_name("/best").visible = self._override is not None and state.best is not None
        self._draw_ghosts(state)
        self._draw_capsules(q)
        self._draw_chart(state)
        self._best_md.content = _best_text(state, self._symbol)

    def _place(self, frames: list, q: np.ndarray) -> None:
        """Put the moving bodies of an arm (its frames of :meth:`_add_arm`) at configuration q."""
        pos, quat = self.geometry.poses(q)
        for frame, body, p, w in zip(frames, self.geometry.bodies, pos, quat):
            if body.moving:
                frame.position, frame.wxyz = p, w

    def _draw_ghosts(self, state: ViewState) -> None:
        """A ghost per branch that reaches the pose, but not one that is the solid arm itself; a label per place
        (branches whose middle link frames coincide, as the shoulder and wrist flips of an S-R-S arm do, share one)."""
        sol = state.branches
        if sol is None:
            return
        solid = state.q if self._override is None else self._override
        show = sol.valid & self._ghost_box.value & (np.abs(sol.q - solid).max(axis=1) > 1e-9)
        F = self.robot.frames(sol.q)  # (B, n+2, 4, 4): the labels sit at the middle link's frame
        spots = F[:, (self.robot.dof + 1) // 2, :3, 3]
        texts: dict[int, list[str]] = {}
        for k, frames in enumerate(self._ghosts):
            root = self.server.scene.get_handle_by_name(f"/ghost{self._branch_ids[k]}")
            if root.visible != bool(show[k]):
                root.visible = bool(show[k])
            if not show[k]:
                continue
            colour = WITHIN if sol.within_limits[k] else OUTSIDE
            if colour != self._ghost_colour[k]:
                self._ghost_colour[k] = colour
                for body in self.geometry.bodies:
                    for i in range(len(body.parts)):
                        handle = self.server.scene.get_handle_by_name(f"/ghost{self._branch_ids[k]}/b{body.body}/p{i}")
                        handle.color = colour
            self._place(frames, sol.q[k])
            first = next((j for j in texts if np.linalg.norm(spots[j] - spots[k]) < 0.01), k)
            texts.setdefault(first, []).append(f"b{self._branch_ids[k]}")
        for k, label in enumerate(self._labels):
            label.visible = k in texts
            if k in texts:
                label.text, label.position = " ".join(texts[k]), spots[k]
        within, valid = int(sol.within_limits.sum()), int(sol.valid.sum())
        self._branch_md.content = (f"{self._symbol} = {state.param:.3f} rad: {valid} of {len(sol.valid)} branches reach"
                                   f" the pose, {within} inside the joint limits (ghosts: green inside, orange"
                                   " outside)")  # fmt: skip

    def _draw_chart(self, state: ViewState) -> None:
        if state.intervals is None:
            return
        best = state.best
        mark = (best.branch, best.param) if best is not None and best.status == "optimal" else None
        self._chart.content = feasible_chart(state.intervals, state.param, mark, self._symbol)

    def _draw_capsules(self, q: np.ndarray) -> None:
        F = self.robot.frames(q)
        for handle, link, local in self._capsules:
            T = F[link] @ local
            handle.position, handle.wxyz = T[:3, 3], wxyz(T[:3, :3])
        dist = self._state.clearance if self._override is None else None
        if not len(self.obstacles):
            return
        if dist is None:
            from qpik.geometry.distance import distances

            dist = distances(self.robot.capsule_segments(q), self.robot.capsule_radii, self.obstacles)
        moving = np.flatnonzero(~self.robot.fixed_capsules)
        points, colours, lines = [], [], []
        for o, (shape, label) in enumerate(zip(self.obstacles.shapes, self._clear_labels)):
            c = moving[np.argmin(dist.d[moving, o])]
            d = float(dist.d[c, o])
            a, b = dist.p_link[c, o], dist.p_obs[c, o]
            points.append((a, b))
            colours.append(OBSTACLE if d < self.d_safe else WITHIN)
            label.text = f"{d * 1e3:.0f} mm"
            label.position = 0.5 * (a + b)
            name = shape.name or f"obstacle {o}"
            lines.append(f"{name}: {d * 1e3:.1f} mm from capsule {c + 1} (link {self.robot.capsules[c].link})")
        self._clear_lines.points = np.array(points, dtype=np.float32)
        self._clear_lines.colors = np.repeat(np.array(colours, dtype=np.uint8)[:, None], 2, axis=1)
        self._clear_md.content = "  \n".join([f"clearance (d_safe = {self.d_safe * 1e3:.0f} mm):", *lines])

    # ---- live mode and playback --------------------------------------------

    def _run_live(self) -> None:
        from qpik.control import Controller

        robot = self.robot
        q = self._state.q.copy()
        ctrl = Controller.for_robot(robot, target=self._pose, obstacles=self.obstacles, dt=self.dt, d_safe=self.d_safe)
        steps = 0
        start = last = time.perf_counter()
        while self._live is not None and not self._stop.is_set():
            now = time.perf_counter()
            due = min(int((now - last) / self.dt), int(0.2 / self.dt))  # real time, at most 0.2 s of catching up
            last += due * self.dt if due < int(0.2 / self.dt) else now - last
            target, best = self._pose, self._state.best
            if best is not None and best.status == "optimal":
                ctrl.set_posture(best.q)
            for _ in range(due):
                q = q + ctrl.step(q, target=target) * self.dt
            steps += due
            info = ctrl.last
            with self._lock:
                self._override = q
                with self.server.atomic():
                    self._place(self._arm, q)
                    if best is not None:
                        self._place(self._best, best.q)
                    self.server.scene.get_handle_by_name("/best").visible = best is not None
                    self._draw_capsules(q)
                    if info is not None:
                        rate = steps / max(time.perf_counter() - start, 1e-9)
                        clear = f", clearance {info.min_clearance * 1e3:.1f} mm" if len(self.obstacles) else ""
                        self._live_md.content = (
                            f"status **{info.status}**, pose error {info.task_error:.2e} (m, rad){clear}, "
                            f"solve {info.solve_time * 1e6:.0f} µs, {rate:.0f} steps/s (dt = {self.dt * 1e3:g} ms); "
                            "gold: the best answer, the controller's posture reference")  # fmt: skip
                self.server.flush()
            time.sleep(max(0.0, 1.0 / FRAME_RATE - (time.perf_counter() - now)))
        self._live_md.content = "off"

    def _toggle_play(self) -> None:
        if self._playing is not None:
            self._stop_playing()
            return
        self.live = False
        self._playing = threading.Thread(target=self._run_play, name="qpik-view-play", daemon=True)
        self._play.label = "pause"
        self._playing.start()

    def _stop_playing(self) -> None:
        thread, self._playing = self._playing, None
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        self._play.label = "play"

    def _run_play(self) -> None:
        track = self.track
        k0 = int(self._time.value) if self._time.value < len(track) - 1 else 0
        t0, start = track.t[k0], time.perf_counter()
        k = k0
        while self._playing is not None and not self._stop.is_set() and k < len(track) - 1:
            elapsed = track.t[k0] + (time.perf_counter() - start) - t0
            k = max(k + 1, int(np.searchsorted(track.t, t0 + elapsed, side="right")) - 1)
            k = min(k, len(track) - 1)
            self.seek(k)
            self._time.value = k
            time.sleep(1.0 / FRAME_RATE)
        self._playing = None
        self._play.label = "play"


def _taken(host: str, port: int) -> str:
    return f"port {port} is taken: another program listens on {host}:{port}; choose another with --port"


def _best_text(state: ViewState, symbol: str) -> str:
    """The panel's lines on the solid arm's answer."""
    if state.numerical is not None:
        r = state.numerical
        return (f"numerical IK (Levenberg–Marquardt from the last configuration): **{r.status}**, "
                f"pose error {r.residual:.2e} (m, rad)")  # fmt: skip
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
    return (f"solid arm: branch **{best.branch}**, {symbol} = {best.param:.4f} rad, objective {best.objective:.6g}"
            f"{clear}  \n{cert} ({best.method}, {best.time * 1e3:.1f} ms)")  # fmt: skip
