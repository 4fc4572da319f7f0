"""Helpers of the teleop tests: a server on its own event loop, waiting, Chromium, synthetic XRHand joints."""

from __future__ import annotations

import asyncio
import threading
import time

import numpy as np


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


def launch_page(pw):
    """(browser, page, errors) in the OS's Chromium under Playwright ``pw``: a new page whose
    uncaught script errors collect in ``errors``."""
    browser = pw.chromium.launch(executable_path=chromium(), args=["--no-sandbox"])
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    return browser, page, errors


def enter_xr(page, session, what: str = "XR poses at the server") -> None:
    """Click the page's XR button (a user gesture; the emulated headset of ``&emulate=1``) and wait
    until the server holds the right hand's poses."""
    page.click("#btn-xr")
    wait_for(lambda: page.evaluate("() => window.teleopState.xrSent > 5") and session.xr is not None
             and "right" in session.xr.hands, what=what)


def save_episode(page, session, out) -> None:
    """Save the episode from the page and wait until it is merged into ``out/dataset``. A DOM click:
    the emulated headset's canvas covers the page (as a headset's view would)."""
    page.dispatch_event("#btn-save", "click")
    wait_for(lambda: session.status()["saved"] >= 1, what="the saved episode")
    wait_for(lambda: (out / "dataset" / "meta" / "teleop.json").is_file(), what="the merge")


# finger: (knuckle x, knuckle z) in the XR wrist frame of a right hand [m] (-z along the fingers,
# +y out of the back of the hand, thumb toward -x), phalanx lengths [m]
FINGERS = {"index": (-0.022, -0.090, (0.045, 0.026, 0.022)), "middle": (0.0, -0.092, (0.048, 0.029, 0.023)),
           "ring": (0.019, -0.088, (0.044, 0.027, 0.022)), "little": (0.036, -0.080, (0.036, 0.020, 0.020))}


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def synthetic_hand(flex: float, *, thumb_flex: float | None = None, wrist: np.ndarray | None = None,
                   side: str = "right") -> np.ndarray:
    """XRHand joint poses (25, 4, 4) [m]: each finger's three joints flexed by ``flex`` [rad]
    toward the palm (-y), the thumb by ``thumb_flex`` (default ``flex``), the wrist at ``wrist``
    (4, 4; identity by default); ``side`` "left" mirrors the hand (x -> -x)."""
    tf = flex if thumb_flex is None else thumb_flex
    local = np.zeros((25, 3))
    # thumb: metacarpal base near the wrist, then along (-0.55, -0.25, -0.8), curling about z and x
    d = np.array([-0.55, -0.25, -0.8]) / np.linalg.norm([-0.55, -0.25, -0.8])
    p = np.array([-0.02, -0.01, -0.03])
    local[1] = p
    for k, length in enumerate((0.04, 0.032, 0.028), start=2):
        bend = tf * (0.5 if k == 2 else 1.0)
        r = _rot_x(-bend) @ np.array([[np.cos(bend), -np.sin(bend), 0], [np.sin(bend), np.cos(bend), 0], [0, 0, 1]]).T
        d = r @ d
        d /= np.linalg.norm(d)
        p = p + length * d
        local[k] = p
    for f, (x, z, lengths) in enumerate(FINGERS.values()):
        i0 = 5 + 5 * f
        local[i0] = (x * 0.5, 0.0, -0.03)  # metacarpal
        p, ang = np.array([x, 0.0, z]), 0.0
        local[i0 + 1] = p
        for k, length in enumerate(lengths):
            ang += flex
            p = p + length * (_rot_x(-ang) @ np.array([0.0, 0.0, -1.0]))
            local[i0 + 2 + k] = p
    if side == "left":
        local[:, 0] *= -1.0
    w = np.eye(4) if wrist is None else np.asarray(wrist, float)
    out = np.tile(np.eye(4), (25, 1, 1))
    out[:, :3, :3] = w[:3, :3]
    out[:, :3, 3] = local @ w[:3, :3].T + w[:3, 3]
    return out
