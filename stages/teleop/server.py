"""The teleop web server (aiohttp): the page, its scripts, and one operator's WebSocket.

- Binds 127.0.0.1 by default (``host``); ``ssl_context`` serves HTTPS/WSS (a LAN headset needs
  a secure context for WebXR).
- A random access token (``secrets.token_urlsafe``) is part of the printed URL; every request
  without it (query ``token``) is answered 401, compared in constant time. Responses carry
  ``Cache-Control: no-store``, ``Referrer-Policy: no-referrer`` and a same-origin content policy.
- One operator at a time: a second WebSocket is refused (409) while one is open. A WebSocket from
  another origin is refused (403). When the operator leaves, the controls fall back to zero.
- Messages are untrusted (:mod:`stages.teleop.protocol`): each is rate limited, validated, and
  dropped with a logged reason (at most one log line per reason kind per second) when bad; nothing
  a client sends reaches the simulation unchecked.
- Frames: the session's frame listener hands each captured frame to the event loop; a sender task
  JPEG-encodes the newest one (older unsent frames are skipped) in a worker thread and sends one
  binary message per frame: ``b"AWF1"``, frame id (uint32, little-endian), camera count (uint8),
  then per camera: name length (uint8), name (ASCII), JPEG length (uint32), JPEG bytes. The page
  acknowledges each frame it has drawn (``{"type": "ack"}``). A status message (JSON, the
  session's :meth:`~stages.teleop.session.TeleopSession.status` plus the server's counters) goes
  out every 0.25 s.
"""

from __future__ import annotations

import asyncio
import hmac
import io
import json
import logging
import secrets
import struct
import time
from importlib import resources
from pathlib import Path

from stages.teleop.protocol import OperatorCommand, ProtocolError, RateLimiter, parse_message

log = logging.getLogger(__name__)

PAGE_FILES = {"teleop.js": "text/javascript", "teleop.css": "text/css", "index.html": "text/html"}
VENDOR_DIR = "vendor"  # page/vendor/: JavaScript built from the npm registry at install time (IWER)
CSP = ("default-src 'self'; img-src 'self' blob: data:; connect-src 'self' ws: wss:; "
       "script-src 'self'; style-src 'self'; frame-ancestors 'none'")


def page_file(name: str) -> bytes:
    """A file of the page (``stages/teleop/page``), from the installed package."""
    return resources.files("stages.teleop").joinpath("page", name).read_bytes()


def encode_frame(frame_id: int, rgb: dict, quality: int) -> bytes:
    """The binary frame message (see the module docstring) of ``rgb`` {camera: (H, W, 3) uint8}."""
    from PIL import Image

    parts = [b"AWF1", struct.pack("<IB", frame_id & 0xFFFFFFFF, len(rgb))]
    for name, im in rgb.items():
        buf = io.BytesIO()
        Image.fromarray(im).save(buf, "JPEG", quality=quality)
        jpg, nm = buf.getvalue(), name.encode("ascii")
        parts += [struct.pack("<B", len(nm)), nm, struct.pack("<I", len(jpg)), jpg]
    return b"".join(parts)


class _Throttled:
    """Logs a message kind at most once per ``period`` [s], with the count of the ones skipped."""

    def __init__(self, period: float = 1.0) -> None:
        self.period, self._last, self._skipped = period, {}, {}

    def warn(self, kind: str, text: str) -> None:
        t = time.monotonic()
        if t - self._last.get(kind, -1e9) >= self.period:
            n = self._skipped.pop(kind, 0)
            log.warning("teleop: %s%s", text, f" (+{n} more)" if n else "")
            self._last[kind] = t
        else:
            self._skipped[kind] = self._skipped.get(kind, 0) + 1


class TeleopServer:
    """Serves ``session`` (a :class:`~stages.teleop.session.TeleopSession`) to one operator.
    host, port: where to listen (port 0: any free port); token: the access token (None: random);
    rate, burst: message rate limit [1/s] and burst; ssl_context: HTTPS (None: HTTP)."""

    def __init__(self, session, *, host: str = "127.0.0.1", port: int = 0, token: str | None = None,
                 rate: float = 120.0, burst: int = 60, ssl_context=None) -> None:
        self.session, self.host, self.port = session, host, port
        self.token = token or secrets.token_urlsafe(24)
        self.rate, self.burst, self.ssl_context = rate, burst, ssl_context
        self.stats = {"rejected": 0, "rate_limited": 0, "unauthorized": 0, "frames_sent": 0, "frames_skipped": 0}
        self.rejections: list[str] = []  # the last reasons, for tests and the status bar
        self._operator = None
        self._runner = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._frame: tuple | None = None
        self._frame_ready: asyncio.Event | None = None
        self._warn = _Throttled()

    @property
    def url(self) -> str:
        scheme = "https" if self.ssl_context else "http"
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host
        return f"{scheme}://{host}:{self.port}/?token={self.token}"

    # -- lifecycle ------------------------------------------------------------------------------
    async def start(self) -> str:
        """Listen; returns the operator's URL (with the token)."""
        from aiohttp import web

        self._loop = asyncio.get_running_loop()
        self._frame_ready = asyncio.Event()
        app = web.Application(middlewares=[self._guard], client_max_size=64 * 1024)
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._ws)
        app.router.add_get("/static/{name}", self._static)
        app.router.add_get("/static/vendor/{name}", self._vendor)
        self._runner = web.AppRunner(app, access_log=None)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port, ssl_context=self.ssl_context)
        await site.start()
        self.port = site._server.sockets[0].getsockname()[1]
        self.session.listeners.append(self._on_frame)
        return self.url

    async def stop(self) -> None:
        if self._on_frame in self.session.listeners:
            self.session.listeners.remove(self._on_frame)
        if self._operator is not None:
            await self._operator.close()
        if self._runner is not None:
            await self._runner.cleanup()

    # -- HTTP -----------------------------------------------------------------------------------
    def _authorized(self, request) -> bool:
        got = request.query.get("token", "")
        return hmac.compare_digest(got.encode("utf-8", "replace"), self.token.encode())

    async def _guard(self, app, handler):
        from aiohttp import web

        async def middleware(request):
            if not self._authorized(request):
                self.stats["unauthorized"] += 1
                self._warn.warn("401", f"refused {request.method} {request.path} from {request.remote}: no valid token")
                return web.Response(status=401, text="401: a valid access token is required\n")
            try:
                resp = await handler(request)
            except web.HTTPException as e:
                resp = e
            if not isinstance(resp, web.WebSocketResponse):
                resp.headers["Cache-Control"] = "no-store"
                resp.headers["Referrer-Policy"] = "no-referrer"
                resp.headers["X-Content-Type-Options"] = "nosniff"
                resp.headers["Content-Security-Policy"] = CSP
            return resp

        return middleware

    async def _index(self, request):
        from aiohttp import web

        html = page_file("index.html").decode("utf-8").replace("{{TOKEN}}", self.token)
        return web.Response(body=html.encode("utf-8"), content_type="text/html")

    async def _static(self, request):
        from aiohttp import web

        name = request.match_info["name"]
        if name not in PAGE_FILES or name == "index.html":
            raise web.HTTPNotFound()
        return web.Response(body=page_file(name), content_type=PAGE_FILES[name])

    async def _vendor(self, request):
        from aiohttp import web

        name = request.match_info["name"]
        root = resources.files("stages.teleop").joinpath("page", VENDOR_DIR)
        if not name.endswith(".js") or "/" in name or name.startswith(".") or not root.joinpath(name).is_file():
            raise web.HTTPNotFound()
        return web.Response(body=root.joinpath(name).read_bytes(), content_type="text/javascript")

    # -- the operator's WebSocket ---------------------------------------------------------------
    async def _ws(self, request):
        from aiohttp import WSMsgType, web

        origin = request.headers.get("Origin")
        if origin is not None and origin.split("://", 1)[-1] != request.host:
            self._warn.warn("origin", f"refused a WebSocket from origin {origin[:80]!r}")
            return web.Response(status=403, text="403: cross-origin WebSocket\n")
        if self._operator is not None:
            self._warn.warn("busy", "refused a second operator (one at a time)")
            return web.Response(status=409, text="409: another operator is connected\n")
        ws = web.WebSocketResponse(max_msg_size=1 << 20, heartbeat=10.0, compress=False)
        await ws.prepare(request)
        self._operator = ws
        log.info("teleop: operator connected from %s", request.remote)
        limiter = RateLimiter(self.rate, self.burst)
        sender = asyncio.create_task(self._send_frames(ws))
        status = asyncio.create_task(self._send_status(ws))
        try:
            async for msg in ws:
                if msg.type == WSMsgType.TEXT:
                    self._handle(msg.data, limiter)
                elif msg.type == WSMsgType.BINARY:
                    self._reject("binary", "binary messages are not accepted")
                elif msg.type == WSMsgType.ERROR:
                    self._reject("ws", f"WebSocket error {ws.exception()!r}")
        finally:
            sender.cancel()
            status.cancel()
            self._operator = None
            # the operator is gone: controls to zero (mode and gripper kept), no XR poses
            self.session.xr = None
            last = self.session.current_command()
            self.session.submit(OperatorCommand(seq=last.seq + 1, mode=last.mode, gripper=last.gripper,
                                                received=time.perf_counter()))
            log.info("teleop: operator disconnected")
        return ws

    def _reject(self, kind: str, reason: str) -> None:
        self.stats["rejected"] += 1
        self.rejections = [*self.rejections[-19:], reason]
        self._warn.warn(kind, f"rejected a message: {reason}")

    def _handle(self, data: str, limiter: RateLimiter) -> None:
        if not limiter.allow():
            self.stats["rate_limited"] += 1
            self._warn.warn("rate", f"rate limit ({self.rate:g} messages/s) exceeded; message dropped")
            return
        try:
            msg = parse_message(data)
        except ProtocolError as e:
            self._reject("protocol", str(e))
            return
        self.session.submit(msg)

    def _on_frame(self, frame_id: int, t: float, rgb: dict) -> None:
        """Frame listener (the session's thread): hand the newest frame to the event loop."""
        loop = self._loop
        if loop is None or self._operator is None or loop.is_closed():
            return
        loop.call_soon_threadsafe(self._set_frame, (frame_id, t, rgb))

    def _set_frame(self, frame) -> None:
        if self._frame is not None:
            self.stats["frames_skipped"] += 1
        self._frame = frame
        self._frame_ready.set()

    async def _send_frames(self, ws) -> None:
        loop = asyncio.get_running_loop()
        quality = self.session.cfg.jpeg_quality
        while not ws.closed:
            await self._frame_ready.wait()
            self._frame_ready.clear()
            frame, self._frame = self._frame, None
            if frame is None:
                continue
            data = await loop.run_in_executor(None, encode_frame, frame[0], frame[2], quality)
            if ws.closed:
                return
            await ws.send_bytes(data)
            self.stats["frames_sent"] += 1

    async def _send_status(self, ws) -> None:
        while not ws.closed:
            st = self.session.status() | {"server": dict(self.stats),
                                          "last_rejection": self.rejections[-1] if self.rejections else ""}
            await ws.send_str(json.dumps(st))
            await asyncio.sleep(0.25)


async def serve(session, *, host: str = "127.0.0.1", port: int = 0, ssl_context=None,
                on_url=None, stop_when_done: bool = True) -> None:
    """Run ``session`` (started here, in its thread) behind a :class:`TeleopServer` until the
    session ends or the task is cancelled (Ctrl-C); ``on_url(url)`` is called once listening."""
    server = TeleopServer(session, host=host, port=port, ssl_context=ssl_context)
    url = await server.start()
    if on_url is not None:
        on_url(url)
    session.start()
    try:
        while session.running:
            await asyncio.sleep(0.2)
    finally:
        session.stop()
        await asyncio.get_running_loop().run_in_executor(None, session.join, 60.0)
        await server.stop()


def self_signed_context(cert_dir: Path, host: str):
    """An SSL context with a self-signed certificate for ``host`` (made with ``openssl`` into
    ``cert_dir`` once, reused after)."""
    import ssl
    import subprocess

    cert_dir.mkdir(parents=True, exist_ok=True)
    crt, key = cert_dir / "teleop.crt", cert_dir / "teleop.key"
    if not (crt.is_file() and key.is_file()):
        subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "30",
                        "-subj", f"/CN={host}", "-addext", f"subjectAltName=IP:{host}" if host[0].isdigit()
                        else f"subjectAltName=DNS:{host}", "-keyout", str(key), "-out", str(crt)],
                       check=True, capture_output=True)
        key.chmod(0o600)
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    ctx.load_cert_chain(crt, key)
    return ctx
