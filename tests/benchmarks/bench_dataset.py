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


def _write_once(spec: DatasetSpec, backend: str, frames: list, base: Path) -> dict:
    shutil.rmtree(base, ignore_errors=True)
    t0 = time.perf_counter()
    with open_shard(base, "bench", spec, backend=backend) as shard:
        for e in range(EPISODES):
            shard.begin_episode(synthetic_episode_info(0, e))
            for f in frames:
                shard.add_frame(f)
            shard.end_episode(success=True)
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
        for e in range(episodes):
            shard.begin_episode(synthetic_episode_info(index, e))
            for f in frames:
                shard.add_frame(f)
            shard.end_episode(success=True)
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
