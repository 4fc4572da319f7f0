"""The input log of a teleop session (JSON lines) and reading it back for ``--replay``.

One JSON object per line, flushed as it is written (a crash loses at most the line being written):

- ``{"kind": "session", "version": 1, "task": ..., "world_seed": ..., "config": {...}}`` first;
- ``{"kind": "begin", "episode": k, "task": ..., "seed": ..., "record": true|false,
  "instruction": ...}`` when an engine episode starts (``record`` false: the preview before the
  operator presses start, not recorded);
- ``{"kind": "tick", "episode": k, "i": i, "base": [3], "jog": [6], "mode": m, "gripper": g}``
  per frame period (the controls applied before frame ``i + 1``'s physics steps), with ``"ee":
  [16]`` (an end-effector target, row-major 4x4 in the base frame [m]) when WebXR drove it, and
  ``"hand": [n]`` (a dexterous hand's retargeted joint targets [rad]) when a WebXR hand drove it;
- ``{"kind": "end", "episode": k, "outcome": "start"|"save"|"discard"|"stop", "reason": ...}``
  ("start": a preview the operator ended by starting a recorded episode).

:func:`read_input_log` validates a log (it is a file from elsewhere: every line is checked, the
problems are collected and raised as one error) into a :class:`SessionScript`.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from stages.teleop.control import Tick

VERSION = 1


class InputLog:
    """Append-only JSON-lines writer (a context manager); ``path``: the log file (created)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._f = open(self.path, "x", encoding="utf-8")  # noqa: SIM115 (closed by close())

    def write(self, record: dict) -> None:
        self._f.write(json.dumps(record, separators=(",", ":"), allow_nan=False) + "\n")
        self._f.flush()

    def sync(self) -> None:
        """Flush to disk (at an episode's end)."""
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self) -> None:
        if not self._f.closed:
            self.sync()
            self._f.close()

    def __enter__(self) -> InputLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class EpisodeScript:
    """One logged episode: its instance (task, seed), whether it was recorded, its instruction, the
    ticks in order and how it ended (outcome "start", "save", "discard", "stop" or "" if the log ends
    first)."""

    episode: int
    task: str
    seed: int
    record: bool
    instruction: str
    ticks: list[Tick] = field(default_factory=list)
    outcome: str = ""
    reason: str = ""


@dataclass
class SessionScript:
    """A parsed input log: the session header and its episodes in order."""

    task: str
    world_seed: int
    config: dict
    episodes: list[EpisodeScript]

    def recorded(self) -> list[EpisodeScript]:
        """The episodes that were saved to the dataset."""
        return [e for e in self.episodes if e.record and e.outcome == "save"]


def _axes(v, n: int) -> tuple[float, ...] | None:
    if not isinstance(v, list) or len(v) != n:
        return None
    if not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and -1 <= x <= 1
               for x in v):
        return None
    return tuple(float(x) for x in v)


def _ee(v) -> tuple[float, ...] | None | bool:
    """An ``ee`` field: None when absent, the 16 numbers, or False when malformed."""
    if v is None:
        return None
    if not isinstance(v, list) or len(v) != 16:
        return False
    if not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and abs(x) <= 100
               for x in v):
        return False
    return tuple(float(x) for x in v)


def _hand(v) -> tuple[float, ...] | None | bool:
    """A ``hand`` field: None when absent, its joint targets (1 to 64 numbers within 10 rad), or
    False when malformed."""
    if v is None:
        return None
    if not isinstance(v, list) or not 1 <= len(v) <= 64:
        return False
    if not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and abs(x) <= 10
               for x in v):
        return False
    return tuple(float(x) for x in v)


def read_input_log(path: Path, *, max_lines: int = 10_000_000) -> SessionScript:
    """Parse and validate an input log (raises ValueError naming every bad line, at most 20)."""
    path = Path(path)
    problems: list[str] = []
    header: dict | None = None
    episodes: dict[int, EpisodeScript] = {}
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, start=1):
            if n > max_lines:
                problems.append(f"more than {max_lines} lines")
                break
            if not line.strip():
                continue
            where = f"{path}:{n}"
            try:
                rec = json.loads(line, parse_constant=lambda c: float("nan"))
            except ValueError as e:
                problems.append(f"{where}: not JSON ({e})")
                continue
            if not isinstance(rec, dict):
                problems.append(f"{where}: not an object")
                continue
            kind = rec.get("kind")
            if n == 1 or header is None:
                if kind != "session" or rec.get("version") != VERSION:
                    problems.append(f"{where}: the first line must be a version {VERSION} session header")
                    break
                if not isinstance(rec.get("task"), str) or not isinstance(rec.get("world_seed"), int):
                    problems.append(f"{where}: session header needs task (text) and world_seed (integer)")
                header = rec
                continue
            ep = rec.get("episode")
            if not isinstance(ep, int) or isinstance(ep, bool):
                problems.append(f"{where}: episode must be an integer")
                continue
            if kind == "begin":
                if ep in episodes or not isinstance(rec.get("task"), str) or not isinstance(rec.get("seed"), int) \
                        or not isinstance(rec.get("record"), bool):
                    problems.append(f"{where}: bad begin record (repeated episode or missing task/seed/record)")
                    continue
                episodes[ep] = EpisodeScript(episode=ep, task=rec["task"], seed=rec["seed"], record=rec["record"],
                                             instruction=str(rec.get("instruction", "")))
            elif kind == "tick":
                e = episodes.get(ep)
                base, jog = _axes(rec.get("base"), 3), _axes(rec.get("jog"), 6)
                mode, grip = rec.get("mode"), rec.get("gripper")
                ee, hand = _ee(rec.get("ee")), _hand(rec.get("hand"))
                if e is None or e.outcome:
                    problems.append(f"{where}: tick outside an open episode")
                elif rec.get("i") != len(e.ticks):
                    problems.append(f"{where}: tick index {rec.get('i')} where {len(e.ticks)} was expected")
                elif base is None or jog is None or mode not in (0, 1) or grip not in (0, 1) or ee is False \
                        or hand is False:
                    problems.append(f"{where}: bad tick (base: 3 axes, jog: 6 axes in [-1, 1]; mode, gripper 0/1; "
                                    "ee: 16 numbers within 100 m; hand: 1-64 numbers within 10 rad)")
                else:
                    e.ticks.append(Tick(base=base, jog=jog, mode=int(mode), gripper=int(grip), ee=ee, hand=hand))
            elif kind == "end":
                e = episodes.get(ep)
                if e is None or rec.get("outcome") not in ("start", "save", "discard", "stop"):
                    problems.append(f"{where}: bad end record")
                else:
                    e.outcome, e.reason = rec["outcome"], str(rec.get("reason", ""))
            else:
                problems.append(f"{where}: unknown kind {str(kind)[:30]!r}")
            if len(problems) >= 20:
                break
    if header is None and not problems:
        problems.append(f"{path}: empty log")
    if problems:
        raise ValueError(f"{path}: invalid input log:\n  " + "\n  ".join(problems))
    return SessionScript(task=header["task"], world_seed=int(header["world_seed"]),
                         config=dict(header.get("config") or {}),
                         episodes=[episodes[k] for k in sorted(episodes)])
