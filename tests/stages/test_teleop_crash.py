"""A saved episode survives the teleop server being killed (``kill -9``) mid-way through the next
one; nothing half-written remains visible, and the next session cleans up and re-merges. The
session runs as the ``agentworld teleop`` command, driven over a real WebSocket."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def kitchen(teleop_world):
    return teleop_world


def _start(out: Path, work: Path) -> tuple[subprocess.Popen, str, list[str]]:
    cmd = [sys.executable, "-m", "pipeline.cli", "teleop", "press_button", "--out", str(out), "--work", str(work),
           "--port", "0", "--width", "32", "--height", "24"]
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    t0 = time.monotonic()
    console = []
    for line in proc.stdout:
        console.append(line)
        if line.startswith("teleop: open "):
            return proc, line.split()[2], console
        if time.monotonic() - t0 > 300:
            break
    proc.kill()
    raise RuntimeError("agentworld teleop did not print its URL")


async def _operate(url: str, out: Path) -> None:
    import aiohttp

    base, token = url.split("?token=")
    status: dict = {}

    async def until(pred, timeout: float = 240.0) -> None:
        t0 = time.monotonic()
        while not pred():
            msg = await ws.receive(timeout=timeout)
            if msg.type == aiohttp.WSMsgType.TEXT:
                status.update(json.loads(msg.data))
            elif msg.type != aiohttp.WSMsgType.BINARY:
                raise RuntimeError(f"teleop socket closed: {msg}")
            if time.monotonic() - t0 > timeout:
                raise TimeoutError("teleop crash test: condition not met")

    async with aiohttp.ClientSession() as http, http.ws_connect(f"{base}ws?token={token}") as ws:
        await ws.send_str(json.dumps({"type": "episode", "action": "start"}))
        await until(lambda: status.get("recording"))
        cmd = {"type": "cmd", "seq": 1, "base": [1, 0, 0], "jog": [0] * 6, "mode": 0, "gripper": 0}
        for i in range(8):
            await ws.send_str(json.dumps(cmd | {"seq": i + 1}))
            await until(lambda i=i: status.get("tick", 0) >= 2 * (i + 1))
        await ws.send_str(json.dumps({"type": "episode", "action": "save"}))
        await until(lambda: status.get("saved") == 1)
        while not (out / "dataset" / "meta" / "teleop.json").is_file():
            await until(lambda: True)
        await ws.send_str(json.dumps({"type": "episode", "action": "start"}))
        await until(lambda: status.get("recording") and status.get("tick", 0) >= 6)


def test_a_saved_episode_survives_kill_9_and_nothing_half_written_remains(kitchen, tmp_path):
    from stages.dataset import list_shards, load_dataset
    from stages.dataset.schema import CameraSpec, DatasetSpec
    from stages.teleop.recording import TeleopRecorder

    out, work = tmp_path / "out", kitchen.usd.parent.parent
    proc, url, console = _start(out, work)
    try:
        asyncio.run(_operate(url, out))
        temps = [p.name for p in (out / "shards").iterdir() if p.name.startswith(".tmp-")]
        assert len(temps) == 1  # the second episode, being written
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(30)
        console += proc.stdout.readlines()
    # the console shows our lines only (Warp's banner and kernel loads, progress bars: in the log)
    text = "".join(console)
    assert "Warp" not in text and "Module" not in text and "%|" not in text, text
    assert (out / "logs" / "teleop.log").is_file()
    shards = list_shards(out / "shards")  # complete shards only
    assert [s.episodes for s in shards] == [1]
    ds = load_dataset(out / "dataset")
    assert ds.num_episodes == 1 and ds.num_frames == shards[0].frames
    log_lines = (next((out / "logs").glob("*.jsonl"))).read_text().splitlines()
    assert all(json.loads(x) for x in log_lines[:-1])  # the input log: whole lines up to the kill
    # the next session: the killed writer's folder goes, the dataset stays
    spec = DatasetSpec(fps=30, cameras=tuple(CameraSpec(c, height=24, width=32)
                                             for c in ("wrist", "head", "third_person")))
    rec = TeleopRecorder(out, spec, "next")
    rec.close()
    assert not [p for p in (out / "shards").iterdir() if p.name.startswith(".tmp-")]
    assert load_dataset(out / "dataset").num_episodes == 1
