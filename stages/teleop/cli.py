"""``agentworld teleop TASK --robot mobile_panda [--hand allegro|shadow] --out DIR [--replay FILE] [--host H]``.

``--hand`` mounts a dexterous hand on the Panda instead of its parallel gripper; a WebXR hand's
fingers drive it through dex-retargeting (``--retarget dexpilot|vector``,
:mod:`stages.teleop.hand_retarget`), the keyboard's G its closing synergy.

Live: builds (or reuses) the task kitchen in ``--work`` (default ``DIR/.work/world``), starts the
session (engine on ``--device``, CPU by default) and the server, and prints the operator's URL (with
its access token). Ctrl-C ends the session; saved episodes are in ``DIR/dataset`` (and
``DIR/shards``), the input log in ``DIR/logs``. ``--host`` other than 127.0.0.1/localhost serves
HTTPS with a self-signed certificate (``DIR/.tls``): WebXR needs a secure context on the LAN.

Replay: ``--replay LOG`` runs the log's saved episodes again, headless, into ``DIR`` (the kitchen is
rebuilt from the log's world seed in ``--work``) and prints what it wrote.

The console shows our lines only; everything (third-party output included) goes to
``DIR/logs/teleop.log``.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
from pathlib import Path

ROBOTS = ("mobile_panda",)  # embodiments the engine builds today (others: stages/embodiment, not wired)


class _ConsoleRecords(logging.Filter):
    """The console's records: stages.teleop from INFO, our other packages from WARNING."""

    def filter(self, record: logging.LogRecord) -> bool:
        from pipeline._src.chatter import is_own

        if record.name == "stages.teleop" or record.name.startswith("stages.teleop."):
            return True
        return is_own(record.name) and record.levelno >= logging.WARNING


def _logging(out: Path, verbose: bool):
    """Everything to ``out/logs/teleop.log`` (third-party messages once each); the console (the
    original stdout, returned) shows our lines only. Without ``verbose`` the process's stdout and
    stderr file descriptors (Warp's banner and kernel-load lines, C libraries) go to the log file."""
    from pipeline._src.chatter import DedupFilter, capture_process_output

    os.environ.setdefault("TQDM_DISABLE", "1")  # lerobot's merge progress bars
    os.environ.setdefault("HF_DATASETS_DISABLE_PROGRESS_BARS", "1")
    (out / "logs").mkdir(parents=True, exist_ok=True)
    root = logging.getLogger()
    root.setLevel(logging.INFO)
    fh = logging.FileHandler(out / "logs" / "teleop.log")
    fh.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s"))
    fh.addFilter(DedupFilter())
    root.addHandler(fh)
    sys.stdout.flush()
    console = os.fdopen(os.dup(1), "w", buffering=1)
    ch = logging.StreamHandler(console)
    ch.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s" if verbose else "%(message)s"))
    if not verbose:
        ch.addFilter(_ConsoleRecords())
        capture_process_output()
    root.addHandler(ch)
    return console


def main(argv: list[str]) -> int:
    from stages.demos.tasks import TASKS

    p = argparse.ArgumentParser(prog="agentworld teleop",
                                description="teleoperate a task world from a browser and record episodes")
    p.add_argument("task", choices=sorted(TASKS), help="basic task (its instance: robot start, objects)")
    p.add_argument("--robot", default="mobile_panda", help=f"embodiment ({', '.join(ROBOTS)})")
    p.add_argument("--hand", choices=("allegro", "shadow"),
                   help="a dexterous hand instead of the parallel gripper (WebXR fingers retargeted)")
    p.add_argument("--retarget", choices=("dexpilot", "vector"), default="dexpilot",
                   help="dex-retargeting optimizer for --hand")
    p.add_argument("--out", required=True, type=Path, help="output folder: dataset/, shards/, logs/")
    p.add_argument("--replay", type=Path, help="an input log (JSON lines): re-run its saved episodes headless")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (not loopback: HTTPS, self-signed)")
    p.add_argument("--port", type=int, default=8765, help="port (0: any free port)")
    p.add_argument("--device", default="cpu", help="simulation device: cpu or cuda[:n]")
    p.add_argument("--world-seed", type=int, default=5, help="the kitchen's seed")
    p.add_argument("--seed", type=int, default=0, help="seed of the first episode's task instance")
    p.add_argument("--width", type=int, default=160, help="camera image width [px]")
    p.add_argument("--height", type=int, default=120, help="camera image height [px]")
    p.add_argument("--cameras", default="wrist,head,third_person",
                   help="cameras rendered, streamed and recorded (comma-separated; fewer render faster on a CPU)")
    p.add_argument("--episode-seconds", type=float, default=300.0, help="longest recorded episode [s]")
    p.add_argument("--work", type=Path, help="where the kitchen's assets are built (default OUT/.work/world)")
    p.add_argument("--verbose", action="store_true", help="show third-party output on the console too")
    a = p.parse_args(argv)
    if a.robot not in ROBOTS:
        p.error(f"--robot {a.robot!r}: the engine drives {', '.join(ROBOTS)} today")
    cameras = tuple(c.strip() for c in a.cameras.split(",") if c.strip())
    bad = set(cameras) - {"wrist", "head", "third_person"}
    if bad or not cameras:
        p.error(f"--cameras {a.cameras!r}: choose among wrist, head, third_person")
    out = a.out.resolve()
    console = _logging(out, a.verbose)
    log = logging.getLogger("stages.teleop")
    from stages.teleop import TeleopConfig, TeleopSession, read_input_log, replay_session
    from stages.teleop.world import teleop_kitchen

    work = (a.work or out / ".work" / "world").resolve()
    if a.replay is not None:
        try:
            script = read_input_log(a.replay)
        except (OSError, ValueError) as e:
            print(f"agentworld teleop: {e}", file=console)
            return 2
        if script.task != a.task:
            p.error(f"--replay {a.replay}: the log is of task {script.task!r}, not {a.task!r}")
        log.info("building the kitchen (world seed %d) in %s", script.world_seed, work)
        world = teleop_kitchen(work, script.world_seed)
        s = replay_session(script, world, out=out)
        print(f"replayed {len(s.saved)} episode(s) of {a.replay} into {out / 'dataset'}", file=console)
        return 0
    cfg = TeleopConfig(device=a.device, seed=a.seed, width=a.width, height=a.height, cameras=cameras,
                       episode_seconds=a.episode_seconds, hand=a.hand, retarget=a.retarget)
    log.info("building the kitchen (world seed %d) in %s", a.world_seed, work)
    world = teleop_kitchen(work, a.world_seed)
    log.info("building the simulation (%s)", a.device)
    try:
        session = TeleopSession(world, task=a.task, out=out, config=cfg, world_seed=a.world_seed)
    except ValueError as e:
        print(f"agentworld teleop: {e}", file=console)
        return 2
    ssl_context = None
    if a.host not in ("127.0.0.1", "localhost", "::1"):
        from stages.teleop.server import self_signed_context

        ssl_context = self_signed_context(out / ".tls", a.host)
    from stages.teleop.server import serve

    def on_url(url: str) -> None:
        print(f"teleop: open {url}\n(Ctrl-C ends the session; episodes go to {out / 'dataset'})", file=console,
              flush=True)

    try:
        asyncio.run(serve(session, host=a.host, port=a.port, ssl_context=ssl_context, on_url=on_url))
    except KeyboardInterrupt:
        pass
    except (RuntimeError, OSError) as e:  # the session failed (logged with its traceback), or the port
        log.debug("teleop: stopped by an error", exc_info=True)
        print(f"agentworld teleop: {e}; see {out / 'logs' / 'teleop.log'}", file=console)
        return 1
    print(f"teleop: {len(session.saved)} episode(s) saved; input log {session.log_path}", file=console)
    return 0
