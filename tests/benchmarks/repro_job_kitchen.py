"""Episodes of the demos jobs' kitchens on the CPU engine (per_world, MuJoCo C, one world, no cameras).

Kitchen ``--kitchen w`` is the demos step's kitchen ``w`` of a job of seed 0 (world seed
``derive_seed(0, "demos-world", w)``: the main job's kitchen_000, demos_success_gpu2's mixed_w000 and
mixed_w001); ``--seeds main`` runs the main job's episode of each task (item ``<task>_w<k>``),
``--seeds mixedN`` the first N episodes of each task of the mixed item ``mixed_w<k>`` (15 basic tasks,
18 per task), or a comma-separated list of instance seeds. ``--cat`` is a work dir holding ``assets/``
and ``catalog/default/generated.json`` (e.g. a main job's out dir). Prints one line per episode and a
JSON summary. Example (issue 12's open_oven regression)::

    PYTHONPATH=$PWD .venv/bin/python tests/benchmarks/repro_job_kitchen.py --cat out/main --kitchen 0 \\
        --tasks open_oven --seeds mixed4
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from pipeline.types import derive_seed

EPISODES_PER_TASK = 18  # demos_success_gpu2's episodes_per_task (the mixed items' plan)


def instances(tasks: list[str], kitchen: int, seeds: str) -> list[tuple[str, int]]:
    """(task, instance seed) of each episode to run (see the module docstring for ``seeds``)."""
    from stages.demos.mixed import plan_episodes
    from stages.demos.tasks import BASIC_TASKS

    out: list[tuple[str, int]] = []
    for t in tasks:
        if seeds == "main":
            item = derive_seed(0, "demos", f"{t}_w{kitchen:03d}")
            out.append((t, derive_seed(item, "episode", "0") % 2**62))
        elif seeds.startswith("mixed"):
            item = derive_seed(0, "demos", f"mixed_w{kitchen:03d}")
            plan = plan_episodes(tuple(BASIC_TASKS), EPISODES_PER_TASK, item)
            out += [(t, s) for task, s in plan if task == t][:int(seeds[5:])]
        else:
            out += [(t, int(s)) for s in seeds.split(",")]
    return out


def run(cat: Path, kitchen: int, jobs: list[tuple[str, int]]) -> list[tuple[str, int, bool, str, int]]:
    """Run ``jobs`` in order in kitchen ``kitchen``; returns (task, seed, success, reason, frames)."""
    import numpy as np

    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    lib = AssetLibrary.from_folder(cat / "assets", cat / "catalog" / "default" / "generated.json")
    ws = derive_seed(0, "demos-world", str(kitchen))
    print("world seed", ws, "episodes", jobs, flush=True)
    rows: list[tuple[str, int, bool, str, int]] = []
    with tempfile.TemporaryDirectory(prefix="repro-kitchen-") as tmp:
        room = write_kitchen(Path(tmp) / "kitchen", lib, scene_id=f"kitchen_{kitchen:03d}",
                             rng=np.random.default_rng(ws))
        eng = BatchEngine(room, panda_root=None, work_dir=Path(tmp) / "kitchen",
                          config=EngineConfig(worlds=1, layout="per_world", record_images=False), seed=ws)
        t0 = [time.perf_counter()]

        def begin(w, ticket):
            return lambda frame: None

        def end(w, ticket, res):
            now = time.perf_counter()
            print(f"{ticket.task:20s} seed {ticket.seed} frames {res.frames} "
                  f"{'ok' if res.success else 'FAILED ' + res.reason} ({now - t0[0]:.0f} s wall)", flush=True)
            rows.append((ticket.task, ticket.seed, res.success, res.reason, res.frames))
            t0[0] = now

        eng.run(Listed(room, {0: [(t, s, None) for t, s in jobs]}), begin=begin, end=end)
    return rows


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cat", type=Path, default=Path("out/main"), help="work dir with assets/ and the catalog")
    p.add_argument("--kitchen", type=int, default=0, help="the job's kitchen index w")
    p.add_argument("--tasks", default="open_oven", help="comma-separated tasks")
    p.add_argument("--seeds", default="main", help="main, mixedN or comma-separated instance seeds")
    p.add_argument("--verbose", action="store_true", help="the experts' log (stages, re-plans)")
    a = p.parse_args()
    if a.verbose:
        import logging

        logging.basicConfig(level=logging.WARNING, format="%(name)s: %(message)s")
        logging.getLogger("stages.demos").setLevel(logging.INFO)
    print("SUMMARY", json.dumps(run(a.cat, a.kitchen, instances(a.tasks.split(","), a.kitchen, a.seeds))))
