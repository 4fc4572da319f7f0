"""Benchmark: settled + validated scenes per hour with the batched settle (``stages.scene.settle_batch``):
``--scenes`` scenes (3-room houses populated on one CPU core beforehand, not timed) settled together
in one Newton model by MuJoCo-Warp on ``--device``, then validated (``stages.scene.validation``, the
per-package cache filled once, as a job's work dir keeps it). Prints the split (model build,
finalize, simulate, validate) and scenes per hour, and writes bench_results/scene_settle_<device>.json.

    python tests/benchmarks/bench_scene_settle_gpu.py --device cuda:0 --scenes 256
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


def run(device: str, n: int, seconds: float, work: Path, rooms: dict[str, int], progress: bool = True,
        procs: int = 1) -> dict:
    """Populate ``n`` scenes, settle them together on ``device`` for ``seconds`` [s], validate each;
    the figures as a dict."""
    import usd_schemas  # noqa: F401
    from stages.scene.checkcache import process_cache
    from stages.scene.settle_batch import scene_layout, settle_batch
    from stages.scene.validation import validate_scene

    scenes, _, cache_dir = make_scenes(n, work, rooms, progress, procs)
    cache = process_cache(cache_dir)

    def packages(scene: Path) -> list[Path]:
        info = json.loads((scene.parent / "scene.json").read_text(encoding="utf-8"))
        return sorted({Path(i["usd"]) for i in info["instances"]}) + [scene_layout(scene)]

    for s in scenes:  # fill the per-package cache (once per package, as a job's work dir keeps it)
        for p in packages(s):
            from stages.scene.validation import validate_package_cached
            validate_package_cached(p, cache)
    t0 = time.perf_counter()
    res = settle_batch(scenes, device=device, seconds=seconds, progress=progress)
    t = time.perf_counter()
    errors = sum(len(validate_scene(s, packages(s), cache).errors) for s in scenes)
    validate = time.perf_counter() - t
    total = time.perf_counter() - t0
    return {"device": device, "scenes": n, "rooms": rooms, "seconds_simulated": res.simulated,
            "bodies": res.bodies, "shapes": res.shapes, "split_s": {**res.seconds, "validate": round(validate, 3)},
            "total_s": round(total, 3), "scenes_per_hour": round(n / total * 3600, 1),
            "passed": sum(res.passed), "validation_errors": errors,
            "max_move_m": max((max(m.values(), default=0.0) for m in res.moved), default=0.0),
            "host": platform.node(), "cpu": platform.processor() or platform.machine()}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--scenes", type=int, default=64)
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated seconds [s]")
    ap.add_argument("--rooms", default="living_room,kitchen,bedroom", help="room types of each house")
    ap.add_argument("--populate-procs", type=int, default=1, help="processes populating the houses (not timed)")
    ap.add_argument("--work", type=Path, default=None, help="work folder (default: a temporary one)")
    a = ap.parse_args(argv)
    rooms = {r: 1 for r in a.rooms.split(",") if r}
    with tempfile.TemporaryDirectory(prefix="aw_settle_") as d:
        out = run(a.device, a.scenes, a.seconds, Path(a.work or d), rooms, procs=a.populate_procs)
    dev = a.device.replace(":", "")
    path = ROOT / "bench_results" / f"scene_settle_{dev}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(out, indent=1))
    print(f"{out['scenes_per_hour']:.0f} settled + validated scenes per hour on {a.device} "
          f"({a.scenes} scenes; split {out['split_s']})")
    return out


if __name__ == "__main__":
    main()
