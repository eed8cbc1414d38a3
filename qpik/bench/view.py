"""Bench: ``qpik view``'s update latency, from a dragged target pose received to the scene messages sent.

For each arm a viewer (:class:`qpik.viewer.server.Viewer`) serves on a free local port to one client, so that its
messages are really serialised, compressed and sent while the bench runs (``--client``, the note says which and
whether it connected):

- ``socket`` (the default): :class:`qpik.viewer.listener.Listener`, a websocket client in a process of its own
  that connects as viser's page does and receives and decodes every message, drawing nothing: in use the page is
  on the user's own machine (a remote viewer is reached through a forwarded port), so the server is timed with
  the CPU it would have. Each pose is sent once the client has every message of the update before (a mark after
  them, :meth:`~qpik.viewer.listener.Listener.sync`; viser's page sends a dragged pose at most every 50 ms, so the
  drag is no slower than a user's), and the note also gives each update's time to that mark's arrival at the client:
  the messages sent, not only flushed.
- ``browser``: a page of the viewer in headless Chromium (:mod:`qpik.viewer.browser`), drawn in software GL; its
  processes run at the lowest CPU priority (:func:`~qpik.viewer.browser.lower_priority`, Linux), but the page
  redraws continuously and takes most of a core of a small machine, which then stalls the server now and then.
  The poses follow each other at once.

A scripted drag of :data:`POSES` target poses (a loop of 8 cm around an end-effector pose, turning ±0.3 rad about
z) goes through :meth:`~qpik.viewer.server.Viewer.receive`, the path of the target's drag callback: every branch at
the slider's ψ/δ, the feasible sets, :func:`qpik.solve_best` without its certificate (which follows when a
drag ends) or the numerical IK, the clearances, every scene and panel message, and the flush of the
websocket buffers. Each update's time is from the pose's arrival to the flush. Every update is timed, the
first one after the viewer's start included: its one-time preparation (compiles, traces) is done by then, the bench
waiting for it as a user waits for the page (:meth:`~qpik.viewer.server.Viewer.wait`). The note also gives the CPU
time of the thread drawing the updates (the latency less the time other threads and processes held the CPU, so a
latency far above it is load, not work) and that of the server's whole process over each update, every thread: the
feasible sets of a large search share their rows with a second thread (:class:`qpik.native.compiled.RowMap`), and
viser's thread serialises and sends the messages.
Arms: the catalog iiwa14
(alone, and with the ball and table of ``problems/iiwa_obstacle_reach.toml``), the catalog Panda (closed form
with q7 locked, its sets by a sweep), the KUKA iiwa URDF of ``pybullet_data`` (meshes, closed form found
in the file's chain) and, when example-robot-data is installed, its xArm7 (q7 locked on the ideal geometry nearest
to its file, polished on the file's chain: :func:`qpik.robots.locked_joint.ideal_chain`).
The loops go around the home pose; the URDF's home is the file's zero, the arm stretched straight up, where
most of the loop is out of reach, so it is also dragged around a bent pose
(:data:`BENT`). Each row says how many of its poses were reached: by some branch, or by the numerical IK
(status ``"ok"``).
"""

from __future__ import annotations

import argparse
import contextlib
import time

import numpy as np

from qpik.bench import Row
from qpik.core.errors import QpikError

TITLE = "Viewer update: target pose received → scene messages sent (qpik view, scripted drag poses)"
POSES = 100
BUDGET = 0.050  # s per update, the target
CLIENTS = ("socket", "browser")
"""The clients ``--client`` chooses from (module docstring); the first is the default."""
PAGE = (1280, 800)
"""(width, height) px of the page open in Chromium while an arm is dragged (``--client browser``)."""
BENT = np.array([0.0, 0.6, 0.0, -1.4, 0.0, 0.8, 0.0])
"""(7,) rad: the bent configuration the URDF arm is also dragged around (shoulder, elbow and wrist bent)."""


def drag(robot, count: int = POSES, q: np.ndarray | None = None) -> np.ndarray:
    """The scripted drag: ``count`` poses (count, 4, 4) on a closed loop around the end effector at ``q`` (n,)
    (default home)."""
    T0 = robot.fk(robot.q_home if q is None else q)
    th = 2 * np.pi * np.arange(count) / count
    out = np.repeat(T0[None], count, axis=0)
    out[:, :3, 3] += 0.08 * np.stack([np.cos(th) - 1.0, np.sin(th), 0.5 * np.sin(2 * th)], axis=1)
    a = 0.3 * np.sin(th)
    Rz = np.zeros((count, 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = np.cos(a), -np.sin(a), np.sin(a), np.cos(a), 1
    out[:, :3, :3] = Rz @ T0[:3, :3]
    return out


def _arms() -> list[tuple[str, object, tuple, np.ndarray | None, str]]:
    from qpik.problems import find_problem, load
    from qpik.robots.loader import load_robot

    iiwa, problem = load_robot("iiwa14"), load(find_problem("iiwa_obstacle_reach"))
    arms = [("iiwa14", iiwa, (), None, ""), ("iiwa14 + ball and table", iiwa, problem.obstacles, None, ""),
            ("panda (q7 locked)", load_robot("panda"), (), None, "")]  # fmt: skip
    from qpik.robots.packaged import packaged_model

    label = "URDF pybullet kuka_iiwa"
    try:
        urdf = load_robot(str(packaged_model("pybullet/iiwa")))
        arms += [(label, urdf, (), None, ""), (f"{label}, bent", urdf, (), BENT, "")]
    except QpikError as exc:  # pybullet is not installed
        arms.append((label, None, (), None, str(exc)))
    label = "URDF example-robot-data xArm7 (q7 locked, polished)"
    try:
        arms.append((label, load_robot(str(packaged_model("erd/xarm7"))), (), None, ""))
    except QpikError as exc:  # example-robot-data is not installed
        arms.append((label, None, (), None, str(exc)))
    return arms


def run(args: argparse.Namespace) -> list[Row]:
    from qpik.viewer import ViewerError
    from qpik.viewer.browser import browser
    from qpik.viewer.options import ViewOptions
    from qpik.viewer.server import Viewer

    rows = []
    with contextlib.ExitStack() as stack:
        chromium, why = None, ""
        if args.client == "browser":
            try:
                chromium = stack.enter_context(browser())
            except ViewerError as exc:
                why = str(exc)
        for label, robot, obstacles, centre, missing in _arms():
            if robot is None:
                rows[-1].note += f"; {label} left out: {missing}"
                continue
            with Viewer(robot, obstacles=obstacles, options=ViewOptions(port=0)) as viewer:
                viewer.wait()
                with _client(args.client, chromium, why, viewer) as (listener, seen):
                    reached, delivered, process = 0, [], []
                    for pose in drag(robot, min(POSES, args.repeat), centre):
                        received, start = time.perf_counter(), time.process_time()
                        viewer.receive(pose, received)
                        process.append(time.process_time() - start)
                        if listener is not None:
                            delivered.append(listener.sync() - received)
                        best, numerical = viewer.state.best, viewer.state.numerical
                        reached += numerical.status == "ok" if best is None else best.status != "unreachable"
                    if listener is not None:
                        frames = listener.frames
                        mb = sum(f.size for f in frames) / 1e6
                        d = np.array(delivered)
                        seen += (f"; pose → the update's last message at the client: median {np.median(d) * 1e3:.1f}"
                                 f" ms, worst {d.max() * 1e3:.1f} ms, {int(np.sum(d <= BUDGET))}/{len(d)} ≤ "
                                 f"{BUDGET * 1e3:.0f} ms ({len(frames)} frames, {mb:.1f} MB received)")  # fmt: skip
                t, cpu = np.array(viewer.latencies), np.array(viewer.cpu_times)
            p95 = float(np.percentile(t, 95))
            within = int(np.sum(t <= BUDGET))
            what = (
                "numerical IK"
                if not robot.branch_functions
                else f"{len(viewer.state.branches)} branches, feasible sets, solve_best {viewer.state.best.method}"
            )
            rows.append(
                Row(
                    f"{label}: pose → scene",
                    float(np.median(t)),
                    p99=float(np.percentile(t, 99)),
                    worst=float(t.max()),
                    note=f"p95 {p95 * 1e3:.1f} ms; {within}/{len(t)} ≤ {BUDGET * 1e3:.0f} ms; CPU of the update "
                    f"median {np.median(cpu) * 1e3:.1f} ms, worst {cpu.max() * 1e3:.1f} ms (the drawing thread; the "
                    f"server's process, every thread: median {np.median(process) * 1e3:.1f} ms, worst "
                    f"{max(process) * 1e3:.1f} ms); {reached}/{len(t)} poses reached; {what}; {seen}",
                )
            )
    return rows


@contextlib.contextmanager
def _client(kind: str, chromium, why: str, viewer):
    """The client of ``viewer`` while it is dragged (module docstring): yields the
    :class:`~qpik.viewer.listener.Listener` (None with the browser or without a client) and the note's words on
    the client; ``chromium``: the browser of ``--client browser`` (None: it did not start, ``why``)."""
    from qpik.viewer import ViewerError
    from qpik.viewer.browser import lower_priority, open_page
    from qpik.viewer.listener import Listener

    if kind == "socket":
        try:
            listener = Listener(viewer)
        except ViewerError as exc:
            yield None, f"no client ({exc})"
            return
        with listener:
            yield (
                listener,
                "a websocket client in another process, receiving and decoding every message, drawing nothing",
            )
        return
    if chromium is None:
        yield None, f"no page ({why})"
        return
    page = open_page(chromium, viewer, PAGE)
    priority = "at the lowest CPU priority" if lower_priority() else "its priority not lowered"
    try:
        yield None, f"a page open in headless Chromium ({priority}), the poses at once"
    finally:
        page.close()
