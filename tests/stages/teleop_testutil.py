"""Helpers of the teleop tests: the kitchen fixture's builder, a server on its own event loop."""

from __future__ import annotations

import asyncio
import threading
import time


class ServerThread:
    """A :class:`~stages.teleop.server.TeleopServer` of ``session`` on an event loop in a thread."""

    def __init__(self, session, **kwargs) -> None:
        from stages.teleop.server import TeleopServer

        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name="teleop-test-server", daemon=True)
        self.thread.start()
        self.server = TeleopServer(session, **kwargs)
        self.url = self.call(self.server.start())
        self.base = self.url.split("?", 1)[0]

    def call(self, coro, timeout: float = 30.0):
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def close(self) -> None:
        self.call(self.server.stop())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(10)


def wait_for(pred, timeout: float = 180.0, what: str = "condition") -> None:
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout:
            raise TimeoutError(f"teleop test: {what} not met within {timeout} s")
        time.sleep(0.02)


def chromium() -> str:
    """The OS's Chromium, or a skip with the reason (``.ci/run`` installs it with apt)."""
    import shutil

    import pytest

    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no Chromium from the OS packages (.ci/run installs it: apt-get install chromium)")
