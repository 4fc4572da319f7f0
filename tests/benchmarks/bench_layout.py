"""Benchmark: seconds per house on one core, USD write included (plan sampling and checks, occupancy
grids, floor plan JSON + images, manifold3d geometry, USD layer), for a 3-room single floor and a
2-floor 6-room house. Prints median and p95; writes bench_results/layout.json.

    python -m pytest -q -m benchmark tests/benchmarks/bench_layout.py -s
"""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import pytest

from asset_catalog.annotations import RoomType as R
from stages.layout.build import generate_layout
from stages.layout.spec import LayoutSpec

CASES = {
    "single_floor_3_rooms": LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 1}),
    "two_floors_6_rooms": LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 3, R.BATHROOM: 1}, floors=2),
}
HOUSES = int(os.environ.get("BENCH_LAYOUT_HOUSES", "40"))
OUT = Path(__file__).resolve().parents[2] / "bench_results" / "layout.json"


@pytest.mark.benchmark
def test_bench_layout(tmp_path: Path) -> None:
    import usd_schemas  # noqa: F401  (registers the schema plugin first, as the stages do)

    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core
    generate_layout(CASES["single_floor_3_rooms"], 10_000, tmp_path / "warmup")  # imports, caches
    results = {}
    for name, spec in CASES.items():
        wall, cpu, steps = [], [], {}
        for seed in range(HOUSES):
            t0, c0 = time.perf_counter(), time.process_time()
            out = generate_layout(spec, seed, tmp_path / name / str(seed))
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            for k, v in out.seconds.items():
                steps.setdefault(k, []).append(v)
        results[name] = {
            "houses": HOUSES,
            "median_s": float(np.median(wall)), "p95_s": float(np.percentile(wall, 95)),
            "cpu_median_s": float(np.median(cpu)), "cpu_p95_s": float(np.percentile(cpu, 95)),
            "step_median_s": {k: float(np.median(v)) for k, v in steps.items()},
        }
        r = results[name]
        print(f"{name}: median {r['median_s']:.3f} s, p95 {r['p95_s']:.3f} s per house "
              f"(cpu median {r['cpu_median_s']:.3f} s, p95 {r['cpu_p95_s']:.3f} s); steps {r['step_median_s']}")
        assert r["median_s"] > 0
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"machine": platform.processor() or platform.machine(), "cores_used": 1,
                               "load_avg": os.getloadavg(), "cases": results}, indent=1) + "\n")
