"""A browser-free operator: the page's protocol (``page/teleop.js``) spoken from Python.

For measuring the teleop loop where there is no browser (the GPU host): the client loads the page
and its scripts with the token as a browser does, opens the operator's WebSocket (with the page's
``Origin``), and then does what the page does:

- on open, and again every 0.1 s (the page's repeat period), it sends the controls held now
  (``{"type": "cmd", "seq", "base", "jog", "mode", "gripper"}``), built from held key codes with
  the page's mapping (locomotion: W/S, A/D, Q/E -> base; manipulation: W/S, A/D, R/F, J/L, I/K,
  Q/E -> jog); a key going down or up, a mode switch (M) or a gripper toggle (G) sends at once;
- episode controls: ``{"type": "episode", "action": "start"|"save"|"discard"}``;
- each binary frame (``AWF1``: :func:`parse_frame`) is decoded (every camera's JPEG, with Pillow,
  where the page decodes its ``<img>``) and then acknowledged (``{"type": "ack", "frame": n}``);
  ``fps`` is the frames shown in the last 2 s per second, as the page's status bar counts them;
- status messages (JSON) are kept as ``status``.

The client runs its own event loop in a thread, so that a plain (synchronous) benchmark drives it
like Playwright drives the page::

    with TeleopClient(url) as c:          # url: the server's, with ?token=...
        c.wait(lambda: c.frames > 2)
        c.episode("start"); c.key_down("KeyW"); time.sleep(1); c.key_up("KeyW"); c.episode("save")
"""

from __future__ import annotations

import asyncio
import collections
import io
import json
import struct
import threading
import time
from urllib.parse import parse_qs, urlsplit

REPEAT_SECONDS = 0.1  # the page's control repeat period [s] (teleop.js: setInterval(..., 100))
FPS_WINDOW = 2.0  # the page's display-fps window [s]
BASE_KEYS = (("KeyW", "KeyS"), ("KeyA", "KeyD"), ("KeyQ", "KeyE"))
JOG_KEYS = (("KeyW", "KeyS"), ("KeyA", "KeyD"), ("KeyR", "KeyF"), ("KeyJ", "KeyL"), ("KeyI", "KeyK"),
            ("KeyQ", "KeyE"))
CONTROL_KEYS = frozenset(k for pair in BASE_KEYS + JOG_KEYS for k in pair)


class FrameError(ValueError):
    """A binary message that is not a well-formed ``AWF1`` frame."""


def parse_frame(buf: bytes) -> tuple[int, dict[str, bytes]]:
    """An ``AWF1`` frame message (:mod:`stages.teleop.server`) -> (frame id, {camera: JPEG bytes})."""
    if buf[:4] != b"AWF1" or len(buf) < 9:
        raise FrameError(f"teleop client: not an AWF1 frame ({bytes(buf[:4])!r}, {len(buf)} bytes)")
    frame, count = struct.unpack_from("<IB", buf, 4)
    off, out = 9, {}
    for _ in range(count):
        n = buf[off]
        name = bytes(buf[off + 1:off + 1 + n]).decode("ascii")
        (length,) = struct.unpack_from("<I", buf, off + 1 + n)
        off += 5 + n
        if off + length > len(buf):
            raise FrameError(f"teleop client: frame {frame}: camera {name!r} JPEG runs past the message")
        out[name] = bytes(buf[off:off + length])
        off += length
    return frame, out


class TeleopClient:
    """One operator connected to a teleop server at ``url`` (the printed URL with its token).
    ``decode``: decode each camera's JPEG before acknowledging the frame (as the page does; False
    acknowledges on arrival). Counters: ``frames`` (shown), ``fps``, ``bytes``, ``last_images``
    (the newest decoded frame: {camera: (H, W, 3) uint8}, with ``decode``), ``status`` (the newest
    status message), ``errors`` (what went wrong in the client's loop)."""

    def __init__(self, url: str, *, decode: bool = True, timeout: float = 30.0) -> None:
        parts = urlsplit(url)
        self.origin = f"{parts.scheme}://{parts.netloc}"
        self.token = parse_qs(parts.query).get("token", [""])[0]
        self.base = self.origin + "/"
        self.decode, self.timeout = decode, timeout
        self.mode = self.gripper = self.seq = 0
        self.frames = 0
        self.bytes = 0
        self.fps = 0.0
        self.status: dict | None = None
        self.last_images: dict | None = None
        self.connected = False
        self.errors: list[str] = []
        self._held: set[str] = set()
        self._shown: collections.deque[float] = collections.deque()
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="teleop-client", daemon=True)
        self._ws = self._http = None
        self._tasks: list[asyncio.Task] = []

    # -- lifecycle (the caller's thread) --------------------------------------------------------
    def connect(self) -> TeleopClient:
        """Load the page (index, script, style) and open the operator's WebSocket."""
        self._thread.start()
        self._call(self._connect())
        return self

    def close(self) -> None:
        if self._thread.is_alive():
            self._call(self._close())
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10)

    def __enter__(self) -> TeleopClient:
        return self.connect()

    def __exit__(self, *exc) -> None:
        self.close()

    def wait(self, pred, timeout: float = 180.0, what: str = "condition") -> None:
        """Poll ``pred()`` until it is true; TimeoutError (naming ``what``) after ``timeout`` [s]."""
        t0 = time.monotonic()
        while not pred():
            if self.errors:
                raise RuntimeError(f"teleop client: {self.errors[-1]}")
            if time.monotonic() - t0 > timeout:
                raise TimeoutError(f"teleop client: {what} not met within {timeout} s")
            time.sleep(0.02)

    # -- the operator's input (the page's handlers) ---------------------------------------------
    def key_down(self, code: str) -> None:
        """A key goes down (``KeyboardEvent.code``): M switches mode, G toggles the gripper, a
        control key is held (sent at once when it was not held)."""
        if code == "KeyM":
            self.mode = 1 - self.mode
        elif code in ("KeyG", "Space"):
            self.gripper = 1 - self.gripper
        elif code in CONTROL_KEYS and code not in self._held:
            self._held.add(code)
        else:
            return
        self._send_soon(self.command())

    def key_up(self, code: str) -> None:
        if code in self._held:
            self._held.discard(code)
            self._send_soon(self.command())

    def episode(self, action: str, task: str = "") -> None:
        """An episode control (``start``, ``save``, ``discard``; ``task``: a start's instruction)."""
        msg = {"type": "episode", "action": action}
        if action == "start":
            msg["task"] = task.strip()[:200]
        self._send_soon(msg)

    def command(self) -> dict:
        """The controls held now as the page's ``cmd`` message (a new ``seq``)."""
        axis = lambda plus, minus: int(plus in self._held) - int(minus in self._held)  # noqa: E731
        base = [axis(*p) for p in BASE_KEYS] if self.mode == 0 else [0, 0, 0]
        jog = [axis(*p) for p in JOG_KEYS] if self.mode == 1 else [0] * 6
        self.seq += 1
        return {"type": "cmd", "seq": self.seq, "base": base, "jog": jog, "mode": self.mode,
                "gripper": self.gripper}

    # -- the event loop's side ------------------------------------------------------------------
    def _call(self, coro):
        return asyncio.run_coroutine_threadsafe(coro, self._loop).result(self.timeout)

    def _send_soon(self, msg: dict) -> None:
        self._loop.call_soon_threadsafe(self._send, msg)

    def _send(self, msg: dict) -> None:
        ws = self._ws
        if ws is not None and not ws.closed:
            self._tasks.append(asyncio.ensure_future(ws.send_str(json.dumps(msg))))
            self._tasks = [t for t in self._tasks if not t.done()]

    async def _connect(self) -> None:
        import aiohttp

        self._http = aiohttp.ClientSession(timeout=aiohttp.ClientTimeout(total=self.timeout))
        q = {"token": self.token}
        for path in ("", "static/teleop.js", "static/teleop.css"):  # what loading the page fetches
            async with self._http.get(self.base + path, params=q) as r:
                if r.status != 200:
                    raise ConnectionError(f"teleop client: GET /{path} answered {r.status}")
                await r.read()
        self._ws = await self._http.ws_connect(self.base + "ws", params=q, origin=self.origin,
                                               max_msg_size=16 << 20, autoping=True)
        self.connected = True
        self._send(self.command())
        self._tasks = [asyncio.ensure_future(self._receive()), asyncio.ensure_future(self._repeat())]

    async def _close(self) -> None:
        for t in self._tasks:
            t.cancel()
        if self._ws is not None:
            await self._ws.close()
        if self._http is not None:
            await self._http.close()
        self.connected = False

    async def _repeat(self) -> None:
        while not self._ws.closed:
            await asyncio.sleep(REPEAT_SECONDS)
            self._send(self.command())

    async def _receive(self) -> None:
        import aiohttp

        try:
            async for msg in self._ws:
                if msg.type == aiohttp.WSMsgType.TEXT:
                    self.status = json.loads(msg.data)
                elif msg.type == aiohttp.WSMsgType.BINARY:
                    self._on_frame(msg.data)
                elif msg.type == aiohttp.WSMsgType.ERROR:
                    self.errors.append(f"WebSocket error {self._ws.exception()!r}")
        except Exception as e:  # noqa: BLE001 (kept for the caller: wait() raises it)
            self.errors.append(f"receiving failed: {e!r}")
        finally:
            self.connected = False

    def _on_frame(self, data: bytes) -> None:
        frame, jpegs = parse_frame(data)
        self.bytes += len(data)
        if self.decode:
            import numpy as np
            from PIL import Image

            self.last_images = {k: np.asarray(Image.open(io.BytesIO(v)).convert("RGB")) for k, v in jpegs.items()}
        self._send({"type": "ack", "frame": frame})
        self.frames += 1
        now = time.monotonic()
        self._shown.append(now)
        while self._shown and now - self._shown[0] > FPS_WINDOW:
            self._shown.popleft()
        self.fps = len(self._shown) / FPS_WINDOW
