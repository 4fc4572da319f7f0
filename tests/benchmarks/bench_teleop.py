"""Teleop latency on localhost: input-to-command and render-to-display times, frame rates.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_teleop.py -s``
(``BENCH_TELEOP_SECONDS`` wall seconds of recording, default 30; ``BENCH_TELEOP_SIZE`` camera
images WxH, default 160x120; ``BENCH_TELEOP_DEVICE`` cpu or cuda). A live session (3 cameras) and
its server run here; the page runs in the OS's Chromium (headless, Playwright); the benchmark holds
W for 1 s, releases it for 1 s, and so on, in one recorded episode, then saves it.

Without a browser (the GPU host has no Chromium): ``python tests/benchmarks/bench_teleop.py
--client python --device cuda [--seconds 30] [--size 160x120]`` runs the same session, server and
script, with the page's protocol spoken by :class:`stages.teleop.client.TeleopClient` (it loads
the page, sends the page's messages at the page's rate, decodes every streamed frame's JPEGs before
acknowledging it). ``--client chromium`` is the page in Chromium, as the pytest benchmark.

Prints and writes ``bench_results/teleop.json`` (Chromium) or ``bench_results/teleop_python_<device>.json``:

- input_to_command: from a control message's arrival at the server to the tick that applies it [ms]
  (the page repeats its controls every 0.1 s, so most samples are repeats);
- render_to_display: from a frame's capture (after the render) to the arrival of the page's
  acknowledgement that it has decoded and shown it [ms] (JPEG encoding, WebSocket, decoding, the
  acknowledgement's way back: an upper bound);
- sim_fps: frames the simulation captured per wall second; display_fps: frames the page showed per
  second (the page's count over its last 2 s, read every 2 s: median, min, max); the engine's wall
  time split (simulation, rendering, control, encoding);
- process_cpu_ms_per_frame: CPU time of the benchmark's process (session, render threads, server,
  and the Python client when it is the client) per simulated frame in the window [ms] (less
  sensitive to a shared machine's load than the frame rates);
- load_average: the machine's 1-minute load average at the start and the end (the figures above
  depend on what else runs on a shared machine).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
for p in (REPO, REPO / "tests" / "stages"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

try:
    import pytest
except ImportError:  # the GPU host's plain run (python bench_teleop.py ...)
    pytest = None


class _ChromiumOperator:
    """The page in the OS's Chromium (headless, Playwright)."""

    def __init__(self, url: str, chromium: str) -> None:
        from playwright.sync_api import sync_playwright

        self._pw = sync_playwright().start()
        self.browser = self._pw.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        self.page = self.browser.new_page(viewport={"width": 1400, "height": 700})
        self.page.goto(url)

    def frames(self) -> int:
        return self.page.evaluate("() => window.teleopState.frames")

    def fps(self) -> float:
        return self.page.evaluate("() => window.teleopState.fps")

    def start(self) -> None:
        self.page.click("#btn-start")

    def focus(self) -> None:
        self.page.click("#views")

    def key(self, code: str, down: bool) -> None:
        (self.page.keyboard.down if down else self.page.keyboard.up)(code)

    def save(self) -> None:
        self.page.click("#btn-save")

    def close(self) -> dict:
        self.browser.close()
        self._pw.stop()
        return {}


class _PythonOperator:
    """The page's protocol from Python (:class:`stages.teleop.client.TeleopClient`)."""

    def __init__(self, url: str) -> None:
        from stages.teleop.client import TeleopClient

        self.c = TeleopClient(url).connect()

    def frames(self) -> int:
        return self.c.frames

    def fps(self) -> float:
        return self.c.fps

    def start(self) -> None:
        self.c.episode("start")

    def focus(self) -> None:
        pass

    def key(self, code: str, down: bool) -> None:
        (self.c.key_down if down else self.c.key_up)(code)

    def save(self) -> None:
        self.c.episode("save")

    def close(self) -> dict:
        self.c.close()
        return {"client_frames": self.c.frames, "client_megabytes": round(self.c.bytes / 1e6, 2),
                "client_errors": self.c.errors}


def run_bench(client: str = "chromium", device: str = "cpu", seconds: float = 30.0, size=(160, 120),
              chromium: str | None = None, cameras: tuple[str, ...] = ("wrist", "head", "third_person")) -> dict:
    """One benchmark run (see the module docstring); returns the result written to bench_results."""
    from teleop_testutil import ServerThread, wait_for

    from stages.teleop import TeleopConfig, TeleopSession
    from stages.teleop.world import teleop_kitchen

    w, h = size
    tmp = Path(tempfile.mkdtemp(prefix="bench-teleop-"))
    try:
        t_build = time.monotonic()
        world = teleop_kitchen(tmp / "world", 5)
        cfg = TeleopConfig(width=w, height=h, device=device, cameras=tuple(cameras))
        session = TeleopSession(world, task="pick_place_bowl", out=tmp / "out", config=cfg, world_seed=5)
        srv = ServerThread(session)
        session.start()
        extra = {}
        try:
            op = _ChromiumOperator(srv.url, chromium) if client == "chromium" else _PythonOperator(srv.url)
            try:
                wait_for(lambda: op.frames() > 2, what="frames")
                build_s = time.monotonic() - t_build
                op.start()
                wait_for(lambda: session.status()["recording"], what="recording")
                op.focus()
                load0 = os.getloadavg()[0]
                t0 = time.monotonic()
                tick0, cpu0 = session.status()["tick"], time.process_time()
                fps = []
                while time.monotonic() - t0 < seconds:
                    op.key("KeyW", True)
                    time.sleep(1.0)
                    op.key("KeyW", False)
                    time.sleep(1.0)
                    fps.append(op.fps())
                ticks, cpu = session.status()["tick"] - tick0, time.process_time() - cpu0
                op.save()
                wait_for(lambda: session.status()["saved"] >= 1, what="save")
            finally:
                extra = op.close()
        finally:
            session.stop()
            session.join(120)
            srv.close()
        meta = json.loads((session.saved[0] / "meta" / "teleop.json").read_text())
        stats = session.engine.stats.to_json()
        frames = meta["frames"]
        result = {"client": client, "device": device, "size": f"{w}x{h}", "cameras": len(cfg.cameras),
                  "wall_seconds": meta["wall_seconds"], "frames": frames, "sim_seconds": meta["sim_seconds"],
                  "sim_fps": round(frames / meta["wall_seconds"], 2),
                  "display_fps_median": round(sorted(fps)[len(fps) // 2], 2) if fps else None,
                  "display_fps_min": min(fps, default=None), "display_fps_max": max(fps, default=None),
                  "load_average": [round(load0, 2), round(os.getloadavg()[0], 2)],
                  "realtime_factor": round(meta["sim_seconds"] / meta["wall_seconds"], 3),
                  "latency": meta["latency"], "engine_seconds": stats["timings"], "cpu_count": os.cpu_count(),
                  "startup_seconds": round(build_s, 1),
                  "process_cpu_ms_per_frame": round(1000.0 * cpu / max(ticks, 1), 1), "server": dict(srv.server.stats), **extra}
        name = "teleop.json" if client == "chromium" else f"teleop_python_{device.replace(':', '')}.json"
        dest = REPO / "bench_results" / name
        dest.parent.mkdir(exist_ok=True)
        dest.write_text(json.dumps(result, indent=2))
        lat = result["latency"]
        print(f"\nteleop on {device} ({client} client), {result['cameras']} cameras {w}x{h}: sim {result['sim_fps']} "
              f"frames/s ({result['realtime_factor']}x real time), display {result['display_fps_median']} fps; "
              f"input->command p50 {lat['input_to_command']['p50_ms']} ms p95 {lat['input_to_command']['p95_ms']} ms; "
              f"render->display p50 {lat['render_to_display']['p50_ms']} ms p95 {lat['render_to_display']['p95_ms']} ms"
              f"\nthis process's CPU {result['process_cpu_ms_per_frame']} ms per frame (server, session, render"
              f"{', client' if client == 'python' else ''}); engine wall split [s]: {stats['timings']}; load average {result['load_average']} on "
              f"{os.cpu_count()} cores\n-> {dest}", flush=True)
        return result
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if pytest is not None:
    @pytest.mark.benchmark
    def test_teleop_latency_on_localhost():
        chromium = shutil.which("chromium") or shutil.which("chromium-browser")
        if chromium is None:
            pytest.skip("no Chromium from the OS packages")
        pytest.importorskip("playwright.sync_api")
        seconds = float(os.environ.get("BENCH_TELEOP_SECONDS", "30"))
        size = tuple(int(x) for x in os.environ.get("BENCH_TELEOP_SIZE", "160x120").split("x"))
        device = os.environ.get("BENCH_TELEOP_DEVICE", "cpu")
        result = run_bench("chromium", device, seconds, size, chromium=chromium)
        lat = result["latency"]
        assert lat["render_to_display"]["count"] > 0 and lat["input_to_command"]["count"] > 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--client", choices=("python", "chromium"), default="chromium",
                   help="who speaks the page's protocol: the page in the OS's Chromium, or Python")
    p.add_argument("--device", default="cpu", help="the session's simulation and rendering device: cpu, cuda[:n]")
    p.add_argument("--seconds", type=float, default=30.0, help="wall seconds of the recorded episode")
    p.add_argument("--size", default="160x120", help="camera images WxH [px]")
    p.add_argument("--cameras", default="wrist,head,third_person", help="cameras rendered and streamed")
    a = p.parse_args(argv)
    chromium = None
    if a.client == "chromium":
        chromium = shutil.which("chromium") or shutil.which("chromium-browser")
        if chromium is None:
            p.error("--client chromium: no Chromium from the OS packages here (use --client python)")
    w, h = (int(x) for x in a.size.split("x"))
    os.environ.setdefault("TQDM_DISABLE", "1")
    result = run_bench(a.client, a.device, a.seconds, (w, h), chromium=chromium, cameras=tuple(a.cameras.split(",")))
    ok = result["latency"]["render_to_display"]["count"] > 0 and result["latency"]["input_to_command"]["count"] > 0
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
