"""Teleoperation (runtime library): an operator drives one task world of the batched engine from
a browser page (keyboard; WebXR poses), and saved episodes land in the same LeRobot dataset
schema as scripted demonstrations, with teleop metadata. ``agentworld teleop`` is its command.

Public surface::

    from stages.teleop import TeleopConfig, TeleopSession, TeleopServer, read_input_log, replay_session

Modules: protocol (messages from the page, validated; rate limit), control (ticks -> robot
commands, CLIK jog), xr (WebXR wrists -> end-effector targets, pinch), hand_retarget (WebXR hand
joints -> a dexterous hand's joint targets, dex-retargeting), inputlog (JSON-lines input log, read
back for replays), recording (episodes as atomic shards, merged dataset), session (the engine
driven by the operator), server (HTTP + WebSocket, token, one operator), cli (the command).
Importing this package loads no simulator.
"""

from stages.teleop.control import TeleopConfig, Tick
from stages.teleop.inputlog import SessionScript, read_input_log
from stages.teleop.protocol import ProtocolError, RateLimiter, parse_message
from stages.teleop.session import TeleopSession, replay_session

__all__ = ["ProtocolError", "RateLimiter", "SessionScript", "TeleopConfig", "TeleopSession", "Tick",
           "parse_message", "read_input_log", "replay_session"]
