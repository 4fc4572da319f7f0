"""Benchmark: the same houses settled one model each (chunk 1) and as the K worlds of one model
(``settle_batch(worlds=True)``), in one process: per-scene seconds (build, finalize, simulate),
Warp kernel launches per step and model (all launches of the run, model setup included, over the
steps: an upper bound), and the largest difference of an instance's displacement between
the two. Each configuration runs once untimed first (kernel compile). Houses: ``--work`` of an
earlier ``bench_scene_settle_gpu.py --work DIR`` run (its scenes/s*/scene.usda), else populated.

    python tests/benchmarks/bench_settle_worlds.py --device cpu --scenes 4 --seconds 0.2 --work /tmp/w
    python tests/benchmarks/bench_settle_worlds.py --device cuda:0 --scenes 16 --seconds 2 --cuda-graph
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))


def count_launches():
    """Patch ``wp.launch`` / ``wp.launch_tiled`` to count calls; returns the counter (a one-item list)."""
    import warp as wp

    n = [0]
    for name in ("launch", "launch_tiled"):
        f = getattr(wp, name, None)
        if f is None or getattr(f, "_counted", False):
            continue

        def counted(*a, _f=f, **k):
            n[0] += 1
            return _f(*a, **k)

        counted._counted = True
        setattr(wp, name, counted)
    return n


def compare(scenes: list[Path], device: str, seconds: float, cuda_graph: bool = False) -> dict:
    """Settle ``scenes`` one per model and as worlds of one model (each once untimed first); figures."""
    from stages.scene.settle_batch import settle_batch

    launches = count_launches()
    out: dict = {"device": device, "scenes": len(scenes), "seconds_simulated": seconds, "cuda_graph": cuda_graph}

    def one_each():
        return [settle_batch([s], device=device, seconds=seconds, progress=False, cuda_graph=cuda_graph)
                for s in scenes]

    def worlds():
        return settle_batch(scenes, device=device, seconds=seconds, progress=False, cuda_graph=cuda_graph)

    for name, fn in (("one_per_model", one_each), ("worlds", worlds)):
        fn()  # compile
        launches[0] = 0
        t = time.perf_counter()
        res = fn()
        wall = time.perf_counter() - t
        runs = res if isinstance(res, list) else [res]
        split = {k: round(sum(r.seconds[k] for r in runs) / len(scenes), 3) for k in runs[0].seconds}
        steps = max(1, round(seconds * 250))
        out[name] = {"wall_s_per_scene": round(wall / len(scenes), 3), "s_per_scene": split,
                     "launches_per_step": round(launches[0] / steps / len(runs), 1), "models": len(runs),
                     "passed": sum(sum(r.passed) for r in runs)}
        out[name + "_moved"] = [m for r in runs for m in r.moved]
    a, b = out.pop("one_per_model_moved"), out.pop("worlds_moved")
    out["same_instances"] = all(x.keys() == y.keys() for x, y in zip(a, b))
    out["max_moved_diff_m"] = max(abs(x[k] - y[k]) for x, y in zip(a, b) for k in x)
    out["simulate_ratio"] = round(out["one_per_model"]["s_per_scene"]["simulate"]
                                  / max(out["worlds"]["s_per_scene"]["simulate"], 1e-9), 2)
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--scenes", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=0.2, help="simulated seconds [s]")
    ap.add_argument("--work", type=Path, default=None, help="folder with (or for) populated houses")
    ap.add_argument("--cuda-graph", action="store_true")
    a = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    with tempfile.TemporaryDirectory(prefix="aw_worlds_") as d:
        work = Path(a.work or d)
        have = sorted(work.glob("scenes/s*/scene.usda"), key=lambda p: int(p.parent.name[1:]))
        if len(have) < a.scenes:
            from tests.benchmarks.bench_scene_settle_gpu import make_scenes

            have = make_scenes(a.scenes, work, {"living_room": 1, "kitchen": 1, "bedroom": 1})[0]
        out = compare(have[:a.scenes], a.device, a.seconds, a.cuda_graph)
    print(json.dumps(out, indent=1), flush=True)
    return out


if __name__ == "__main__":
    main()
