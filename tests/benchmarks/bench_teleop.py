"""Teleop latency on localhost: input-to-command and render-to-display times, frame rates.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_teleop.py -s``
(``BENCH_TELEOP_SECONDS`` wall seconds of recording, default 30; ``BENCH_TELEOP_SIZE`` camera
images WxH, default 160x120; ``BENCH_TELEOP_DEVICE`` cpu or cuda). A live session (3 cameras) and
its server run here; the page runs in the OS's Chromium (headless, Playwright); the benchmark holds
W for 1 s, releases it for 1 s, and so on, in one recorded episode, then saves it. Prints and writes
``bench_results/teleop.json``:

- input_to_command: from a control message's arrival at the server to the tick that applies it [ms]
  (the page repeats its controls every 0.1 s, so most samples are repeats);
- render_to_display: from a frame's capture (after the render) to the arrival of the page's
  acknowledgement that it has decoded and shown it [ms] (JPEG encoding, WebSocket, decoding, the
  acknowledgement's way back: an upper bound);
- sim_fps: frames the simulation captured per wall second; display_fps: frames the page showed per
  second (the page's count over its last 2 s, read every 2 s: median, min, max); the engine's wall
  time split (simulation, rendering, control, encoding);
- load_average: the machine's 1-minute load average at the start and the end (the figures above
  depend on what else runs on a shared machine).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
for p in (REPO, REPO / "tests" / "stages"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


@pytest.mark.benchmark
def test_teleop_latency_on_localhost():
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("no Chromium from the OS packages")
    sync_api = pytest.importorskip("playwright.sync_api")
    from teleop_testutil import ServerThread, wait_for

    from stages.teleop import TeleopConfig, TeleopSession
    from stages.teleop.world import teleop_kitchen

    seconds = float(os.environ.get("BENCH_TELEOP_SECONDS", "30"))
    w, h = (int(x) for x in os.environ.get("BENCH_TELEOP_SIZE", "160x120").split("x"))
    device = os.environ.get("BENCH_TELEOP_DEVICE", "cpu")
    tmp = Path(tempfile.mkdtemp(prefix="bench-teleop-"))
    try:
        world = teleop_kitchen(tmp / "world", 5)
        cfg = TeleopConfig(width=w, height=h, device=device)
        session = TeleopSession(world, task="pick_place_bowl", out=tmp / "out", config=cfg, world_seed=5)
        srv = ServerThread(session)
        session.start()
        try:
            with sync_api.sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
                page = browser.new_page(viewport={"width": 1400, "height": 700})
                page.goto(srv.url)
                wait_for(lambda: page.evaluate("() => window.teleopState.frames > 2"), what="frames")
                page.click("#btn-start")
                wait_for(lambda: session.status()["recording"], what="recording")
                page.click("#views")
                load0 = os.getloadavg()[0]
                t0 = time.monotonic()
                fps = []
                while time.monotonic() - t0 < seconds:
                    page.keyboard.down("KeyW")
                    time.sleep(1.0)
                    page.keyboard.up("KeyW")
                    time.sleep(1.0)
                    fps.append(page.evaluate("() => window.teleopState.fps"))
                page.click("#btn-save")
                wait_for(lambda: session.status()["saved"] >= 1, what="save")
                browser.close()
        finally:
            session.stop()
            session.join(120)
            srv.close()
        meta = json.loads((session.saved[0] / "meta" / "teleop.json").read_text())
        stats = session.engine.stats.to_json()
        frames = meta["frames"]
        result = {"device": device, "size": f"{w}x{h}", "cameras": 3, "wall_seconds": meta["wall_seconds"],
                  "frames": frames, "sim_seconds": meta["sim_seconds"],
                  "sim_fps": round(frames / meta["wall_seconds"], 2),
                  "display_fps_median": round(sorted(fps)[len(fps) // 2], 2) if fps else None,
                  "display_fps_min": min(fps, default=None), "display_fps_max": max(fps, default=None),
                  "load_average": [round(load0, 2), round(os.getloadavg()[0], 2)],
                  "realtime_factor": round(meta["sim_seconds"] / meta["wall_seconds"], 3),
                  "latency": meta["latency"], "engine_seconds": stats["timings"], "cpu_count": os.cpu_count()}
        dest = REPO / "bench_results" / "teleop.json"
        dest.parent.mkdir(exist_ok=True)
        dest.write_text(json.dumps(result, indent=2))
        lat = result["latency"]
        print(f"\nteleop on {device}, 3 cameras {w}x{h}: sim {result['sim_fps']} frames/s "
              f"({result['realtime_factor']}x real time), display {result['display_fps_median']} fps; "
              f"input->command p50 {lat['input_to_command']['p50_ms']} ms p95 {lat['input_to_command']['p95_ms']} ms; "
              f"render->display p50 {lat['render_to_display']['p50_ms']} ms p95 {lat['render_to_display']['p95_ms']} ms"
              f"\nengine wall split [s]: {stats['timings']}; load average {result['load_average']} on "
              f"{os.cpu_count()} cores\n-> {dest}")
        assert lat["render_to_display"]["count"] > 0 and lat["input_to_command"]["count"] > 0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
