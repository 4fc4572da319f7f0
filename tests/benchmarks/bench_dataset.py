"""Dataset writing speed: frames/s of the shard writer at 320x240 with 3 RGB cameras + depth.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_dataset.py -s``
(``BENCH_DATASET_WORKERS=1,4,8,16`` sets the writer counts of the parallel-writers test).
Prints the figures and writes ``bench_results/dataset.json`` (medians over REPEATS runs of EPISODES
episodes of FRAMES frames, one writer process; frames are precomputed, so only writing is timed).

Configurations, each with both writer backends (``direct``: stages.dataset.direct; ``lerobot``:
LeRobotDataset.create/add_frame/save_episode/finalize). The split between encoding and parquet
writing comes from writing each part alone:

- ``full``: 3 RGB videos (h264 ultrafast, crf 23, GOP 30) + 3 lossless depth images + state/action;
- ``rgb_only``: the 3 RGB videos + state/action (video encoding, image stats);
- ``depth_only``: the 3 depth images + state/action (depth encoding, parquet, stats);
- ``state_only``: state/action only (parquet and metadata bookkeeping);
- ``full_one_depth``: 3 RGB videos + depth of the head camera only;
- ``full_av1_default``: like ``full`` with lerobot's default codec (libsvtav1 preset 12, GOP 2, crf 30);
- ``encode_only``: PyAV alone encoding the same 3 RGB streams with the ``full`` settings, in one
  thread, no writer: an upper bound for the video part.

Cost of one recorded timestep per CPU core (``test_bench_timestep_cost``, or
``python tests/benchmarks/bench_dataset.py --timestep --frames 60 --episodes 2 --repeats 3``): CPU
time (``time.process_time``: every thread of the process, so the encoder threads count) of one
writer writing ``episodes`` x ``frames`` timesteps of 3 cameras 240x320 with render-like content
(RGB: ``bench_encode.render_like_frames``; depth: :func:`render_like_depth`, a noise-free
ray-traced room in mm), split by writing each part alone (``rgb`` = rgb_only - state_only,
``depth`` = depth_only - state_only, ``numeric`` = state_only: columns, parquet, stats, metadata),
plus ``validation`` (one ``validate_frame``), the engine side of a ``ShardPool`` (its thread's CPU
in ``add_frame``: validation + copy into shared memory + the pipe) and the pool's writer process
(its CPU, start-up subtracted). Medians of ``repeats``; writes ``bench_results/dataset_timestep.json``.
"""

from __future__ import annotations

import atexit
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from fractions import Fraction
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))
os.environ.setdefault("HF_HUB_OFFLINE", "1")
if "HF_DATASETS_CACHE" not in os.environ:  # LeRobotDataset caches arrow copies of the parquet files there
    os.environ["HF_DATASETS_CACHE"] = tempfile.mkdtemp(prefix="hf-datasets-cache-")
    atexit.register(shutil.rmtree, os.environ["HF_DATASETS_CACHE"], True)

from stages.dataset.schema import CameraSpec, DatasetSpec, VideoCodecSpec  # noqa: E402
from stages.dataset.shards import open_shard  # noqa: E402
from stages.dataset.synthetic import synthetic_episode_info, synthetic_frame  # noqa: E402

H, W = 240, 320
EPISODES, FRAMES, REPEATS = 2, 90, 3
CAMS = ("wrist", "head", "third_person")


def _spec(rgb: bool, depth: bool | tuple[str, ...], video: VideoCodecSpec | None = None) -> DatasetSpec:
    cams = []
    for name in CAMS:
        d = depth if isinstance(depth, bool) else name in depth
        if rgb or d:
            cams.append(CameraSpec(name, H, W, rgb=rgb, depth=d))
    return DatasetSpec(cameras=tuple(cams), video=video or VideoCodecSpec())


SPECS = {
    "full": _spec(True, True),
    "rgb_only": _spec(True, False),
    "depth_only": _spec(False, True),
    "state_only": _spec(False, False),
    "full_one_depth": _spec(True, ("head",)),
    "full_av1_default": _spec(True, True, VideoCodecSpec(codec="libsvtav1", preset=12, crf=30, gop=2)),
}
CONFIGS = {
    f"{name}/{backend}": (spec, backend) for backend in ("direct", "lerobot") for name, spec in SPECS.items()
}


def _folder_mb(path: Path, sub: str) -> float:
    return sum(f.stat().st_size for f in (path / sub).rglob("*") if f.is_file()) / 2**20


def _write_episodes(shard, frames: list, episodes: int, index: int = 0) -> None:
    """``episodes`` successful episodes of ``frames`` into an open shard (episode info of writer ``index``)."""
    for e in range(episodes):
        shard.begin_episode(synthetic_episode_info(index, e))
        for f in frames:
            shard.add_frame(f)
        shard.end_episode(success=True)


def _write_once(spec: DatasetSpec, backend: str, frames: list, base: Path) -> dict:
    shutil.rmtree(base, ignore_errors=True)
    t0 = time.perf_counter()
    with open_shard(base, "bench", spec, backend=backend) as shard:
        _write_episodes(shard, frames, EPISODES)
    wall = time.perf_counter() - t0
    n = EPISODES * len(frames)
    return {
        "fps": n / wall, "wall_s": wall, "add_frame_s": shard.stats.add_frame_s,
        "save_episode_s": shard.stats.save_episode_s, "close_s": shard.stats.finalize_s,
        "data_kb_per_frame": _folder_mb(base / "bench", "data") * 1024 / n,
        "video_kb_per_frame": _folder_mb(base / "bench", "videos") * 1024 / n,
    }  # fmt: skip


def _encode_only(frames: list, video: VideoCodecSpec) -> float:
    """frames/s of PyAV encoding the 3 RGB streams (one after another, libx264 with 1 thread)."""
    import av

    opts = {"g": str(video.gop), "crf": str(video.crf), "preset": str(video.preset), "threads": "1"}
    tmp = Path(tempfile.mkdtemp())
    t0 = time.perf_counter()
    for cam in CAMS:
        with av.open(str(tmp / f"{cam}.mp4"), "w") as out:
            stream = out.add_stream(video.codec, 30, options=opts)
            stream.pix_fmt, stream.width, stream.height = video.pix_fmt, W, H
            stream.time_base = Fraction(1, 30)
            for i, f in enumerate(frames * EPISODES):
                vf = av.VideoFrame.from_ndarray(f.rgb[cam], format="rgb24")
                vf.pts = i
                for packet in stream.encode(vf):
                    out.mux(packet)
            for packet in stream.encode():
                out.mux(packet)
    wall = time.perf_counter() - t0
    shutil.rmtree(tmp)
    return EPISODES * len(frames) / wall


@pytest.mark.benchmark
def test_bench_dataset_writing(tmp_path):
    full = SPECS["full"]
    frames_by_spec = {}
    results = {}
    for name, (spec, backend) in CONFIGS.items():
        key = tuple(spec.cameras)
        if key not in frames_by_spec:
            frames_by_spec[key] = [synthetic_frame(spec, 0, 0, i) for i in range(FRAMES)]
        folder = tmp_path / name.replace("/", "-")
        runs = [_write_once(spec, backend, frames_by_spec[key], folder) for _ in range(REPEATS)]
        results[name] = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    full_frames = [synthetic_frame(full, 0, 0, i) for i in range(FRAMES)]
    encode = [_encode_only(full_frames, full.video) for _ in range(REPEATS)]
    results["encode_only"] = {"fps": statistics.median(encode)}

    ms = {k: 1000.0 / v["fps"] for k, v in results.items()}
    split = {
        b: {
            "video_encoding_ms": ms[f"rgb_only/{b}"] - ms[f"state_only/{b}"],
            "depth_parquet_ms": ms[f"depth_only/{b}"] - ms[f"state_only/{b}"],
            "state_parquet_ms": ms[f"state_only/{b}"],
            "full_ms": ms[f"full/{b}"],
        }
        for b in ("direct", "lerobot")
    }
    out = {
        "resolution": [H, W], "cameras": len(CAMS), "episodes": EPISODES, "frames_per_episode": FRAMES,
        "repeats": REPEATS, "cpu_count": os.cpu_count(), "configs": results, "split_ms_per_frame": split,
    }  # fmt: skip
    print(f"\ndataset writing, {H}x{W}, {len(CAMS)} cameras, {EPISODES}x{FRAMES} frames, "
          f"median of {REPEATS}:")
    for name, r in results.items():
        extra = ""
        if "wall_s" in r:
            extra = (f"  add {r['add_frame_s']:.2f}s save {r['save_episode_s']:.2f}s"
                     f" close {r['close_s']:.2f}s"
                     f"  data {r['data_kb_per_frame']:.0f} KB/frame"
                     f" video {r['video_kb_per_frame']:.1f} KB/frame")
        print(f"  {name:26s} {r['fps']:7.1f} frames/s{extra}")
    for b, sp in split.items():
        print(f"  split per frame [ms], {b}: " + ", ".join(f"{k} {v:.1f}" for k, v in sp.items()))
    dest = REPO / "bench_results" / "dataset.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2))
    assert results["encode_only"]["fps"] > results["full/direct"]["fps"] > 0


def _parallel_worker(shards_dir: str, index: int, episodes: int, barrier, results) -> None:
    """One writer process: import and precompute, wait for all, write a ``full`` shard, report times."""
    from stages.dataset.writer import import_lerobot

    import_lerobot()
    spec = SPECS["full"]
    frames = [synthetic_frame(spec, index, 0, i) for i in range(FRAMES)]
    barrier.wait()
    t0 = time.time()
    with open_shard(Path(shards_dir), f"w{index:02d}", spec) as shard:
        _write_episodes(shard, frames, episodes, index)
    results.put((t0, time.time(), episodes * len(frames)))


@pytest.mark.benchmark
def test_bench_parallel_shard_writers(tmp_path):
    """Aggregate frames/s of N concurrent shard writers (``full`` spec, direct backend).

    N from ``BENCH_DATASET_WORKERS`` (comma-separated, default ``1,2``); each writes EPISODES episodes
    of FRAMES frames; wall time from the common start (a barrier after imports) to the last finish."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    counts = [int(x) for x in os.environ.get("BENCH_DATASET_WORKERS", "1,2").split(",")]
    out = {"cpu_count": os.cpu_count(), "frames_per_worker": EPISODES * FRAMES, "workers": {}}
    print(f"\nparallel shard writers ({H}x{W}, 3 RGB + 3 depth, direct backend), {os.cpu_count()} CPUs:")
    for n in counts:
        barrier, results = ctx.Barrier(n), ctx.Queue()
        shards = tmp_path / f"n{n}"
        procs = [ctx.Process(target=_parallel_worker, args=(str(shards), k, EPISODES, barrier, results))
                 for k in range(n)]  # fmt: skip
        for p in procs:
            p.start()
        rows = [results.get(timeout=600) for _ in procs]
        for p in procs:
            p.join()
            assert p.exitcode == 0
        wall = max(r[1] for r in rows) - min(r[0] for r in rows)
        total = sum(r[2] for r in rows)
        out["workers"][n] = {"frames_per_s": total / wall, "per_worker_frames_per_s": total / wall / n,
                             "wall_s": wall}  # fmt: skip
        print(f"  {n:3d} writers: {total / wall:8.1f} frames/s ({total / wall / n:6.1f} per writer)")
        shutil.rmtree(shards)
    dest = REPO / "bench_results" / "dataset_parallel.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2))
    assert all(v["frames_per_s"] > 0 for v in out["workers"].values())


# -- cost of one recorded timestep per CPU core ---------------------------------------------------


def render_like_depth(n: int, h: int, w: int, seed: int = 0) -> list:
    """uint16 (h, w) [mm] x n: what the ray tracer gives (no noise): a floor receding to a wall at
    2.5-3.5 m and a few moving spheres in front, panning with the camera."""
    import numpy as np

    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    balls = [(rng.uniform(0, w), rng.uniform(0.5 * h, h), rng.uniform(-3, 3), rng.uniform(10, 40),
              rng.uniform(600, 2000)) for _ in range(5)]  # fmt: skip
    out = []
    for i in range(n):
        horizon = 0.4 * h + 5 * np.sin(i / 15.0)
        wall = 3000.0 + 500.0 * np.sin((xx + 2 * i) / w * 3.0)
        floor = 1200.0 * h / np.maximum(yy - horizon, 1.0) / 4.0
        d = np.where(yy > horizon, np.minimum(floor, wall), wall)
        for cx, cy, vx, r, z in balls:
            d2 = (xx - (cx + vx * i) % w) ** 2 + (yy - cy) ** 2
            inside = d2 < r * r
            d[inside] = np.minimum(d[inside], z - 2.0 * np.sqrt(r * r - d2[inside]))
        out.append(np.rint(d).clip(0, 65535).astype(np.uint16))
    return out


def render_like_frames_for(spec: DatasetSpec, n: int) -> list:
    """``n`` frames of ``spec``: render-like images per camera, numbers of ``synthetic_frame``."""
    import dataclasses

    if str(Path(__file__).parent) not in sys.path:
        sys.path.insert(0, str(Path(__file__).parent))
    from bench_encode import render_like_frames  # a sibling benchmark module

    rgb = {c.name: render_like_frames(n, c.height, c.width, seed=k)
           for k, c in enumerate(spec.cameras) if c.rgb}  # fmt: skip
    depth = {c.name: render_like_depth(n, c.height, c.width, seed=k) for k, c in enumerate(spec.cameras)
             if c.depth}  # fmt: skip
    return [dataclasses.replace(synthetic_frame(spec, 0, 0, i), rgb={k: v[i] for k, v in rgb.items()},
                                depth_mm={k: v[i] for k, v in depth.items()}) for i in range(n)]  # fmt: skip


def _cpu_write(spec: DatasetSpec, frames: list, base: Path, episodes: int) -> float:
    """CPU seconds (all threads) per timestep of one inline shard writer (open to close)."""
    shutil.rmtree(base, ignore_errors=True)
    t0 = time.process_time()
    with open_shard(base, "bench", spec) as shard:
        _write_episodes(shard, frames, episodes)
    cpu = time.process_time() - t0
    shutil.rmtree(base, ignore_errors=True)
    return cpu / (episodes * len(frames))


def _children_cpu() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _cpu_pool(spec: DatasetSpec, frames: list, base: Path, episodes: int,
              shards: int = 4) -> tuple[float, float]:  # fmt: skip
    """(engine-side CPU s per timestep in ``ShardPool.add_frame``, writer-process CPU s per timestep
    with its start-up subtracted) of a pool of one writer process and ``shards`` shards."""
    from stages.dataset.pool import PoolConfig, ShardPool

    def once(n_frames: int) -> tuple[float, float]:
        shutil.rmtree(base, ignore_errors=True)
        c0, engine = _children_cpu(), 0.0
        with ShardPool(base, [f"s{k}" for k in range(shards)], spec, PoolConfig(workers=1)) as pool:
            pool.wait_ready()
            for e in range(episodes):
                for k in range(shards):
                    pool.begin_episode(k, synthetic_episode_info(k, e))
                for f in frames[:n_frames]:
                    for k in range(shards):
                        t = time.thread_time()
                        pool.add_frame(k, f)
                        engine += time.thread_time() - t
                for k in range(shards):
                    pool.end_episode(k, success=n_frames > 0)
        for p in mp_children():
            p.join()
        shutil.rmtree(base, ignore_errors=True)
        return engine, _children_cpu() - c0

    _, startup = once(0)
    engine, worker = once(len(frames))
    n = episodes * len(frames) * shards
    return engine / n, (worker - startup) / n


def mp_children() -> list:
    import multiprocessing as mp

    return mp.active_children()


def timestep_cost(frames: int = 60, episodes: int = 2, repeats: int = REPEATS, pool: bool = True) -> dict:
    """CPU ms per timestep (module docstring), medians of ``repeats``; writes dataset_timestep.json."""
    from stages.dataset.schema import validate_frame

    base = Path(tempfile.mkdtemp(prefix="bench-timestep-"))
    full = SPECS["full"]
    import dataclasses

    fr = render_like_frames_for(full, frames)  # the other specs take the same frames' parts
    per_spec = {"full": fr, "rgb_only": [dataclasses.replace(f, depth_mm={}) for f in fr],
                "depth_only": [dataclasses.replace(f, rgb={}) for f in fr],
                "state_only": [dataclasses.replace(f, rgb={}, depth_mm={}) for f in fr]}
    _cpu_write(full, per_spec["full"][:2], base / "warm", 1)  # imports (lerobot, PyAV) are not writing
    parts = ("full", "rgb_only", "depth_only", "state_only", "validation", "pool_engine", "pool_writer")
    runs: dict[str, list[float]] = {k: [] for k in parts}
    for _ in range(repeats):  # interleaved, so that a busy moment of the machine hits every part alike
        for name, fr in per_spec.items():
            runs[name].append(_cpu_write(SPECS[name], fr, base / name, episodes))
        t = time.process_time()
        for f in per_spec["full"]:
            validate_frame(full, f)
        runs["validation"].append((time.process_time() - t) / frames)
        if pool:
            e, w = _cpu_pool(full, per_spec["full"], base / "pool", episodes)
            runs["pool_engine"].append(e)
            runs["pool_writer"].append(w)
    shutil.rmtree(base, ignore_errors=True)
    med = {k: 1000.0 * statistics.median(v) for k, v in runs.items() if v}
    split = {"rgb_video": med["rgb_only"] - med["state_only"],
             "depth_png": med["depth_only"] - med["state_only"],
             "numeric_parquet": med["state_only"], "validation": med["validation"]}  # fmt: skip
    if pool:
        split["pool_engine_side"] = med["pool_engine"]
    out = {"resolution": [H, W], "cameras": len(CAMS), "frames_per_episode": frames, "episodes": episodes,
           "repeats": repeats, "cpu_count": os.cpu_count(), "cpu_ms_per_timestep": med, "split_ms": split,
           "inline_writer_timesteps_per_core_s": 1000.0 / med["full"],
           **({"pool_writer_timesteps_per_core_s": 1000.0 / med["pool_writer"]} if pool else {})}  # fmt: skip
    print(f"\nCPU ms per timestep ({H}x{W}, {len(CAMS)} cameras RGB + depth, {episodes}x{frames} frames, "
          f"median of {repeats}):")
    for k, v in med.items():
        print(f"  {k:12s} {v:7.2f} ms")
    print("  split: " + ", ".join(f"{k} {v:.2f}" for k, v in split.items()))
    pool_rate = out.get("pool_writer_timesteps_per_core_s")
    print(f"  one core: inline writer {out['inline_writer_timesteps_per_core_s']:.0f} timesteps/s"
          + (f", pool writer process {pool_rate:.0f} timesteps/s" if pool else ""))
    dest = REPO / "bench_results" / "dataset_timestep.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2))
    return out


def test_render_like_depth_is_a_room_in_millimetres():
    d = render_like_depth(3, 60, 80)
    assert d[0].dtype.name == "uint16" and d[0].shape == (60, 80)
    assert 300 < d[0].min() and d[0].max() < 10000 and (d[0] != d[2]).any()


@pytest.mark.benchmark
def test_bench_timestep_cost():
    out = timestep_cost(frames=30, episodes=2, repeats=1)
    assert out["cpu_ms_per_timestep"]["full"] > 0


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--timestep", action="store_true", help="the CPU cost of one timestep (only mode here)")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=REPEATS)
    ap.add_argument("--no-pool", action="store_true")
    a = ap.parse_args()
    timestep_cost(a.frames, a.episodes, a.repeats, pool=not a.no_pool)
