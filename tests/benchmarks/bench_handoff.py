"""Benchmark: the engine side of the frame hand-off to a ShardPool (issue 12), on the CPU.

The batched engine records N worlds per frame step: :class:`~stages.engine.capture.FrameCapture`
collects the worlds' state and actions after the programs ran, then delivers each world's frame
(3 cameras, RGB + depth, views of the render's read-back buffers) to its episode's sink, a shard of
a :class:`~stages.dataset.pool.ShardPool` whose writer processes encode it. That hand-off runs in the
engine's single thread and was its largest share of the wall on the GPU host (~0.7 ms per frame).

This benchmark opens a real ShardPool with the demos' DatasetSpec (3 cameras at 240x320, RGB +
depth; one shard per world), keeps N worlds' images in reused buffers shaped as the render's
(``CameraRig.render_compact``: camera -> RGB (N, H, W, 3) uint8, depth (N, H, W) uint16 [mm]) and
hands every world's frame over at each of ``--steps`` frame steps, timing the engine side alone:

- ``cpu_ms_per_frame``: the engine thread's CPU time (``time.thread_time``) in collect + deliver per
  frame (medians over steps): what the hand-off costs, whatever the writers do;
- ``wall_ms_per_frame``: wall time in collect + deliver less ``ShardPool.wait_s`` (the time spent
  waiting for a free slot, i.e. for the writers) per frame;
- ``wait_s``: total time waiting for the writers (on a 2-core machine they are far behind: the
  writers' speed is not what this measures).

Modes: ``legacy`` replays the engine's code before session 15 (one :class:`~stages.dataset.Frame`
per world built at collect, one ``sink(frame)`` per world at deliver, ``ShardPool.add_frame`` each);
``per_frame`` runs today's capture code with plain sinks (no pool behind them: per-world frames,
what other sinks get); ``batched`` runs today's capture code with the pool's sinks (one hand-over per
writer per frame step). Writes ``bench_results/handoff.json``::

    python tests/benchmarks/bench_handoff.py --worlds 256 --steps 6 --writer-procs 2
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

CAMERAS = ("wrist", "head", "third_person")


def _spec(height: int, width: int):
    from stages.dataset import CameraSpec, DatasetSpec

    return DatasetSpec(cameras=tuple(CameraSpec(c, height=height, width=width) for c in CAMERAS))


def _images(n: int, height: int, width: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Smooth per-world content (x264 works as on rendered frames), one buffer per camera."""
    yy, xx = np.mgrid[0:height, 0:width]
    out = {}
    for k, cam in enumerate(CAMERAS):
        rgb = np.empty((n, height, width, 3), np.uint8)
        base = (128 + 100 * np.sin(2 * np.pi * (xx / width + k / 3))).astype(np.uint8)
        rgb[..., 0] = base
        rgb[..., 1] = (128 + 100 * np.cos(2 * np.pi * yy / height)).astype(np.uint8)
        rgb[..., 2] = (np.arange(n) * 7 % 200)[:, None, None]
        depth = np.broadcast_to((500 + xx * 3 + yy * 5).astype(np.uint16), (n, height, width)).copy()
        out[cam] = (rgb, depth)
    return out


def _move(images, step: int) -> None:
    """What changes between frames: a square moving in every world's images."""
    for rgb, depth in images.values():
        h, w = rgb.shape[1:3]
        s = h // 6
        y, x = (7 * step) % (h - s), (11 * step) % (w - s)
        rgb[:, y:y + s, x:x + s] = 255 - rgb[:, y:y + s, x:x + s]
        depth[:, y:y + s, x:x + s] += 1


def _state(k: int, step: int) -> dict[str, np.ndarray]:
    """The columns the engine's collect reads for ``k`` worlds (what its state read and commands give)."""
    a = np.arange(k)[:, None] * 0.001 + step * 0.01
    quat = np.zeros((2 * k, 4))
    quat[:, 0] = np.cos(a.repeat(2, 0)[:, 0])
    quat[:, 3] = np.sin(a.repeat(2, 0)[:, 0])
    ee = np.concatenate([np.full((2 * k, 3), 0.4), quat], axis=1)
    return {"q": a + np.arange(7) * 0.1, "t": a + 0.05 + np.arange(7) * 0.1, "base": a + np.arange(3),
            "ee": ee, "hand_q": np.zeros((k, 0)), "hand_t": np.zeros((k, 0)), "base_v": a * np.ones(3),
            "grip": (np.arange(k) % 2).astype(float), "mode": np.arange(k) % 2,
            "subtask": np.zeros(k, np.int64)}


def _legacy_collect(st, sinks) -> list:
    """FrameCapture.collect before session 15: one Frame per recording world."""
    from stages.dataset import Frame

    k = len(sinks)
    grip, mode = st["grip"].tolist(), st["mode"].astype(int).tolist()
    frames = []
    for j in range(k):
        state = dict(arm_joint_pos=st["q"][j], ee_pose=st["ee"][j], base_pose=st["base"][j],
                     arm_joint_target=st["t"][j], ee_target=st["ee"][k + j], base_velocity=st["base_v"][j],
                     gripper=grip[j], mode=mode[j], hand_joint_pos=st["hand_q"][j], hand_joint_target=st["hand_t"][j])
        frames.append((sinks[j], 0, j, Frame(**state, rgb={}, depth_mm={}, subtask_index=int(st["subtask"][j]))))
    return frames


def _legacy_deliver(frames, images) -> None:
    """FrameCapture.deliver before session 15: views of the buffers attached, one sink call per world."""
    for sink, _bid, i, frame in frames:
        views = getattr(sink, "takes_views", False)
        for name, im in images.items():
            frame.rgb[name] = im[0][i] if views else im[0][i].copy()
            frame.depth_mm[name] = im[1][i] if views else im[1][i].copy()
        sink(frame)


def _capture_collect(st, sinks):
    from stages.engine.capture import collected

    k = len(sinks)
    fields = {"arm_joint_pos": st["q"], "ee_pose": st["ee"][:k], "base_pose": st["base"],
              "arm_joint_target": st["t"], "ee_target": st["ee"][k:], "base_velocity": st["base_v"],
              "gripper": st["grip"], "mode": st["mode"], "hand_joint_pos": st["hand_q"],
              "hand_joint_target": st["hand_t"], "subtask_index": st["subtask"]}
    return collected(sinks, [0] * k, list(range(k)), fields)


def _capture_deliver(pending, images) -> None:
    from stages.engine.capture import hand_over

    hand_over(pending, {0: images})


def run_mode(mode: str, args, work: Path) -> dict:
    from stages.dataset import EpisodeInfo
    from stages.dataset.pool import PoolConfig, ShardPool

    spec = _spec(args.height, args.width)
    n = args.worlds
    images = _images(n, args.height, args.width)
    root = work / mode
    shutil.rmtree(root, ignore_errors=True)
    pool = ShardPool(root, [f"w{i:04d}" for i in range(n)], spec,
                     PoolConfig(workers=args.writer_procs, slots=args.slots)).open()
    pool.wait_ready()
    for i in range(n):
        pool.begin_episode(i, EpisodeInfo(task="hand off", task_kind="press_button", scene_id="bench",
                                          seed=i, asset_ids=()))
    if mode == "batched":
        sinks = [pool.sink(i) for i in range(n)]
    else:
        def plain(i):
            def sink(frame):  # a sink that is not the pool's own: per-world frames
                pool.add_frame(i, frame)
            sink.takes_views = True
            return sink
        sinks = [plain(i) for i in range(n)]
    collect, deliver = ((_legacy_collect, _legacy_deliver) if mode == "legacy"
                        else (_capture_collect, _capture_deliver))
    cpu, wall, waits = [], [], []
    for step in range(args.warmup + args.steps):
        time.sleep(args.gap)  # the engine busy elsewhere (physics, programs): the writers catch up
        _move(images, step)
        st = _state(n, step)
        w0, c0, t0 = pool.wait_s, time.thread_time(), time.perf_counter()
        pending = collect(st, sinks)
        deliver(pending, images)
        c1, t1 = time.thread_time(), time.perf_counter()
        if step >= args.warmup:
            cpu.append(c1 - c0)
            wall.append(t1 - t0 - (pool.wait_s - w0))
            waits.append(pool.wait_s - w0)
    for i in range(n):
        pool.end_episode(i, success=True)
    t = time.perf_counter()
    stats = pool.close()
    close_s = time.perf_counter() - t
    frames = sum(s["frames"] for s in stats.values())
    if frames != n * (args.warmup + args.steps):
        raise RuntimeError(f"bench_handoff {mode}: {frames} frames written, expected {n * (args.warmup + args.steps)}")
    shutil.rmtree(root, ignore_errors=True)
    res = {"mode": mode, "worlds": n, "steps": args.steps, "slots": args.slots, "frames_written": frames,
           "cpu_ms_per_frame": round(1000 * statistics.median(cpu) / n, 4),
           "wall_ms_per_frame": round(1000 * statistics.median(wall) / n, 4),
           "cpu_ms_per_frame_all": [round(1000 * c / n, 4) for c in cpu],
           "wait_s": round(sum(waits), 3), "close_s": round(close_s, 2)}
    print(json.dumps(res), flush=True)
    return res


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--worlds", type=int, default=256)
    p.add_argument("--steps", type=int, default=6, help="timed frame steps (all worlds each)")
    p.add_argument("--warmup", type=int, default=1)
    p.add_argument("--height", type=int, default=240)
    p.add_argument("--width", type=int, default=320)
    p.add_argument("--writer-procs", type=int, default=2)
    p.add_argument("--slots", type=int, default=32, help="PoolConfig.slots (frames in flight per writer)")
    p.add_argument("--gap", type=float, default=0.0,
                   help="[s] between frame steps, the engine's other work (simulation, programs), when the "
                        "writers catch up: with it, wait_s shows whether the ring absorbs a step's burst")
    p.add_argument("--modes", nargs="+", default=["legacy", "per_frame", "batched"],
                   choices=("legacy", "per_frame", "batched"))
    p.add_argument("--out", type=Path, default=REPO / "bench_results" / "handoff.json")
    args = p.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="bench-handoff-"))
    try:
        results = [run_mode(m, args, work) for m in args.modes]
    finally:
        shutil.rmtree(work, ignore_errors=True)
    doc = {"size": [args.height, args.width], "cameras": len(CAMERAS), "writer_procs": args.writer_procs,
           "slots": args.slots, "gap_s": args.gap, "results": results}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1))
    return doc


@pytest.mark.benchmark
def test_bench_handoff():
    doc = main(["--worlds", "8", "--steps", "2", "--height", "48", "--width", "64", "--writer-procs", "1"])
    assert all(r["frames_written"] == 8 * 3 for r in doc["results"])


if __name__ == "__main__":
    main()
