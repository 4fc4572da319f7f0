"""Runner overhead: 1000 trivial items on the local process pool (and inline), and the cached re-run.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_pipeline.py -s``.
Prints the figures and writes ``bench_results/pipeline.json`` (medians over REPEATS runs).
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
for _p in (str(REPO / "tests" / "pipeline"), str(REPO)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

from pipeline import build_job, run_job  # noqa: E402

N_ITEMS = 1000
REPEATS = 3
WORKERS = 2


def _job(tmp: Path, n: int):
    data = {"job": {"name": "bench", "workers": WORKERS, "retries": 0},
            "step": [{"name": "trivial", "kind": "stagefns:TRIVIAL_KIND", "config": {"n": n}}]}
    return build_job(data, source="<bench>", base_dir=tmp, registry={})


def _time_run(job, out: Path, executor: str) -> tuple[float, object]:
    t0 = time.perf_counter()
    s = run_job(job, out=out, executor=executor, progress=False, log_level="WARNING")
    return time.perf_counter() - t0, s


@pytest.mark.benchmark
def test_runner_overhead(tmp_path):
    job = _job(tmp_path, N_ITEMS)
    fresh: dict[str, list[float]] = {"local": [], "inline": []}
    cached: list[float] = []
    startup: list[float] = []
    for r in range(REPEATS):
        for ex in ("local", "inline"):
            wall, s = _time_run(job, tmp_path / f"{ex}{r}", ex)
            assert (s.done, s.failed) == (N_ITEMS, 0)
            fresh[ex].append(wall)
        wall, s = _time_run(job, tmp_path / f"local{r}", "local")
        assert (s.done, s.cached) == (0, N_ITEMS)
        cached.append(wall)
        wall, s = _time_run(_job(tmp_path, 1), tmp_path / f"one{r}", "local")   # pool start + 1 item
        startup.append(wall)
    med = {k: statistics.median(v) for k, v in fresh.items()}
    figures = {
        "items": N_ITEMS,
        "workers": WORKERS,
        "cpu_count": os.cpu_count(),
        "local_pool_total_s": med["local"],
        "local_pool_per_item_ms": 1000 * med["local"] / N_ITEMS,
        "local_pool_per_item_excl_startup_ms": 1000 * (med["local"] - statistics.median(startup)) / N_ITEMS,
        "local_pool_startup_one_item_s": statistics.median(startup),
        "inline_total_s": med["inline"],
        "inline_per_item_ms": 1000 * med["inline"] / N_ITEMS,
        "cached_rerun_s": statistics.median(cached),
        "cached_rerun_per_item_ms": 1000 * statistics.median(cached) / N_ITEMS,
        "repeats": REPEATS,
    }
    out = REPO / "bench_results" / "pipeline.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(figures, indent=2) + "\n")
    print("\npipeline runner overhead (medians of %d):" % REPEATS)
    for k, v in figures.items():
        print(f"  {k:40s} {v:.4g}" if isinstance(v, float) else f"  {k:40s} {v}")
    assert figures["cached_rerun_s"] < med["local"]
