"""The operator protocol rejects what the page must never be able to send (pure: no simulator)."""

from __future__ import annotations

import json

import pytest

from stages.teleop.protocol import (
    MAX_MESSAGE_BYTES,
    EpisodeControl,
    FrameAck,
    OperatorCommand,
    ProtocolError,
    RateLimiter,
    XrPoses,
    parse_message,
)

CMD = {"type": "cmd", "seq": 3, "base": [1, 0, -0.5], "jog": [0, 0, 0, 0, 0, 0], "mode": 0, "gripper": 1}
EYE = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.1, 0.2, 1.5, 1]  # column-major, translation (0.1, 0.2, 1.5)


def test_valid_messages_parse_into_typed_values():
    c = parse_message(json.dumps(CMD), now=2.0)
    assert c == OperatorCommand(seq=3, base=(1.0, 0.0, -0.5), jog=(0.0,) * 6, mode=0, gripper=1, received=2.0)
    assert parse_message('{"type": "episode", "action": "start", "task": " wipe "}') == EpisodeControl("start", "wipe")
    assert parse_message('{"type": "ack", "frame": 7}', now=1.0) == FrameAck(7, 1.0)
    xr = parse_message(json.dumps({"type": "xr", "head": EYE, "hands": {"left": [EYE] * 25}}))
    assert isinstance(xr, XrPoses) and xr.head[0][3] == 0.1 and xr.head[2][3] == 1.5 and len(xr.hands["left"]) == 25


@pytest.mark.parametrize("raw, reason", [
    ("not json", "not JSON"),
    ("[1, 2]", "JSON object"),
    ('{"type": "fly"}', "unknown message type"),
    (json.dumps(CMD | {"extra": 1}), "unknown keys"),
    (json.dumps({k: v for k, v in CMD.items() if k != "mode"}), "missing keys"),
    (json.dumps(CMD).replace("-0.5", "NaN"), "not a number"),
    (json.dumps(CMD).replace("-0.5", "1e400"), "not finite"),
    (json.dumps(CMD | {"base": [2, 0, 0]}), "out of range"),
    (json.dumps(CMD | {"base": [0, 0]}), "list of 3"),
    (json.dumps(CMD | {"base": [True, 0, 0]}), "must be a number"),
    (json.dumps(CMD | {"mode": 2}), "out of range"),
    (json.dumps(CMD | {"seq": -1}), "out of range"),
    (json.dumps(CMD | {"gripper": 0.5}), "integer"),
    ('{"type": "episode", "action": "format_disk"}', "start, save or discard"),
    ('{"type": "episode", "action": "start", "task": "' + "x" * 201 + '"}', "200"),
    ("[" * 100000 + "]" * 100000, "exceeds"),
    ("[" * 5000 + "]" * 5000, "not JSON"),
    (json.dumps({"type": "xr", "head": EYE[:15], "hands": {}}), "16 numbers"),
    (json.dumps({"type": "xr", "head": [2.0] + EYE[1:], "hands": {}}), "orthonormal"),
    (json.dumps({"type": "xr", "head": EYE, "hands": {"left": [EYE] * 24}}), "25 joint"),
    (json.dumps({"type": "xr", "head": EYE, "hands": {"tail": [EYE] * 25}}), "left and/or right"),
    (json.dumps({"type": "xr", "head": EYE, "hands": {"right": [EYE] * 9 + [EYE[:12] + [0.1, 0.2, 2.0, 1]]
                                                      + [EYE] * 15}}), r"right\[9\] is 0.50 m from the wrist"),
])
def test_malformed_messages_are_rejected_with_a_reason(raw, reason):
    with pytest.raises(ProtocolError, match=reason):
        parse_message(raw)


def test_oversized_message_is_rejected_before_parsing():
    raw = json.dumps(CMD | {"pad": "x" * MAX_MESSAGE_BYTES})
    with pytest.raises(ProtocolError, match="exceeds"):
        parse_message(raw)


def test_rate_limiter_allows_bursts_then_the_rate():
    rl = RateLimiter(rate=10.0, burst=5)
    assert [rl.allow(now=0.0) for _ in range(7)] == [True] * 5 + [False] * 2
    assert rl.allow(now=0.1) and not rl.allow(now=0.1)  # one token per 0.1 s
    assert rl.dropped == 3


def test_importing_teleop_loads_no_simulator_and_no_torch():
    import subprocess
    import sys

    code = ("import sys, stages.teleop, stages.teleop.server, stages.teleop.xr; "
            "print(sorted(m for m in ('warp', 'newton', 'torch', 'pxr', 'lerobot', 'mujoco') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=__file__.rsplit("/tests/", 1)[0])
    assert out.stdout.strip() == "[]"
