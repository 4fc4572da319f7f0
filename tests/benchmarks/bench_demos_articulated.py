"""Benchmark: scripted open/close success rate of the generic articulated-part experts
(stages.demos.articulated) on default-catalog assets, one asset per part world
(stages.demos.part_world), CPU.

For each category: AW_ART_VARIANTS variants (default 3; each its own world: wall and position from
the variant index), AW_ART_SEEDS seeds per action (default 4; the seed picks the robot's start
pose and which door / drawer of the asset). Writes bench_results/demos_articulated.json: per
(category, action) episodes, successes, rate, failure reasons, median simulated and wall seconds
per episode, world build seconds. Categories: AW_ART_CATEGORIES (comma list of category:role,
default microwave:door,fridge:door,cabinet:drawer,kitchen_counter:drawer,oven:door,door:door).
"""

from __future__ import annotations

import json
import os
import statistics
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
DEFAULT = "microwave:door,fridge:door,cabinet:drawer,kitchen_counter:drawer,oven:door,door:door"


def _catalog(out: Path, categories: list[str], variants: int) -> Path:
    from pipeline import build_job, run_job

    data = {"job": {"name": "bench_articulated", "seed": 0, "out": str(out), "executor": "inline",
                    "workers": 1},
            "step": [{"name": "catalog", "kind": "default_catalog",
                      "config": {"variants": variants, "categories": categories}},
                     {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog"}}]}
    summary = run_job(build_job(data, source="<bench>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps}["assets"] == 0
    return out


@pytest.mark.benchmark
def test_bench_demos_articulated(tmp_path: Path):
    from stages.demos.part_world import PartSession, write_part_world
    from stages.demos.parts import load_generated_info

    pairs = [c.split(":") for c in os.environ.get("AW_ART_CATEGORIES", DEFAULT).split(",")]
    variants = int(os.environ.get("AW_ART_VARIANTS", "3"))
    seeds = int(os.environ.get("AW_ART_SEEDS", "4"))
    out = _catalog(tmp_path / "out", sorted({c for c, _ in pairs}), variants)
    info = load_generated_info(out / "catalog" / "default" / "generated.json")
    rows = []
    for cat, role in pairs:
        for v in range(variants):
            aid = f"{cat}_{v:02d}"
            t0 = time.perf_counter()
            world = write_part_world(tmp_path / aid, package_usd=out / "assets" / aid / f"{aid}.usda",
                                     record=info[aid], asset_id=aid, rng=np.random.default_rng(v))
            sess = PartSession(world, panda_root=None, work_dir=tmp_path / aid)
            build = time.perf_counter() - t0
            parts = [p for p in world.parts if p.role == role]
            actions = ("open",) if cat == "oven" else ("open", "close")
            for action in actions:
                for seed in range(seeds):
                    part = parts[seed % len(parts)]
                    r = sess.run(part, action, seed=seed, max_seconds=60.0)
                    rows.append({"category": cat, "action": action, "asset": aid, "seed": seed,
                                 "joint": part.joint_path.rsplit("/", 1)[-1], "success": r.success,
                                 "reason": r.reason, "sim_s": r.sim_seconds, "wall_s": r.wall_seconds,
                                 "build_s": build})
    summary = {}
    for cat, _ in pairs:
        for action in ("open", "close"):
            rs = [r for r in rows if r["category"] == cat and r["action"] == action]
            if not rs:
                continue
            ok = sum(r["success"] for r in rs)
            summary[f"{cat}/{action}"] = {
                "episodes": len(rs), "successes": ok, "rate": round(ok / len(rs), 3),
                "failures": dict(Counter(r["reason"] for r in rs if not r["success"])),
                "median_sim_s": round(statistics.median(r["sim_s"] for r in rs), 1),
                "median_wall_s": round(statistics.median(r["wall_s"] for r in rs), 1),
                "assets": sorted({r["asset"] for r in rs})}
    figures = {"variants": variants, "seeds_per_action": seeds, "cpu_count": os.cpu_count(),
               "summary": summary, "episodes": rows}
    (REPO / "bench_results").mkdir(exist_ok=True)
    (REPO / "bench_results" / "demos_articulated.json").write_text(json.dumps(figures, indent=2) + "\n")
    print(json.dumps(summary, indent=2))
    assert rows
