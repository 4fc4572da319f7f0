"""Benchmark: generate the default catalog (37 categories x 5 variants = 185 assets) and ingest it into
USD asset packages on 2 worker processes. Target: under 5 minutes on 2 cores.

Writes bench_results/default_catalog.json: generate_s (median of 3 builds), ingest_s (one fresh run;
a second run would be all cache hits), total_s, assets, per-sub-step ingest time sums.
"""

from __future__ import annotations

import json
import os
import statistics
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TARGET_S = 300.0


@pytest.mark.benchmark
def test_bench_default_catalog(tmp_path: Path):
    from asset_catalog.default_catalog import build_default_catalog
    from pipeline import build_job, load_results, run_job

    gen_times = []
    for i in range(3):
        t0 = time.perf_counter()
        rep = build_default_catalog(tmp_path / f"catalog{i}", variants_per_category=5, seed=0)
        gen_times.append(time.perf_counter() - t0)
    catalog = tmp_path / "catalog0"
    out = tmp_path / "out"
    data = {"job": {"name": "bench_default_catalog", "seed": 0, "out": str(out), "executor": "local",
                    "workers": 2},
            "step": [{"name": "assets", "kind": "ingest", "config": {"catalog": str(catalog)}}]}
    t0 = time.perf_counter()
    summary = run_job(build_job(data, source="<bench>", base_dir=tmp_path), progress=False)
    ingest_s = time.perf_counter() - t0
    (step,) = summary.steps
    results = load_results(out, "assets")
    sub = {}
    for r in results.values():
        for k, v in r.timings.items():
            sub[k] = sub.get(k, 0.0) + v
    figures = {
        "assets": len(rep.asset_ids), "categories": len(rep.categories), "ingested": len(results),
        "failed": step.failed, "workers": 2, "cpu_count": os.cpu_count(),
        "generate_s": round(statistics.median(gen_times), 2), "generate_runs_s": [round(t, 2) for t in gen_times],
        "ingest_s": round(ingest_s, 2), "total_s": round(statistics.median(gen_times) + ingest_s, 2),
        "ingest_substep_sums_s": {k: round(v, 2) for k, v in sorted(sub.items())},
        "colliders_by_method": {m: sum(r.collider_method == m for r in results.values())
                                for m in sorted({r.collider_method for r in results.values()})},
        "target_s": TARGET_S,
    }
    (REPO / "bench_results").mkdir(exist_ok=True)
    (REPO / "bench_results" / "default_catalog.json").write_text(json.dumps(figures, indent=2) + "\n")
    print(json.dumps(figures, indent=2))
    assert step.failed == 0, [f.reason for f in step.failures]
    assert len(results) >= 150
    assert figures["total_s"] < TARGET_S, f"default catalog took {figures['total_s']} s (target {TARGET_S} s)"
