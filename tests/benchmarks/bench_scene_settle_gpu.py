"""Benchmark: settled + validated scenes per hour with the batched settle (``stages.scene.settle_pool``):
``--scenes`` scenes (3-room houses populated beforehand, not timed) settled in chunks of ``--chunk``
scenes per Newton model (one world each, ``--side-by-side``: one world) by MuJoCo-Warp on
``--device`` (several: comma list or 'cuda'), by ``--procs-per-device`` worker processes each,
then validated (``stages.scene.validation``, the
per-package cache filled once, as a job's work dir keeps it). Prints, as chunks finish, scenes per
hour and the workers' split per scene (model build, finalize, simulate, validate), and writes
bench_results/scene_settle_<device>.json each time; no chunk starts after ``--max-seconds``.

    python tests/benchmarks/bench_scene_settle_gpu.py --device cuda --scenes 1024 --populate-procs 56 \
        --procs-per-device 8 --chunk 16 --cuda-graph --max-seconds 120 --work /tmp/aw_settle
    python tests/benchmarks/bench_scene_settle_gpu.py --device cpu --scenes 2 --seconds 0.2
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))


def _populate(job: tuple, lib=None, rules=None) -> str | None:
    """One house (layout plan, layout USD, library index, out folder, population seed) populated
    with settle and validation off; its scene.usda, or None when the solver rejects it."""
    from stages.scene.build import BuildOptions, SceneRejected, build_scene
    from stages.scene.rules import load_rules
    from stages.scene.solver import Library

    plan, usd, index, out, seed = job
    lib = Library.from_index(Path(index)) if lib is None else lib
    rules = load_rules() if rules is None else rules
    try:
        build_scene(Path(plan), Path(usd), lib, rules, np.random.default_rng(seed), Path(out), Path(out),
                    BuildOptions(n_looks=2, settle=False, validate=False))
    except SceneRejected:
        return None
    return str(Path(out) / "scene.usda")


def make_scenes(n: int, work: Path, rooms: dict[str, int], progress: bool = True,
                procs: int = 1) -> tuple[list[Path], Path, Path]:
    """(n scene.usda paths, the library index, the check cache dir): houses from layout seeds
    0.. and population seeds, built with settle and validation off (the benchmark does them);
    ``procs`` processes populate them (not timed)."""
    from tqdm import tqdm

    from stages.layout.build import generate_layout
    from stages.layout.spec import LayoutSpec
    from stages.scene.rules import load_rules
    from stages.scene.solver import Library
    from stages.scene.standin import build_library

    cats = ["sofa", "tv_stand", "coffee_table", "armchair", "bookshelf", "cabinet", "floor_lamp", "rug",
            "kitchen_counter", "fridge", "oven", "dining_table", "chair", "microwave", "bed", "nightstand",
            "wardrobe", "dresser", "pillow", "alarm_clock", "mug", "cup", "can", "book", "box", "plate", "bottle",
            "sponge", "bowl"]
    index = build_library(work / "lib", categories=cats, variants=2)
    layouts = [generate_layout(LayoutSpec(rooms=rooms), s, work / f"layout_{s}") for s in range(max(1, min(n, 8)))]
    scenes: list[Path] = []
    seed = 0
    with tqdm(total=n, desc="populate scenes", unit="scene", disable=not progress) as bar:
        if procs <= 1:
            lib, rules = Library.from_index(index), load_rules()
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            pool = ProcessPoolExecutor(procs, mp_context=mp.get_context("spawn"))
        while len(scenes) < n:
            batch = range(seed, seed + (1 if procs <= 1 else max(procs, n - len(scenes))))
            jobs = [(str(layouts[s % len(layouts)].plan_json), str(layouts[s % len(layouts)].usd), str(index),
                     str(work / "scenes" / f"s{s}"), s + 1) for s in batch]
            seed = batch.stop
            done = [_populate(j, lib, rules) for j in jobs] if procs <= 1 else list(pool.map(_populate, jobs))
            for path in done:
                if path is not None and len(scenes) < n:
                    scenes.append(Path(path))
                    bar.update(1)
        if procs > 1:
            pool.shutdown()
    return scenes, work / "lib" / "catalog.sqlite", work / "scene_checks"


def _fill(job: tuple) -> float:
    """Validate one package into the check cache (as a job's work dir keeps it); seconds taken."""
    from stages.scene.checkcache import process_cache
    from stages.scene.validation import validate_package_cached

    t = time.perf_counter()
    validate_package_cached(Path(job[0]), process_cache(Path(job[1])))
    return time.perf_counter() - t


def _say(msg: str) -> None:
    print(msg, flush=True)


def _offenders(results: list) -> dict:
    """Instances that moved more than the tolerance, by category (the instance name without its
    number): count and largest move [m]."""
    out: dict[str, list] = {}
    for r in results:
        for moved, names in zip(r.settle.moved, r.settle.offenders):
            for name in names:
                cat = name.rsplit("_", 1)[0]
                n, m = out.get(cat, (0, 0.0))
                out[cat] = [n + 1, round(max(m, moved[name]), 4)]
    return out


def _figures(results: list, n_asked: int, elapsed: float, opts: dict) -> dict:
    split: dict[str, float] = {}
    for r in results:
        for k, v in r.seconds.items():
            split[k] = split.get(k, 0.0) + v
    n = sum(len(r.settle.scenes) for r in results)
    moved = [m for r in results for m in r.settle.moved]
    return {**opts, "scenes_asked": n_asked, "scenes": n, "chunks": len(results),
            "seconds_simulated": results[0].settle.simulated if results else 0.0,
            "bodies": sum(r.settle.bodies for r in results), "shapes": sum(r.settle.shapes for r in results),
            "worker_split_s": {k: round(v, 2) for k, v in split.items()},
            "worker_s_per_scene": {k: round(v / max(n, 1), 3) for k, v in split.items()},
            "total_s": round(elapsed, 2), "scenes_per_hour": round(n / max(elapsed, 1e-9) * 3600, 1),
            "passed": sum(sum(r.settle.passed) for r in results),
            "validation_errors": sum(sum(r.errors) for r in results),
            "max_move_m": max((max(m.values(), default=0.0) for m in moved), default=0.0),
            "offenders": _offenders(results),
            "host": platform.node(), "cpu": platform.processor() or platform.machine()}


def run(devices: list[str], n: int, seconds: float, work: Path, rooms: dict[str, int], progress: bool = True,
        procs: int = 1, *, chunk: int = 1, per_device: int = 1, max_seconds: float = 180.0,
        cuda_graph: bool = False, out_json: Path | None = None, reuse: bool = False, worlds: bool = True) -> dict:
    """Populate ``n`` scenes (not timed), fill the package check cache (not timed), warm the workers
    up (one chunk alone: kernel compile; then one chunk per worker: package parse; not timed), then
    settle + validate all ``n`` in chunks of ``chunk`` on ``devices`` with ``per_device`` workers each
    (0: in this process), starting no chunk after ``max_seconds`` [s] of that. ``reuse``: scenes
    already in ``work`` (an earlier run's) are used instead of populating. Prints progress and the
    figures as it goes, writes them to ``out_json`` each time; returns them."""
    from concurrent.futures import ProcessPoolExecutor
    import multiprocessing as mp

    from stages.scene.settle_pool import SettlePool, scene_packages

    t = time.perf_counter()
    have = sorted(work.glob("scenes/s*/scene.json"), key=lambda p: int(p.parent.name[1:]))
    if reuse and len(have) >= n:
        scenes, cache_dir = [p.parent / "scene.usda" for p in have[:n]], work / "scene_checks"
    else:
        scenes, _, cache_dir = make_scenes(n, work, rooms, progress, procs)
    _say(f"[populate] {len(scenes)} scenes in {time.perf_counter() - t:.1f} s (not timed)")
    t = time.perf_counter()
    pkgs = sorted({str(p) for s in scenes for p in scene_packages(s)})
    jobs = [(p, str(cache_dir)) for p in pkgs]
    if procs > 1:
        with ProcessPoolExecutor(min(procs, len(jobs)), mp_context=mp.get_context("spawn")) as ex:
            list(ex.map(_fill, jobs))
    else:
        [_fill(j) for j in jobs]
    _say(f"[package cache] {len(pkgs)} packages validated in {time.perf_counter() - t:.1f} s (not timed)")
    opts = {"devices": devices, "rooms": rooms, "chunk": chunk, "workers_per_device": per_device,
            "cuda_graph": cuda_graph, "worlds": worlds, "max_seconds": max_seconds}
    out: dict = {}
    t_start = time.perf_counter()
    with SettlePool(devices, per_device, seconds=seconds, cache_dir=cache_dir, cuda_graph=cuda_graph,
                    worlds=worlds) as pool:
        # one chunk alone first (it compiles the kernels into Warp's disk cache), then one per worker
        stages = [("compile", scenes[:chunk])]
        if pool.workers > 1:
            stages.append(("workers", scenes[:pool.workers * chunk]))
        for stage, warm in stages:
            _say(f"[warmup {stage}] {len(warm)} scenes on {pool.workers} workers ({devices})")
            for r in pool.run(warm, chunk):
                _say(f"[warmup {stage}] pid {r.pid} {r.device}: {len(r.settle.scenes)} scenes, "
                     f"{r.settle.bodies} bodies, split {r.seconds} at {time.perf_counter() - t_start:.1f} s")
        warmup = time.perf_counter() - t_start
        _say(f"[warmup] done in {warmup:.1f} s (not timed); timed: {n} scenes, no chunk starts after "
             f"{max_seconds:.0f} s")
        opts["warmup_s"] = round(warmup, 2)
        results: list = []
        t0 = last = t_end = time.perf_counter()
        deadline = t0 + max_seconds
        for r in pool.run(scenes, chunk, deadline):
            results.append(r)
            now = t_end = time.perf_counter()
            if now - last >= 5.0 or len(results) * chunk >= n:
                last = now
                out = _figures(results, n, now - t0, opts)
                _say(f"[settle+validate] {out['scenes']}/{n} scenes in {now - t0:.1f} s: "
                     f"{out['scenes_per_hour']:.0f} scenes/h; worker s/scene {out['worker_s_per_scene']}; "
                     f"passed {out['passed']}, validation errors {out['validation_errors']}")
                if out_json is not None:
                    out_json.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    out = _figures(results, n, t_end - t0, opts)  # to the last chunk's end (not the workers' exit)
    out["complete"] = out["scenes"] == n
    if out_json is not None:
        out_json.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    return out


def _devices(spec: str) -> list[str]:
    if spec in ("cuda", "cuda:all"):
        import warp as wp

        wp.config.quiet = True
        return [f"cuda:{i}" for i in range(wp.get_cuda_device_count())]
    return [d for d in spec.split(",") if d]


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cuda:0", help="device, comma list, or 'cuda' (every GPU)")
    ap.add_argument("--scenes", type=int, default=64)
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated seconds [s]")
    ap.add_argument("--rooms", default="living_room,kitchen,bedroom", help="room types of each house")
    ap.add_argument("--populate-procs", type=int, default=1, help="processes populating the houses (not timed)")
    ap.add_argument("--chunk", type=int, default=1, help="scenes per model")
    ap.add_argument("--procs-per-device", type=int, default=1,
                    help="settling worker processes per device (0: settle in this process)")
    ap.add_argument("--max-seconds", type=float, default=180.0,
                    help="no chunk of the timed part starts after this many seconds of it [s]")
    ap.add_argument("--cuda-graph", action="store_true", help="step through a captured CUDA graph")
    ap.add_argument("--side-by-side", action="store_true",
                    help="a chunk's scenes side by side in one world (default: one world each)")
    ap.add_argument("--work", type=Path, default=None, help="work folder (default: a temporary one)")
    ap.add_argument("--reuse", action="store_true", help="use the scenes an earlier run left in --work")
    a = ap.parse_args(argv)
    rooms = {r: 1 for r in a.rooms.split(",") if r}
    devices = _devices(a.device)
    name = devices[0].replace(":", "") + (f"_x{len(devices)}" if len(devices) > 1 else "")
    path = ROOT / "bench_results" / f"scene_settle_{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="aw_settle_") as d:
        out = run(devices, a.scenes, a.seconds, Path(a.work or d), rooms, procs=a.populate_procs, chunk=a.chunk,
                  per_device=a.procs_per_device, max_seconds=a.max_seconds, cuda_graph=a.cuda_graph, out_json=path,
                  reuse=a.reuse, worlds=not a.side_by_side)
    print(json.dumps(out, indent=1))
    print(f"{out['scenes_per_hour']:.0f} settled + validated scenes per hour on {','.join(devices)} "
          f"({out['scenes']}/{a.scenes} scenes, chunks of {a.chunk}, {a.procs_per_device} workers per device; "
          f"worker s/scene {out['worker_s_per_scene']})", flush=True)
    return out


if __name__ == "__main__":
    main()
