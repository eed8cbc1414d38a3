"""A client of the viewer that receives without rendering: viser's websocket, every message decoded, nothing drawn.

:class:`Listener` connects to a :class:`~qpik.viewer.server.Viewer` as viser's page does (a websocket at the
server's address, subprotocol ``viser-v<viser's version>``, which the server checks; then one camera message
(:data:`CAMERA`), as the page sends once it has drawn: viser counts a client from its first camera, and needs
nothing else from it, sending the scene and then every update) from a process of its own
(``python -m qpik.viewer.listener URL``), so that the server's messages are serialised, compressed and sent as they
are to a page, and the client's work (receiving and decoding) runs beside the server's process, not in it. The
process writes one JSON line per websocket frame it receives (:func:`decode`: viser's frame of messages) to
its standard output, which a thread of the server's process reads into :attr:`Listener.frames`;
:meth:`Listener.sync` queues a mark (a hidden scene node moved, :data:`MARK`) after the messages queued so far and
waits until the client has it.

Times are :func:`time.perf_counter` seconds: on Linux the machine's monotonic clock, the same in both processes.
"""

from __future__ import annotations

import collections
import json
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from qpik.core.errors import ViewerError

CONNECT_TIMEOUT = 30.0
"""s: the client's process starts and its websocket connects."""
RECEIVE_TIMEOUT = 10.0
"""s: a mark (:meth:`Listener.sync`) reaches the client."""
POLL = 0.5
"""s: the client's longest wait for a frame before it checks that the process that started it still runs."""
CAMERA = {
    "type": "ViewerCameraMessage", "wxyz": (1.0, 0.0, 0.0, 0.0), "position": (1.5, -1.5, 1.0), "fov": 0.9,
    "near": 0.01, "far": 100.0, "image_height": 800, "image_width": 1280, "look_at": (0.0, 0.0, 0.5),
    "up_direction": (0.0, 0.0, 1.0),
}  # fmt: skip
"""The client's camera (viser's ``ViewerCameraMessage``: pose, field of view rad, clip distances m, picture px):
nothing is drawn with it."""
MARK = "/qpik-listener-mark"
"""The hidden scene node whose position :meth:`Listener.sync` sets (a frame without axes, never drawn)."""


@dataclass(frozen=True)
class Frame:
    """One websocket frame the client received.

    Attributes:
        arrived: s, :func:`time.perf_counter` when the client had it.
        size: bytes on the wire.
        types: messages per viser message type (``"SetPositionMessage"``, ``"GuiUpdateMessage"``, …).
        mark: the count of the latest mark (:meth:`Listener.sync`) in the frame, or None.
    """

    arrived: float
    size: int
    types: dict[str, int]
    mark: int | None


def decode(frame: bytes) -> list[dict[str, Any]]:
    """viser's websocket frame → its messages as dicts, each with its ``"type"``.

    The layout (viser's ``_message_producer``): the msgpack payload's size (8 bytes, little-endian), its
    zstd-compressed size (8 bytes), the compressed msgpack of ``{"messages", "timestampSec", "binaryBufferLengths"}``
    (numpy arrays replaced by ``{"__binary_index", "dtype"}`` placeholders), then the arrays' bytes, which are
    not read here.

    Raises:
        ViewerError: the frame is shorter than its header says, or its payload does not decode.
    """
    import msgspec
    import zstandard

    if len(frame) < 16:
        raise ViewerError(f"a viser frame holds at least 16 bytes of header, got {len(frame)}")
    size, packed = int.from_bytes(frame[:8], "little"), int.from_bytes(frame[8:16], "little")
    if 16 + packed > len(frame):
        raise ViewerError(f"a viser frame of {len(frame)} bytes says its payload has {packed}")
    try:
        body = msgspec.msgpack.decode(zstandard.ZstdDecompressor().decompress(frame[16 : 16 + packed], size))
    except (msgspec.DecodeError, zstandard.ZstdError) as exc:
        raise ViewerError(f"a viser frame does not decode: {exc}") from None
    return list(body["messages"])


def _mark_of(messages: list[dict[str, Any]]) -> int | None:
    """The count carried by the last position of :data:`MARK` among ``messages``, or None."""
    found = None
    for message in messages:
        if message["type"] == "SetPositionMessage" and message.get("name") == MARK:
            found = round(message["position"][0])
    return found


def listen(url: str, out=sys.stdout) -> None:
    """The client's process: connect to the viewer at ``url`` (``http://HOST:PORT``), then write ``{"connected":
    time}`` and, per frame received, its :class:`Frame` fields, as JSON lines to ``out``; return when the server
    closes the connection or the parent process ends."""
    import msgspec
    import viser
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    parent = os.getppid()
    address = "ws" + url.removeprefix("http")
    with connect(address, subprotocols=[f"viser-v{viser.__version__}"], open_timeout=CONNECT_TIMEOUT, proxy=None,
                 compression=None, max_size=None) as socket:  # fmt: skip
        socket.send(msgspec.msgpack.encode(CAMERA))
        out.write(json.dumps({"connected": time.perf_counter()}) + "\n")
        out.flush()
        while os.getppid() == parent:
            try:
                data = socket.recv(timeout=POLL)
            except TimeoutError:
                continue
            except ConnectionClosed:
                return
            arrived = time.perf_counter()
            messages = decode(data)
            types = collections.Counter(message["type"] for message in messages)
            line = {"arrived": arrived, "size": len(data), "types": types, "mark": _mark_of(messages)}
            out.write(json.dumps(line) + "\n")
            out.flush()


class Listener:
    """A client process receiving everything a viewer's server sends (module docstring); a context manager.

    Args:
        viewer: a :class:`~qpik.viewer.server.Viewer` (its ``url`` and viser ``server``).

    Attributes:
        frames: every frame received so far (:class:`Frame`), in order.

    Raises:
        ViewerError: the client did not connect within :data:`CONNECT_TIMEOUT` (with what it printed).
    """

    def __init__(self, viewer):
        self._server = viewer.server
        self.frames: list[Frame] = []
        self._changed = threading.Condition()
        self._count = 0
        self._connected: float | None = None  # when the client said it connected
        self._marker = self._server.scene.add_frame(MARK, show_axes=False, visible=False)
        known = set(self._server.get_clients())
        root = str(Path(__file__).resolve().parents[2])  # the qpik the server runs
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)}
        self._process = subprocess.Popen(
            [sys.executable, "-m", "qpik.viewer.listener", viewer.url], stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )  # fmt: skip
        self._reader = threading.Thread(target=self._read, name="qpik-listener", daemon=True)
        self._reader.start()
        deadline = time.monotonic() + CONNECT_TIMEOUT
        with self._changed:
            self._changed.wait_for(lambda: self._connected is not None or self._process.poll() is not None,
                                   timeout=CONNECT_TIMEOUT)  # fmt: skip
        while self._connected is not None and not set(self._server.get_clients()) - known:
            if time.monotonic() > deadline:
                break
            time.sleep(0.01)
        if self._connected is None or not set(self._server.get_clients()) - known:
            ended = self._process.poll() is not None
            why = self._stop()
            self._marker.remove()
            what = "ended" if ended else f"did not connect within {CONNECT_TIMEOUT:g} s"
            raise ViewerError(f"the websocket client of {viewer.url} {what}{': ' + why if why else ''}")

    def _read(self) -> None:
        for line in self._process.stdout:
            item = json.loads(line)
            with self._changed:
                if "connected" in item:
                    self._connected = item["connected"]
                else:
                    self.frames.append(Frame(**item))
                self._changed.notify_all()
        with self._changed:
            self._changed.notify_all()

    def sync(self, timeout: float = RECEIVE_TIMEOUT) -> float:
        """Queue a mark after every message the server has queued so far, flush, and wait until the client has it;
        returns when it arrived (:func:`time.perf_counter` s): by then the client had every one of those messages
        (a server sends its messages in order).

        Raises:
            ViewerError: the mark did not arrive within ``timeout`` s, or the client's process ended.
        """
        self._count += 1
        count = self._count
        self._marker.position = (float(count), 0.0, 0.0)
        self._server.flush()
        with self._changed:
            arrived = self._changed.wait_for(
                lambda: next((f.arrived for f in reversed(self.frames) if f.mark is not None and f.mark >= count),
                             None) or self._process.poll() is not None, timeout=timeout)  # fmt: skip
        if not isinstance(arrived, float):
            ended = self._process.poll() is not None
            raise ViewerError(f"the websocket client {'ended' if ended else 'received nothing'}: mark {count} did not"
                              f" arrive within {timeout:g} s")  # fmt: skip
        return arrived

    def _stop(self) -> str:
        """End the client's process; returns the last line it wrote to its standard error."""
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait(timeout=5.0)
        self._reader.join(timeout=5.0)
        lines = self._process.stderr.read().strip().splitlines() if self._process.stderr else []
        return lines[-1] if lines else ""

    def close(self) -> None:
        """End the client's process and take the hidden mark off the scene."""
        self._stop()
        self._marker.remove()

    def __enter__(self) -> Listener:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


if __name__ == "__main__":
    listen(sys.argv[1])
