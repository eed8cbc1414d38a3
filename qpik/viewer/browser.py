"""The viewer's page in a headless browser: Chromium (Debian's ``chromium`` package) driven by Playwright.

Nothing is downloaded: the browser is the one installed on the machine (``QPIK_BROWSER`` names its
executable, else ``chromium``, ``chromium-browser``, ``google-chrome`` on the ``PATH``), started
without a sandbox, GPU or network services; WebGL runs on SwiftShader, Chromium's software renderer.
"""

from __future__ import annotations

import os
import shutil
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from qpik.core.errors import InputError, ViewerError

EXECUTABLES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
ARGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
)  # fmt: skip
HIDE_NOTICES = ".mantine-Notifications-root { display: none !important; }"
"""CSS: viser's notices (such as 'Software WebGL rendering detected') are not part of a picture."""
CONNECT_TIMEOUT = 30.0  # s: the page's websocket connects to the server
SETTLE_TIMEOUT = 20.0  # s: the page stops changing
SETTLE_INTERVAL = 0.4  # s between two pictures compared
_local = threading.local()  # .open: the browsers of this thread's enclosing browser() contexts


class Page(Protocol):
    """What the browser reads of a :class:`~qpik.viewer.server.Viewer`: its address and its viser server."""

    url: str
    server: Any


def find_browser() -> str:
    """The Chromium executable to use; :class:`ViewerError` (one line, what to install) when there is none."""
    named = os.environ.get("QPIK_BROWSER")
    if named:
        found = shutil.which(named)
        if found is None:
            raise ViewerError(f"no headless browser: QPIK_BROWSER={named} is not an executable")
        return found
    for name in EXECUTABLES:
        found = shutil.which(name)
        if found is not None:
            return found
    raise ViewerError("no headless browser: install Chromium (Debian: apt-get install chromium) or set QPIK_BROWSER")


@contextmanager
def browser() -> Iterator[object]:
    """A headless Chromium (a Playwright ``Browser``), closed on exit.

    Raises:
        ViewerError: Playwright is not installed, no browser is found, or it does not start (one line each).
    """
    opened = getattr(_local, "open", None)
    if opened is None:
        opened = _local.open = []
    if opened:  # Playwright's sync API runs one instance per thread: share the open one
        yield opened[-1]
        return
    executable = find_browser()
    try:
        from playwright.sync_api import Error, sync_playwright
    except ImportError:
        raise ViewerError("no headless browser: playwright is not installed: pip install 'qpik[view]'") from None
    with sync_playwright() as pw:
        try:
            chromium = pw.chromium.launch(executable_path=executable, args=list(ARGS))
        except Error as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise ViewerError(f"no headless browser: {executable} did not start ({first})") from None
        opened.append(chromium)
        try:
            yield chromium
        finally:
            opened.pop()
            chromium.close()


def lower_priority(niceness: int = 19) -> int:
    """Lower the CPU priority of every process this one started (the browser's, whose software-GL redraw of an
    open page takes most of a core) to ``niceness``, so that a server on the same machine keeps the CPU when it
    needs it, as it would with the page on another machine. Linux only (``/proc``); returns how many processes
    were lowered (0 elsewhere)."""
    children: dict[int, list[int]] = {}
    proc = Path("/proc")
    if not proc.is_dir():
        return 0
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):  # gone meanwhile
            continue
        children.setdefault(parent, []).append(int(entry.name))
    lowered, todo = 0, list(children.get(os.getpid(), []))
    while todo:
        pid = todo.pop()
        todo += children.get(pid, [])
        try:  # Linux keeps a niceness per thread: every thread of the process
            threads = [int(t.name) for t in (proc / str(pid) / "task").iterdir()]
            for tid in threads:
                os.setpriority(os.PRIO_PROCESS, tid, max(os.getpriority(os.PRIO_PROCESS, tid), niceness))
            lowered += 1
        except OSError:  # gone meanwhile, or not ours
            continue
    return lowered


def open_page(chromium, viewer: Page, size: tuple[int, int], messages: list | None = None):
    """A page of ``viewer`` in ``chromium``, connected and with its scene drawn; console messages and page errors
    are appended to ``messages`` as ``(type, text)``."""
    page = _connected_page(chromium, viewer, size, messages)
    settle(page)
    return page


def _connected_page(chromium, viewer: Page, size: tuple[int, int], messages: list | None = None):
    """A page of ``viewer`` in ``chromium`` (``size``: width, height px) once its websocket is connected, its scene
    perhaps not yet drawn; ``messages`` as in :func:`open_page`."""
    known = set(viewer.server.get_clients())
    page = chromium.new_page(viewport={"width": int(size[0]), "height": int(size[1])})
    if messages is not None:
        page.on("console", lambda m: messages.append((m.type, m.text)))
        page.on("pageerror", lambda e: messages.append(("pageerror", str(e))))
    page.goto(viewer.url)
    page.add_style_tag(content=HIDE_NOTICES)
    deadline = time.monotonic() + CONNECT_TIMEOUT
    while not set(viewer.server.get_clients()) - known:
        if time.monotonic() > deadline:
            page.close()
            raise ViewerError(f"the page at {viewer.url} did not connect within {CONNECT_TIMEOUT:g} s")
        time.sleep(0.05)
    return page


def settle(page) -> np.ndarray:
    """Wait until two pictures of the page :data:`SETTLE_INTERVAL` apart are the same (or :data:`SETTLE_TIMEOUT`);
    returns the last one (H, W, 3) uint8."""
    last = _picture(page)
    deadline = time.monotonic() + SETTLE_TIMEOUT
    while time.monotonic() < deadline:
        time.sleep(SETTLE_INTERVAL)
        now = _picture(page)
        if now.shape == last.shape and np.array_equal(now, last):
            return now
        last = now
    return last


def _picture(page) -> np.ndarray:
    import io

    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))


def screenshot(viewer: Page, path: str | os.PathLike, size: tuple[int, int] = (1280, 800)) -> np.ndarray:
    """Write a PNG of ``viewer``'s page at ``size`` (width, height) px to ``path``; returns the picture (H, W, 3).

    Raises:
        InputError: ``path`` does not end in ``.png`` or ``size`` is not two whole numbers ≥ 64.
        ViewerError: no headless browser.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise InputError(f"screenshot: the picture is written as PNG, so the file name must end in .png, got {path}")
    if len(size) != 2 or any(int(s) != s or s < 64 for s in size):
        raise InputError(f"size: expected (width, height), whole pixels >= 64, got {tuple(size)}")
    with browser() as chromium:
        page = _connected_page(chromium, viewer, size)
        picture = settle(page)
        page.close()
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(picture).save(path)
    return picture
