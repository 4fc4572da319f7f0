"""The operator protocol: JSON messages from the page (untrusted), validated into typed values.

Every message is one JSON object of at most :data:`MAX_MESSAGE_BYTES` bytes with a ``type``:

- ``{"type": "cmd", "seq": n, "base": [vx, vy, wz], "jog": [x, y, z, roll, pitch, yaw],
  "mode": 0|1, "gripper": 0|1}``: the operator's controls as they are now (keys held). ``base``
  and ``jog`` are axes in [-1, 1] (scaled by :class:`~stages.teleop.control.TeleopConfig`'s
  maximum speeds: base [m/s, m/s, rad/s], jog [m/s, rad/s] in the base frame); ``mode`` 0
  locomotion, 1 manipulation; ``gripper`` 0 open, 1 closed; ``seq`` a non-negative integer.
- ``{"type": "episode", "action": "start"|"save"|"discard", "task": "..."}``: episode controls
  (``task``: optional instruction text for a start, at most 200 characters).
- ``{"type": "ack", "frame": n}``: the page displayed frame ``n`` (render-to-display latency).
- ``{"type": "xr", "head": [16], "hands": {"left"|"right": [[16] x 25]}}``: WebXR poses (column-
  major 4x4 matrices in the XR reference space [m]), head and up to two hands of 25 joints, each
  joint within :data:`MAX_HAND_SPAN` of its wrist.

Anything else (not JSON, not an object, unknown type or key, a missing key, a wrong type, NaN or
infinity, a value out of range, too large) raises :class:`ProtocolError` with the reason; the
server logs it and drops the message. :class:`RateLimiter` bounds the message rate (token bucket).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field

MAX_MESSAGE_BYTES = 16384
"""Largest accepted message [bytes] (an XR message of two hands is about 10 kB)."""

XR_JOINTS = 25
"""Joints per hand (WebXR XRHand: wrist, 4 thumb, 5 per finger)."""

MAX_HAND_SPAN = 0.35
"""Farthest a hand joint may be from its wrist [m] (a human hand: tips at about 0.2 m)."""


class ProtocolError(ValueError):
    """A rejected message; the text is the reason (logged, sent back to the page)."""


@dataclass(frozen=True)
class OperatorCommand:
    """The operator's controls: base (3,) and jog (6,) axes in [-1, 1]; mode 0/1; gripper 0/1;
    seq: the page's message counter; received: server clock at arrival [s, time.perf_counter]."""

    seq: int
    base: tuple[float, float, float] = (0.0, 0.0, 0.0)
    jog: tuple[float, float, float, float, float, float] = (0.0,) * 6
    mode: int = 0
    gripper: int = 0
    received: float = 0.0


@dataclass(frozen=True)
class EpisodeControl:
    """start, save or discard the episode; task: instruction text for a start ("" keeps the task's)."""

    action: str
    task: str = ""


@dataclass(frozen=True)
class FrameAck:
    """The page displayed frame ``frame``; received: server clock [s]."""

    frame: int
    received: float = 0.0


@dataclass(frozen=True)
class XrPoses:
    """Head pose (4, 4) and hand joint poses {"left"|"right": (25, 4, 4)} as nested tuples, row-major
    (converted from WebXR's column-major arrays) [m]; received: server clock [s]."""

    head: tuple
    hands: dict = field(default_factory=dict)
    received: float = 0.0


Message = OperatorCommand | EpisodeControl | FrameAck | XrPoses

_KEYS = {"cmd": {"type", "seq", "base", "jog", "mode", "gripper"},
         "episode": {"type", "action", "task"},
         "ack": {"type", "frame"},
         "xr": {"type", "head", "hands"}}
_REQUIRED = {"cmd": {"type", "seq", "base", "jog", "mode", "gripper"}, "episode": {"type", "action"},
             "ack": {"type", "frame"}, "xr": {"type", "head", "hands"}}


def parse_message(raw: str | bytes, *, now: float | None = None) -> Message:
    """Validate one raw message into a typed value (raises :class:`ProtocolError`)."""
    size = len(raw.encode("utf-8") if isinstance(raw, str) else raw)
    if size > MAX_MESSAGE_BYTES:
        raise ProtocolError(f"message of {size} bytes exceeds {MAX_MESSAGE_BYTES}")
    try:
        msg = json.loads(raw, parse_constant=_reject_constant)
    except (ValueError, UnicodeDecodeError, RecursionError) as e:
        raise ProtocolError(f"not JSON ({str(e)[:80]})") from None
    if not isinstance(msg, dict):
        raise ProtocolError(f"a message must be a JSON object, got {type(msg).__name__}")
    kind = msg.get("type")
    if not isinstance(kind, str) or kind not in _KEYS:
        raise ProtocolError(f"unknown message type {str(kind)[:40]!r}; known {sorted(_KEYS)}")
    extra = set(msg) - _KEYS[kind]
    missing = _REQUIRED[kind] - set(msg)
    if extra or missing:
        raise ProtocolError(f"{kind}: unknown keys {sorted(extra)[:5]}, missing keys {sorted(missing)}")
    t = time.perf_counter() if now is None else now
    if kind == "cmd":
        return OperatorCommand(seq=_int(msg["seq"], "cmd.seq", 0, 2**53), base=_axes(msg["base"], 3, "cmd.base"),
                               jog=_axes(msg["jog"], 6, "cmd.jog"), mode=_int(msg["mode"], "cmd.mode", 0, 1),
                               gripper=_int(msg["gripper"], "cmd.gripper", 0, 1), received=t)
    if kind == "episode":
        action = msg["action"]
        if action not in ("start", "save", "discard"):
            raise ProtocolError(f"episode.action must be start, save or discard, got {str(action)[:40]!r}")
        task = msg.get("task", "")
        if not isinstance(task, str) or len(task) > 200 or any(ord(c) < 32 for c in task):
            raise ProtocolError("episode.task must be text of at most 200 printable characters")
        return EpisodeControl(action=action, task=task.strip())
    if kind == "ack":
        return FrameAck(frame=_int(msg["frame"], "ack.frame", 0, 2**53), received=t)
    return _xr(msg, t)


def _reject_constant(name: str):
    raise ValueError(f"{name} is not a number")


def _number(v, where: str, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ProtocolError(f"{where} must be a number, got {type(v).__name__}")
    x = float(v)
    if not math.isfinite(x):
        raise ProtocolError(f"{where} is not finite")
    if not lo <= x <= hi:
        raise ProtocolError(f"{where} = {x:g} is out of range [{lo:g}, {hi:g}]")
    return x


def _int(v, where: str, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise ProtocolError(f"{where} must be an integer, got {type(v).__name__}")
    if not lo <= v <= hi:
        raise ProtocolError(f"{where} = {v} is out of range [{lo}, {hi}]")
    return int(v)


def _axes(v, n: int, where: str) -> tuple:
    if not isinstance(v, list) or len(v) != n:
        raise ProtocolError(f"{where} must be a list of {n} numbers")
    return tuple(_number(x, f"{where}[{i}]", -1.0, 1.0) for i, x in enumerate(v))


def _matrix(v, where: str) -> tuple:
    """A WebXR column-major 4x4 (16 numbers, translations within 100 m) -> row-major nested tuple."""
    if not isinstance(v, list) or len(v) != 16:
        raise ProtocolError(f"{where} must be a list of 16 numbers (a column-major 4x4)")
    m = [_number(x, f"{where}[{i}]", -100.0, 100.0) for i, x in enumerate(v)]
    if abs(m[15] - 1.0) > 1e-6 or any(abs(m[i]) > 1e-6 for i in (3, 7, 11)):
        raise ProtocolError(f"{where} is not a rigid transform (last row must be 0 0 0 1)")
    rows = tuple(tuple(m[c * 4 + r] for c in range(4)) for r in range(4))
    for r in range(3):  # the rotation block: unit rows within 1e-3
        if abs(sum(x * x for x in rows[r][:3]) - 1.0) > 1e-3:
            raise ProtocolError(f"{where} has no orthonormal rotation")
    return rows


def _xr(msg: dict, t: float) -> XrPoses:
    head = _matrix(msg["head"], "xr.head")
    hands = msg["hands"]
    if not isinstance(hands, dict) or set(hands) - {"left", "right"}:
        raise ProtocolError("xr.hands must be an object with keys left and/or right")
    out = {}
    for side, joints in hands.items():
        if not isinstance(joints, list) or len(joints) != XR_JOINTS:
            raise ProtocolError(f"xr.hands.{side} must list {XR_JOINTS} joint poses")
        out[side] = tuple(_matrix(j, f"xr.hands.{side}[{i}]") for i, j in enumerate(joints))
        wrist = out[side][0]
        for i, m in enumerate(out[side]):
            d = math.dist([r[3] for r in m[:3]], [r[3] for r in wrist[:3]])
            if d > MAX_HAND_SPAN:
                raise ProtocolError(f"xr.hands.{side}[{i}] is {d:.2f} m from the wrist (at most {MAX_HAND_SPAN} m)")
    return XrPoses(head=head, hands=out, received=t)


class RateLimiter:
    """Token bucket: ``rate`` messages per second [1/s] on average, bursts of ``burst``."""

    def __init__(self, rate: float = 120.0, burst: int = 60) -> None:
        if rate <= 0 or burst < 1:
            raise ValueError(f"rate limiter: rate must be > 0 and burst >= 1, got {rate}, {burst}")
        self.rate, self.burst = float(rate), float(burst)
        self._tokens, self._last = float(burst), None
        self.dropped = 0

    def allow(self, now: float | None = None) -> bool:
        """Take one token (True), or count a drop (False)."""
        t = time.perf_counter() if now is None else now
        if self._last is not None:
            self._tokens = min(self.burst, self._tokens + (t - self._last) * self.rate)
        self._last = t
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self.dropped += 1
        return False
