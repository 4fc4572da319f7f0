"""Recorded demonstration frames per second, end to end, split into simulation, rendering, control,
encoding and writing.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_demos.py -s`` or directly
``.venv/bin/python tests/benchmarks/bench_demos.py --device cuda --worlds 1,4,8 --episodes 2``.
Environment for the pytest entry: ``BENCH_DEMOS_DEVICE`` (cpu | cuda), ``BENCH_DEMOS_WORLDS``
(comma-separated world counts), ``BENCH_DEMOS_EPISODES``, ``BENCH_DEMOS_TASKS``, ``BENCH_DEMOS_SIZE``
(WxH), ``BENCH_DEMOS_CATALOG`` (a work dir holding ``assets/`` and ``catalog/default/generated.json``,
e.g. ``out/main``). Without a catalog, the kitchen's packages are generated from the default
catalog and ingested first (~20 s, not timed). The Panda comes from the pip package example-robot-data.

For a world count W, W processes run at once, each with its own world (a kitchen from the default
catalog, :mod:`stages.demos.kitchen`), simulation
and shard writer, recording ``episodes`` episodes of each task (3 cameras, RGB + depth, at the
given size). Per process: frames recorded, wall time of the episodes (world building excluded and
reported separately), and the per-stage split (:class:`stages.demos.record.Timings`): simulation
(physics steps), rendering (3 cameras), control (state reads, IK, planning), encoding (frames into
the writer, which feeds the video encoders), writing (end of episode and shard close). Throughput
for W is the sum over processes of frames / wall; per-frame stage times are medians over episodes.
Writes ``bench_results/demos.json``.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))
KITCHEN = ("kitchen_counter", "microwave", "fridge", "oven", "door", "dining_table", "mug", "bowl", "can")
PACKAGES = ("kitchen_counter_00", "microwave_00", "fridge_00", "oven_00", "door_00", "dining_table_00",
            "mug_04", "bowl_00", "can_00")


def build_catalog(out: Path) -> Path:
    """Generate the kitchen categories of the default catalog and ingest one package of each into
    the work dir ``out`` (the real job steps); returns ``out``."""
    from pipeline import build_job, run_job

    data = {"job": {"name": "bench_demos_catalog", "seed": 0, "out": str(out), "executor": "inline",
                    "workers": 1},
            "step": [{"name": "catalog", "kind": "default_catalog",
                      "config": {"variants": 5, "categories": list(KITCHEN)}},
                     {"name": "assets", "kind": "ingest",
                      "config": {"catalog_step": "catalog", "only": list(PACKAGES)}}]}
    summary = run_job(build_job(data, source="<bench>", base_dir=out.parent), progress=False)
    if summary.status != "ok":
        raise RuntimeError(f"catalog for the benchmark failed: {summary}")
    return out


def _world_run(args: tuple) -> dict:
    """One process: build world ``w``, record the episodes into a shard, return the figures."""
    w, device, tasks, episodes, size, base, catalog = args
    import numpy as np

    from stages.dataset import EpisodeInfo, open_shard
    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.demos.sampling import sample_instance
    from stages.demos.session import DemoSettings, DemoWorld

    t0 = time.perf_counter()
    lib = AssetLibrary.from_folder(Path(catalog) / "assets",
                                   Path(catalog) / "catalog" / "default" / "generated.json")
    room = write_kitchen(Path(base) / f"w{w}", lib, scene_id=f"bench_{w}",
                         rng=np.random.default_rng(1000 + w))
    settings = DemoSettings(width=size[0], height=size[1], device=device)
    world = DemoWorld(room, panda_root=None, work_dir=Path(base) / f"w{w}", settings=settings, seed=w)
    build = time.perf_counter() - t0
    per_episode = []
    t_run = time.perf_counter()
    with open_shard(Path(base) / "shards", f"w{w}", settings.dataset_spec()) as shard:
        for task in tasks:
            for k in range(episodes):
                inst = sample_instance(task, room, 7000 + 100 * w + k)
                shard.begin_episode(EpisodeInfo(task=inst.instruction, task_kind=task, scene_id=room.scene_id,
                                                seed=inst.seed))
                res = world.run_episode(inst, sink=shard.add_frame)
                t1 = time.perf_counter()
                shard.end_episode(success=res.success, reason=res.reason)
                res.timings.writing += time.perf_counter() - t1
                per_episode.append({"task": task, "success": res.success, "reason": res.reason,
                                    "frames": res.frames, **res.timings.to_json()})
        t_close = time.perf_counter()
    close = time.perf_counter() - t_close
    wall = time.perf_counter() - t_run
    return {"world": w, "build_s": build, "wall_s": wall, "close_s": close, "episodes": per_episode}


def run(device: str = "cpu", worlds=(1,), episodes: int = 1, tasks=("press_button",), size=(128, 96),
        catalog: Path | None = None) -> dict:
    """Benchmark every world count; returns (and writes) the figures. ``catalog``: a work dir with
    the ingested packages (None: build the kitchen's packages first)."""
    out = {"device": device, "tasks": list(tasks), "episodes_per_task": episodes, "image_size": list(size),
           "cameras": 3, "cpu_count": os.cpu_count(), "worlds": {}}
    with tempfile.TemporaryDirectory(prefix="bench-demos-catalog-") as cat_tmp:
        if catalog is None:
            catalog = build_catalog(Path(cat_tmp) / "out")
        for n in worlds:
            _run_worlds(out, n, device, tasks, episodes, size, Path(catalog))
    dest = REPO / "bench_results" / "demos.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2))
    return out


def _run_worlds(out: dict, n: int, device: str, tasks, episodes: int, size, catalog: Path) -> None:
    """Record with ``n`` worlds (processes) at once; the figures go to ``out["worlds"][str(n)]``."""
    from stages.demos.record import STAGES

    with tempfile.TemporaryDirectory(prefix="bench-demos-") as base:
        args = [(w, device, tuple(tasks), episodes, tuple(size), base, str(catalog)) for w in range(n)]
        if n == 1:
            runs = [_world_run(args[0])]
        else:
            with mp.get_context("spawn").Pool(n) as pool:
                runs = pool.map(_world_run, args)
    eps = [e for r in runs for e in r["episodes"]]
    frames = sum(e["frames"] for e in eps)
    per_frame_ms = {s: round(1000 * statistics.median(e[s] / max(1, e["frames"]) for e in eps), 3)
                    for s in STAGES}
    out["worlds"][str(n)] = {
        "frames": frames,
        "frames_per_s": round(sum(sum(e["frames"] for e in r["episodes"]) / r["wall_s"]
                                  for r in runs), 3),
        "frames_per_s_per_world": round(statistics.median(
            sum(e["frames"] for e in r["episodes"]) / r["wall_s"] for r in runs), 3),
        "per_frame_ms_median": per_frame_ms,
        "build_s_median": round(statistics.median(r["build_s"] for r in runs), 3),
        "success": f"{sum(e['success'] for e in eps)}/{len(eps)}",
    }
    print(f"[demos] {device} worlds={n}: {out['worlds'][str(n)]}", flush=True)


@pytest.mark.benchmark
def test_bench_demos():
    size = tuple(int(v) for v in os.environ.get("BENCH_DEMOS_SIZE", "128x96").split("x"))
    res = run(device=os.environ.get("BENCH_DEMOS_DEVICE", "cpu"),
              worlds=tuple(int(v) for v in os.environ.get("BENCH_DEMOS_WORLDS", "1").split(",")),
              episodes=int(os.environ.get("BENCH_DEMOS_EPISODES", "1")),
              tasks=tuple(os.environ.get("BENCH_DEMOS_TASKS", "press_button,pick_place_bowl").split(",")),
              size=size, catalog=(Path(os.environ["BENCH_DEMOS_CATALOG"])
                                  if "BENCH_DEMOS_CATALOG" in os.environ else None))
    for v in res["worlds"].values():
        assert v["frames"] > 0 and v["frames_per_s"] > 0


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu")
    p.add_argument("--worlds", default="1", help="comma-separated world counts, e.g. 1,4,8")
    p.add_argument("--episodes", type=int, default=1)
    p.add_argument("--tasks", default="press_button,pick_place_bowl")
    p.add_argument("--size", default="128x96")
    p.add_argument("--catalog", type=Path, default=None,
                   help="work dir with assets/ and catalog/default/generated.json (default: build them)")
    a = p.parse_args()
    run(a.device, tuple(int(v) for v in a.worlds.split(",")), a.episodes, tuple(a.tasks.split(",")),
        tuple(int(v) for v in a.size.split("x")), a.catalog)
