"""Ingest throughput: assets per minute per core for hull-only and CoACD assets, and the cached re-run.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_ingest.py -s``
(``AGENTWORLD_BENCH_INGEST_ALL=1`` ingests every shared rigid entry instead of the default subset).
Needs ../shared/assets. Prints the figures and writes ``bench_results/ingest.json``.

Per-core rate of a class = 60 / median seconds of one item (an item runs on one core; the times are
the item's own sub-step timings, so they do not depend on how many workers ran beside it); the
mean-based rate (items / summed item time) is reported too, since CoACD times have a long tail. The
wall-clock rate of the whole job (items / minute / worker) is reported too, as is the wall time of
the second, fully cached run of the same job through the runner.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
ANNOTATIONS = REPO / "tests" / "data" / "shared_rigid" / "annotations.toml"
HULL_SUBSET = ("ycb_apple", "ycb_orange", "ycb_rubiks_cube", "rs_can", "rs_cereal", "rs_milk", "os_phone",
               "os_flashlight")
COACD_SUBSET = ("os_mug", "os_teapot", "os_rubberduck", "ms_shelves")
WORKERS = 2


def _job(shared: Path, out: Path, only: tuple[str, ...]):
    from pipeline import build_job

    config: dict = {"catalog": str(shared), "annotations": str(ANNOTATIONS)}
    if only:
        config["only"] = list(only)
    data = {"job": {"name": "bench_ingest", "seed": 0, "out": str(out), "executor": "local",
                    "workers": WORKERS},
            "step": [{"name": "assets", "kind": "ingest", "config": config}]}
    return build_job(data, source="<bench_ingest>", base_dir=out.parent)


def _rates(results: list) -> dict:
    secs = [sum(r.timings.values()) for r in results]
    if not secs:
        return {"n": 0}
    med = statistics.median(secs)
    steps = {k: round(statistics.median(r.timings[k] for r in results), 3) for k in results[0].timings}
    return {"n": len(secs), "median_item_s": round(med, 3), "max_item_s": round(max(secs), 3),
            "assets_per_min_per_core": round(60.0 / med, 2),
            "assets_per_min_per_core_mean": round(60.0 * len(secs) / sum(secs), 2),
            "median_step_s": steps, "median_colliders": statistics.median(r.n_colliders for r in results)}


@pytest.mark.benchmark
def test_ingest_throughput(shared_assets, tmp_path):
    from pipeline import load_results, run_job

    only = () if os.environ.get("AGENTWORLD_BENCH_INGEST_ALL") else HULL_SUBSET + COACD_SUBSET
    out = tmp_path / "out"
    job = _job(shared_assets, out, only)
    t0 = time.perf_counter()
    first = run_job(job, progress=False, log_level="WARNING")
    wall = time.perf_counter() - t0
    (step,) = first.steps
    assert step.failed == 0, step.failures
    t0 = time.perf_counter()
    second = run_job(job, progress=False, log_level="WARNING")
    cached_wall = time.perf_counter() - t0
    assert second.steps[0].done == 0 and second.steps[0].cached == step.done
    results = list(load_results(out, "assets").values())
    hull = [r for r in results if r.collider_method in ("hull", "hulls")]
    coacd = [r for r in results if r.collider_method == "coacd"]
    figures = {
        "assets": len(results), "workers": WORKERS, "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "load_average_1min": round(os.getloadavg()[0], 2),
        "hull_only": _rates(hull), "coacd": _rates(coacd),
        "job_wall_s": round(wall, 2),
        "job_assets_per_min_per_worker": round(len(results) / (wall / 60.0) / WORKERS, 2),
        "cached_rerun_s": round(cached_wall, 3),
    }
    print("\ningest benchmark:", json.dumps(figures, indent=2))
    dest = REPO / "bench_results" / "ingest.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    assert figures["cached_rerun_s"] < wall
