r"""The viewer's web server: a viser scene of the arm, its branches, its best answer and its obstacles.

:class:`Viewer` runs the server, answers the page's controls and runs live mode and playback; the page
(:mod:`qpik.viewer.page`, viser's client served on ``http://HOST:PORT``) shows:

- the arm drawn solid (:mod:`qpik.viewer.geometry`): :func:`qpik.solve_best`'s answer for the target (for an arm
  whose branches :func:`qpik.ik` finds by a search, the branch at the slider's parameter inside the limits nearest
  the last configuration, so that the slider moves it along its self-motion; the numerical IK's for an arm without
  either), the controller's configuration in live mode, the played configuration in playback;
- a target frame to drag (viser's transform controls); every drag update recomputes the branches, the
  feasible sets and the best answer without its certificate, and the certificate follows when the drag
  ends (:data:`Viewer.latencies` times each drag update from its callback to the flushed scene messages);
- every branch of :func:`qpik.ik` at the slider's parameter as a translucent ghost labelled with its branch id: green
  inside the joint limits, orange outside them (a branch that does not reach the pose is hidden);
- the slider of the parameter with the exact feasible sets of every branch under it (:mod:`qpik.viewer.chart`);
- the obstacles (red), the link capsules (blue) and, per obstacle, the segment from it to the nearest capsule with
  the distance in mm, red when it is below ``d_safe``;
- a playback folder with a time slider (:mod:`qpik.viewer.playback`) and a live folder: the QP
  controller (:meth:`qpik.Controller.for_robot`, posture toward the best answer) tracks the target in
  real time, integrated at its control period ``dt``, with its status.
"""

from __future__ import annotations

import collections
import contextlib
import io
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
from qpik.viewer.geometry import ArmGeometry, rotation, wxyz
from qpik.viewer.options import ViewOptions
from qpik.viewer.page import Page
from qpik.viewer.playback import Track, as_track
from qpik.viewer.state import ViewState, prepare_search, solve_view

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
        self.cpu_times: collections.deque[float] = collections.deque(maxlen=LATENCIES)
        """CPU seconds of the thread drawing each drag update, over the same span as :attr:`latencies` (less than it
        by the time other threads and processes held the CPU)."""
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
            self.page = Page(self.server, robot, self.obstacles, self.d_safe, self._pose, self.track, objective)
            self._connect()
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
    def geometry(self) -> ArmGeometry:
        """The arm's meshes the page draws."""
        return self.page.geometry

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
        self.page.target.position, self.page.target.wxyz = T[:3, 3], wxyz(T[:3, :3])
        return self.update(T, certify=certify)

    def set_param(self, value: float) -> None:
        """Put the ghosts at redundancy parameter ``value`` (rad, wrapped to (−π, π])."""
        self.page.slider.value = float(wrap(number(value, "value", None)))  # the slider's callback redraws

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
                self.page.draw(state, self._override)
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
        if self.page.live_box.value != bool(on):
            self.page.live_box.value = bool(on)

    def seek(self, k: int) -> None:
        """Show record ``k`` of the playback (its configuration solid, its pose as the target)."""
        if self.track is None:
            raise InputError("seek: this viewer has nothing to play back")
        k = int(np.clip(k, 0, len(self.track) - 1))
        with self._lock:
            self._override = self.track.q[k]
            if self.track.param is not None:
                self._param = float(self.track.param[k])
                self.page.slider.value = round(self._param, 4)
            T = self.track.poses[k]
            self.page.target.position, self.page.target.wxyz = T[:3, 3], wxyz(T[:3, :3])
            self.update(T, certify=False)
            status = f", status {self.track.status[k]}" if self.track.status is not None else ""
            branch = f", branch {self.track.branch[k]}" if self.track.branch is not None else ""
            self.page.play_md.content = f"record {k + 1}/{len(self.track)}, t = {self.track.t[k]:.3f} s{branch}{status}"

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
        """Wait until the certificate of the first pose is drawn and the search of later poses is built."""
        if self._certifier is not None:
            self._certifier.join()

    def _certify_later(self) -> None:
        """Certify the current pose in a thread of its own (its first certificate builds the arm's bounds) unless
        the level sets certified it, then build the search (:func:`~qpik.viewer.state.prepare_search`)."""
        state = self._state
        if state.best is None:
            return

        def work() -> None:
            if not state.best.certified:
                self.update()
            prepare_search(self.robot, state, self._objective, self.obstacles, self.d_safe)

        self._certifier = threading.Thread(target=work, name="qpik-view-certify", daemon=True)
        self._certifier.start()

    def _stop_server(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(Exception):  # "Server stopped"; stopped
            self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- callbacks --------------------------------------------------------

    def _connect(self) -> None:
        """The page's controls call the viewer."""
        page = self.page
        page.target.on_update(self._on_drag)
        page.slider.on_update(lambda _: self._on_param())
        page.ghost_box.on_update(lambda _: self.page.draw_ghosts(self._state, self._solid()))
        page.objective_dd.on_update(lambda _: self._on_objective())
        page.to_best.on_click(lambda _: self._go_to_best())
        page.time.on_update(lambda e: self.seek(e.target.value) if self._playing is None or e.client else None)
        page.play.on_click(lambda _: self._toggle_play())
        page.live_box.on_update(lambda e: setattr(self, "live", e.target.value))

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
            cpu = time.thread_time()
            self.update(item[0], certify=False)
            self.latencies.append(time.perf_counter() - item[1])
            self.cpu_times.append(time.thread_time() - cpu)
            self.updates += 1

    def _on_param(self) -> None:
        with self._lock:
            self._param = float(self.page.slider.value)
            state = self._state
            if state.branches is None:
                return
            if not self.robot.branch_functions:  # the solid arm is a branch at the slider's parameter: it follows
                self.update(certify=False)
                return
            from qpik.analytic import ik

            state.branches, state.param = ik(self.robot, state.pose, self._param), self._param
            with self.server.atomic():
                self.page.draw_ghosts(state, self._solid())
                self.page.draw_chart(state)
            self.server.flush()

    def _solid(self) -> np.ndarray:
        """(n,) the solid arm's configuration: the answer's, or the live or played one."""
        return self._state.q if self._override is None else self._override

    def _go_to_best(self) -> None:
        best = self._state.best
        if best is not None and best.status == "optimal":
            self.set_param(best.param)

    def _on_objective(self) -> None:
        self._objective = self.page.objective_dd.value
        self.update(certify=True)

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
                    self.page.place(self.page.arm, q)
                    if best is not None:
                        self.page.place(self.page.best, best.q)
                    self.server.scene.get_handle_by_name("/best").visible = best is not None
                    self.page.draw_capsules(q, None)
                    if info is not None:
                        rate = steps / max(time.perf_counter() - start, 1e-9)
                        clear = f", clearance {info.min_clearance * 1e3:.1f} mm" if len(self.obstacles) else ""
                        self.page.live_md.content = (
                            f"status **{info.status}**, pose error {info.task_error:.2e} (m, rad){clear}, "
                            f"solve {info.solve_time * 1e6:.0f} µs, {rate:.0f} steps/s (dt = {self.dt * 1e3:g} ms); "
                            "gold: the best answer, the controller's posture reference")  # fmt: skip
                self.server.flush()
            time.sleep(max(0.0, 1.0 / FRAME_RATE - (time.perf_counter() - now)))
        self.page.live_md.content = "off"

    def _toggle_play(self) -> None:
        if self._playing is not None:
            self._stop_playing()
            return
        self.live = False
        self._playing = threading.Thread(target=self._run_play, name="qpik-view-play", daemon=True)
        self.page.play.label = "pause"
        self._playing.start()

    def _stop_playing(self) -> None:
        thread, self._playing = self._playing, None
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        self.page.play.label = "play"

    def _run_play(self) -> None:
        track = self.track
        k0 = int(self.page.time.value) if self.page.time.value < len(track) - 1 else 0
        t0, start = track.t[k0], time.perf_counter()
        k = k0
        while self._playing is not None and not self._stop.is_set() and k < len(track) - 1:
            elapsed = track.t[k0] + (time.perf_counter() - start) - t0
            k = max(k + 1, int(np.searchsorted(track.t, t0 + elapsed, side="right")) - 1)
            k = min(k, len(track) - 1)
            self.seek(k)
            self.page.time.value = k
            time.sleep(1.0 / FRAME_RATE)
        self._playing = None
        self.page.play.label = "play"


def _taken(host: str, port: int) -> str:
    return f"port {port} is taken: another program listens on {host}:{port}; choose another with --port"
