"""Scripted success of (multistage) tasks in the default-catalog task kitchen, CPU (issue 16).

Run: ``.venv/bin/python tests/benchmarks/bench_kitchen_tasks.py --kitchens 0 1 2 --tasks store_food
--seeds 1 2 --catalog /tmp/kcat`` (the catalog work dir is built there by the real job steps, as
``bench_demos.build_catalog``, when it does not hold one yet: ~20 s; with 5 pitchers and 5 cups
when a task needs the drink). Each kitchen (world seed) runs
on the batched engine (``layout="per_world"``, one world, no cameras) every task with every seed,
each to its end or the task's time limit. Prints one line per episode (kitchen, task, seed, success,
reason, frames, wall seconds) and per task the successes and the failures by reason (a multistage
reason names its stage: ``s2_pick_place_fridge.object_tipped``); writes
``bench_results/kitchen_tasks.json``.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
for p in (REPO, Path(__file__).parent):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def build_drink_catalog(out: Path) -> Path:
    """``bench_demos.build_catalog``'s kitchen catalog plus the pitchers and cups (5 of each) a task
    with the drink needs (serve_drinks), built by the real job steps in the work dir ``out``."""
    from bench_demos import KITCHEN, PACKAGES
    from pipeline import build_job, run_job

    extra = [f"{c}_{i:02d}" for c in ("pitcher", "cup") for i in range(5)]
    data = {"job": {"name": "bench_drink_catalog", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
            "step": [{"name": "catalog", "kind": "default_catalog",
                      "config": {"variants": 5, "categories": [*KITCHEN, "pitcher", "cup"]}},
                     {"name": "assets", "kind": "ingest",
                      "config": {"catalog_step": "catalog", "only": [*PACKAGES, *extra]}}]}
    summary = run_job(build_job(data, source="<bench>", base_dir=out.parent), progress=False)
    if summary.status != "ok":
        raise RuntimeError(f"drink catalog for the benchmark failed: {summary}")
    return out


def run(catalog: Path, work: Path, kitchens: list[int], tasks: list[str], seeds: list[int]) -> dict:
    import numpy as np

    from bench_demos import build_catalog
    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.demos.multistage import needs_clock, needs_drink, needs_household
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    if not (catalog / "catalog" / "default" / "generated.json").is_file():
        (build_drink_catalog if needs_drink(tasks) else build_catalog)(catalog)
    lib = AssetLibrary.from_folder(catalog / "assets", catalog / "catalog" / "default" / "generated.json")
    rows = []
    for k in kitchens:
        room = write_kitchen(work / f"kitchen_{k}", lib, scene_id=f"k{k}", rng=np.random.default_rng(k),
                             household=needs_household(tasks), drink=needs_drink(tasks), clock=needs_clock(tasks))
        cfg = EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True)
        eng = BatchEngine(room, panda_root=None, work_dir=work / f"engine_{k}", config=cfg)

        def end(_w, t, r, k=k):
            rows.append({"kitchen": k, "task": t.task, "seed": t.seed, "success": r.success, "reason": r.reason,
                         "frames": r.frames, "wall_s": round(r.wall_seconds, 1)})
            print(rows[-1], flush=True)

        eng.run(Listed(room, {0: [(t, s, None) for t in tasks for s in seeds]}), begin=lambda *_: None, end=end)
    per = {}
    for t in tasks:
        mine = [r for r in rows if r["task"] == t]
        per[t] = {"success": f"{sum(r['success'] for r in mine)}/{len(mine)}",
                  "failures": dict(collections.Counter(r["reason"] for r in mine if not r["success"]))}
    print("per task:", json.dumps(per))
    return {"episodes": rows, "per_task": per}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kitchens", nargs="+", type=int, default=[0])
    ap.add_argument("--tasks", nargs="+", default=["store_food"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1])
    ap.add_argument("--catalog", type=Path, required=True)
    ap.add_argument("--out", type=Path, default=Path("bench_results/kitchen_tasks.json"))
    a = ap.parse_args()
    t0 = time.time()
    res = run(a.catalog, Path(tempfile.mkdtemp(prefix="kitchen_tasks_")), a.kitchens, a.tasks, a.seeds)
    res["wall_seconds"] = round(time.time() - t0, 1)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(res, indent=1))
