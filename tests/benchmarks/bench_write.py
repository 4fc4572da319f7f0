"""Writing recorded frames into real LeRobot shards: CPU ms per timestep and timesteps/s per writer process.

Run: ``python tests/benchmarks/bench_write.py [--writer-procs 3] [--shards 256] [--frames 30]
[--baseline /path/to/older/checkout] [--repeats 3]`` (or ``-m benchmark``, short). Writes
``bench_results/write.json``.

A timestep is 3 cameras of 240x320, RGB + depth (render-like content: ``bench_encode.render_like_frames``
and ``bench_dataset.render_like_depth``), plus its parquet row. Two patterns, each in a fresh process:

- ``steady``: one inline shard writer (``open_shard``, the engine's ``--writer-procs 0``) writing
  ``--episodes`` episodes of ``--steady-frames`` frames: the per-frame cost with the per-episode and
  per-shard costs spread thin. CPU of the whole process (``time.process_time``: the encoder and
  depth threads count), opening to publishing.
- ``interleaved``: the engine's pattern (``bench_engine.py --write``): ``--shards`` shards (one per
  world) in a :class:`~stages.dataset.pool.ShardPool` of ``--writer-procs`` processes, one episode of
  ``--frames`` frames each, handed over one frame per shard in turn, then every shard closed and
  published. Writer CPU = the pool processes' CPU (``RUSAGE_CHILDREN`` after they exit) minus their
  CPU when every shard was open (``/proc/<pid>/stat``: process start, imports, opening); the engine
  side is the calling thread's CPU in ``add_frame`` (validation, copy into shared memory, pipe).
  ``timesteps/s per writer process`` = timesteps / writer CPU seconds: what one core of writing
  sustains; the wall rate depends on the machine's free cores and is printed beside it.

``--baseline DIR`` runs every measurement also with the code of DIR (another checkout of this
repository: ``git worktree add /tmp/base main``), alternating the two per repeat, and prints the
medians of both and their ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
H, W, CAMS = 240, 320, ("wrist", "head", "third_person")
CLK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _frames(n: int) -> list:
    """``n`` render-like frames of the ``full`` spec (3 cameras RGB + depth)."""
    from bench_dataset import SPECS, render_like_frames_for  # the measured tree's (see _child)

    return render_like_frames_for(SPECS["full"], n)


def _proc_cpu(pid: int) -> float:
    """CPU seconds (user + system) of a live process, from /proc/<pid>/stat."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK


def _children_cpu() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def measure_steady(frames_per_episode: int, episodes: int, work: Path) -> dict:
    """One inline shard writer: CPU ms per timestep (module docstring)."""
    from stages.dataset.shards import open_shard
    from stages.dataset.synthetic import synthetic_episode_info
    from bench_dataset import SPECS

    spec = SPECS["full"]
    frames = _frames(min(frames_per_episode, 60))
    with open_shard(work, "warm", spec) as s:  # imports (lerobot, PyAV, OpenCV) are not writing
        s.begin_episode(synthetic_episode_info(0, 0))
        s.add_frame(frames[0])
        s.end_episode(success=True)
    c0, t0 = time.process_time(), time.perf_counter()
    with open_shard(work, "steady", spec) as shard:
        for e in range(episodes):
            shard.begin_episode(synthetic_episode_info(0, e))
            for i in range(frames_per_episode):
                shard.add_frame(frames[i % len(frames)])
            shard.end_episode(success=True)
    n = episodes * frames_per_episode
    return {"timesteps": n, "cpu_ms_per_timestep": 1000 * (time.process_time() - c0) / n,
            "wall_s": time.perf_counter() - t0}  # fmt: skip


def measure_interleaved(shards: int, frames_per_shard: int, procs: int, work: Path) -> dict:
    """``shards`` shards written by a pool of ``procs`` processes, one frame per shard in turn."""
    import multiprocessing as mp

    from stages.dataset.pool import PoolConfig, ShardPool
    from stages.dataset.synthetic import synthetic_episode_info
    from bench_dataset import SPECS

    spec = SPECS["full"]
    frames = _frames(min(frames_per_shard, 60))
    c_before = _children_cpu()
    pool = ShardPool(work, [f"w{i:04d}" for i in range(shards)], spec, PoolConfig(workers=procs)).open()
    pool.wait_ready()
    startup = sum(_proc_cpu(w.proc.pid) for w in pool._workers)
    t0, engine = time.perf_counter(), 0.0
    for i in range(shards):
        pool.begin_episode(i, synthetic_episode_info(i, 0))
    for k in range(frames_per_shard):
        f = frames[k % len(frames)]
        for i in range(shards):
            t = time.thread_time()
            pool.add_frame(i, f)
            engine += time.thread_time() - t
    for i in range(shards):
        pool.end_episode(i, success=True)
    pool.close()
    wall = time.perf_counter() - t0
    for p in mp.active_children():
        p.join()
    writer = _children_cpu() - c_before - startup
    n = shards * frames_per_shard
    return {"timesteps": n, "cpu_ms_per_timestep": 1000 * writer / n,
            "engine_ms_per_timestep": 1000 * engine / n, "wall_s": wall, "wall_timesteps_per_s": n / wall,
            "wait_s": pool.wait_s}  # fmt: skip


def _child(argv: list[str]) -> None:
    """Entry of one measurement process (``stages`` and ``bench_dataset`` imported from the measured
    tree, which heads ``sys.path``): prints one JSON line."""
    kind, work = argv[0], Path(argv[1])
    nums = [int(x) for x in argv[2:]]
    out = measure_steady(*nums, work) if kind == "steady" else measure_interleaved(*nums, work)
    print("RESULT " + json.dumps(out), flush=True)


def _run(tree: Path, kind: str, nums: list[int]) -> dict:
    """One measurement in a fresh process importing the code of ``tree``."""
    with tempfile.TemporaryDirectory(prefix="bench-write-") as tmp:
        env = {**os.environ, "BENCH_WRITE_TREE": str(tree), "SVT_LOG": "1", "HF_HUB_OFFLINE": "1"}
        env.pop("PYTHONPATH", None)
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", kind, tmp, *map(str, nums)]
        proc = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, timeout=3600)
        lines = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
        if proc.returncode != 0 or not lines:
            raise RuntimeError(f"{tree}: {kind} measurement failed: {proc.stderr.strip()[-2000:]}")
        return json.loads(lines[-1][len("RESULT "):])


def run(*, procs: int = 3, shards: int = 256, frames: int = 30, steady_frames: int = 300,
        episodes: int = 2, repeats: int = 3, baseline: Path | None = None,
        patterns=("steady", "interleaved")) -> dict:  # fmt: skip
    """Measure ``patterns`` (module docstring) ``repeats`` times; print and write the medians."""
    trees = {"this": REPO, **({"baseline": Path(baseline).resolve()} if baseline else {})}
    args = {"steady": [steady_frames, episodes], "interleaved": [shards, frames, procs]}
    runs: dict[str, dict[str, list[dict]]] = {t: {p: [] for p in patterns} for t in trees}
    for r in range(repeats):  # alternating, so that a busy moment of the machine hits both trees alike
        for p in patterns:
            for t, tree in (trees.items() if r % 2 == 0 else reversed(trees.items())):
                runs[t][p].append(_run(tree, p, args[p]))
                ms = runs[t][p][-1]["cpu_ms_per_timestep"]
                print(f"  [{r + 1}/{repeats}] {t:8s} {p:11s} {ms:6.2f} ms/timestep", flush=True)
    med = {t: {p: {k: statistics.median(x[k] for x in v) for k in v[0]} for p, v in ps.items()}
           for t, ps in runs.items()}  # fmt: skip
    for ps in med.values():
        for m in ps.values():
            m["timesteps_per_s_per_writer_process"] = 1000.0 / m["cpu_ms_per_timestep"]
    out = {"resolution": [H, W], "cameras": len(CAMS), "streams": "RGB (h264 ultrafast) + depth (16-bit PNG)",
           "writer_procs": procs, "shards": shards, "frames_per_shard": frames,
           "steady_frames": steady_frames, "steady_episodes": episodes, "repeats": repeats,
           "cpu_count": os.cpu_count(),
           "trees": {t: str(p) for t, p in trees.items()}, "median": med, "runs": runs}  # fmt: skip
    print(f"\nwriting {H}x{W}, {len(CAMS)} cameras RGB + depth; medians of {repeats} "
          f"({os.cpu_count()} CPUs):")
    for t, ps in med.items():
        for p, m in ps.items():
            extra = ""
            if p == "interleaved":
                extra = (f", engine side {m['engine_ms_per_timestep']:.2f} ms, wall "
                         f"{m['wall_timesteps_per_s']:.0f} timesteps/s with {procs} writer processes")
            print(f"  {t:8s} {p:11s} {m['cpu_ms_per_timestep']:6.2f} ms/timestep = "
                  f"{m['timesteps_per_s_per_writer_process']:6.0f} timesteps/s per writer process{extra}")
    if baseline:
        out["speedup"] = {p: med["baseline"][p]["cpu_ms_per_timestep"] / med["this"][p]["cpu_ms_per_timestep"]
                          for p in patterns}  # fmt: skip
        print("  speed-up (baseline / this, CPU per timestep): "
              + ", ".join(f"{p} {v:.2f}x" for p, v in out["speedup"].items()))
    dest = REPO / "bench_results" / "write.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2))
    return out


@pytest.mark.benchmark
def test_bench_write():
    out = run(procs=1, shards=4, frames=10, steady_frames=30, episodes=1, repeats=1)
    assert all(m["cpu_ms_per_timestep"] > 0 for m in out["median"]["this"].values())


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        tree = Path(os.environ.get("BENCH_WRITE_TREE", str(REPO)))  # its code, and its benchmark helpers
        sys.path[:0] = [str(tree / "tests" / "benchmarks"), str(tree)]
        _child(sys.argv[2:])
        sys.exit(0)
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--writer-procs", type=int, default=3, help="processes of the interleaved pattern's pool")
    ap.add_argument("--shards", type=int, default=256, help="shards (worlds) of the interleaved pattern")
    ap.add_argument("--frames", type=int, default=30, help="frames per shard, interleaved pattern")
    ap.add_argument("--steady-frames", type=int, default=300, help="frames per episode, steady pattern")
    ap.add_argument("--episodes", type=int, default=2, help="episodes, steady pattern")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline", type=Path, default=None, help="another checkout to compare with")
    ap.add_argument("--patterns", nargs="*", default=["steady", "interleaved"])
    a = ap.parse_args()
    run(procs=a.writer_procs, shards=a.shards, frames=a.frames, steady_frames=a.steady_frames,
        episodes=a.episodes, repeats=a.repeats, baseline=a.baseline, patterns=tuple(a.patterns))
