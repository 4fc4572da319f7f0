"""Scripted success of tasks in generated houses (issue 16), CPU: ``--houses`` 3-room flats from the
layout stage, their ``--room`` (kitchen, living_room or bedroom) populated by the scene stage with the
household-task rules from the default catalog's categories of that room (all 5 variants, ingested
by the real job steps), each turned into a task world (:func:`stages.demos.house.house_kitchen`,
:func:`stages.demos.house_living.house_living`, :func:`stages.demos.house_bedroom.house_bedroom`) and run on the batched engine
(``layout="per_world"``, one world, no cameras) for every task and seed.

Run: ``.venv/bin/python tests/benchmarks/bench_house_tasks.py --houses 8 --tasks heat_food --seeds 1``;
``... --room living_room --tasks clean_table_living`` (or ``organize_books``, ``serve_drinks``: the
living room keeps the table's pitcher and cup and adds the drink); ``... --room bedroom --tasks make_bed`` (``--tasks set_alarm_clock``: the nightstand's world,
:func:`stages.demos.house_bedside.house_bedside`) (``--worlds N``: the first N flats whose room converts;
the others' conversion errors are listed apart) (``--work DIR`` keeps and reuses the job's work dir). Prints one line per episode (house, task, seed,
success, reason, frames) and success per task; writes ``bench_results/house_tasks.json``. ``--record OUT``
records the episodes with the engine's cameras: ``OUT/datasets/<task>`` and ``OUT/sheets/<task>.png``
(:mod:`stages.demos.house_record`). A house
whose kitchen cannot be made a task world counts as a failed episode with the conversion's reason.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

CATEGORIES = ("fridge", "kitchen_counter", "microwave", "dish_rack", "sponge", "plate", "mug", "oven")
#: the living room's (the household rules require the pillows on the sofa)
LIVING_CATEGORIES = ("pillow", "sofa", "tv_stand", "coffee_table", "bookshelf", "trash_can", "crumpled_paper",
                     "book", "pitcher", "cup")
#: the bedroom's (make the bed: stages.demos.house_bedroom)
BEDROOM_CATEGORIES = ("bed", "nightstand", "wardrobe", "dresser", "chair", "rug", "pillow", "cushion",
                      "crumpled_paper", "trash_can", "alarm_clock", "book", "hanger")
ROOM_CATEGORIES = {"kitchen": CATEGORIES, "living_room": LIVING_CATEGORIES, "bedroom": BEDROOM_CATEGORIES}


def build_houses(out: Path, n: int, room: str = "kitchen") -> list[Path]:
    """The populated flats' scene folders in work dir ``out`` (the job's items are cached there)."""
    from pipeline import build_job, run_job
    from stages.scene.rules import HOUSEHOLD_TASK_RULES

    job = {"job": {"name": "house_tasks", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": list(ROOM_CATEGORIES[room])}},
                    {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog"}},
                    {"name": "layouts", "kind": "layout", "config": {"house": [
                        {"id": "flat", "count": n, "spec": {"rooms": {"living_room": 1, "kitchen": 1, "bedroom": 1}}}]}},
                    {"name": "scenes", "kind": "scene", "config": {
                        "assets_step": "assets", "layouts_step": "layouts", "rules": str(HOUSEHOLD_TASK_RULES),
                        "looks": 1, "validate_usd": False,
                        "group": [{"id": "flat", "layouts": ["flat_*"], "rooms": [room]}]}}]}
    run_job(build_job(job, source="<bench>", base_dir=out.parent), progress=False)
    return sorted(p for p in (out / "scenes").iterdir() if (p / "scene.json").is_file())


def run(work: Path, houses: int, tasks: list[str], seeds: list[int], room: str = "kitchen",
        worlds: int | None = None, record: Path | None = None) -> dict:
    """The episodes of ``tasks`` x ``seeds`` in the first ``houses`` flats' ``room`` task worlds; with
    ``worlds``, in the first ``worlds`` flats whose room converts (the others' conversion errors are
    listed apart, not counted as episodes); with ``record``, the episodes recorded by the engine's
    cameras into ``record`` (:mod:`stages.demos.house_record`: a dataset and a contact sheet per task)."""
    from stages.demos.house import house_kitchen
    from stages.demos.house_bedroom import house_bedroom
    from stages.demos.house_bedside import house_bedside
    from stages.demos.house_living import house_living
    from stages.demos.multistage import needs_clock, needs_drink, needs_household, needs_wardrobe
    from stages.demos.house_record import HouseRecordConfig, merge_and_sheet, run_world

    rows, unconverted, converted = [], [], 0
    dishes = needs_household(tasks) or bool({"wipe_plate", "place_in_rack"} & set(tasks))  # the kitchen's dish rack
    make = {"kitchen": lambda *a, **k: house_kitchen(*a, **k, dishes=dishes),
            "bedroom": lambda *a, **k: house_bedroom(*a, **k, multiccd=needs_wardrobe(tasks)),
            "living_room": lambda *a, **k: house_living(*a, **k, drink=needs_drink(tasks))}[room]
    if room == "bedroom" and needs_clock(tasks):  # the alarm clock's world: the nightstand as the surface
        if not all(needs_clock([t]) for t in tasks):
            raise SystemExit(f"bench_house_tasks: run the clock tasks apart from the bed's ({tasks})")
        make = house_bedside
    for scene in build_houses(work / "out", houses, room)[:houses]:
        if worlds is not None and converted >= worlds:
            break
        try:
            w = make(scene, work / "task" / scene.name, work / "out" / "catalog" / "default" / "generated.json",
                              scene_id=scene.name)
        except Exception as e:  # noqa: BLE001 - counted with its reason
            if worlds is not None:
                unconverted.append(f"{scene.name}: {e}")
                print("conversion:", unconverted[-1], flush=True)
                continue
            rows += [{"house": scene.name, "task": t, "seed": s, "success": False, "reason": f"conversion: {e}",
                      "frames": 0} for t in tasks for s in seeds]
            print(rows[-1], flush=True)
            continue
        converted += 1
        from stages.demos.multistage import sample_task

        plan = []
        for t in tasks:  # a world that lacks what a task needs (a bedroom without a wardrobe) counts it failed
            for s in seeds:
                try:
                    sample_task(t, w, s)
                    plan.append((t, s, None))
                except Exception as e:  # noqa: BLE001 - counted with its reason
                    rows.append({"house": scene.name, "task": t, "seed": s, "success": False,
                                 "reason": f"sample: {e}", "frames": 0})
                    print(rows[-1], flush=True)
        if not plan:
            continue
        def end(t, r, name=scene.name):
            rows.append({"house": name, "task": t.task, "seed": t.seed, "success": r.success, "reason": r.reason,
                         "frames": r.frames})
            print(rows[-1], flush=True)

        run_world(w, scene.name, plan, work / "engine" / scene.name, end, out=record,
                  record=HouseRecordConfig() if record is not None else None)
    per = {t: f"{sum(r['success'] for r in rows if r['task'] == t)}/{sum(r['task'] == t for r in rows)}" for t in tasks}
    from collections import Counter

    reasons = {t: dict(Counter(r["reason"] for r in rows if r["task"] == t and not r["success"])) for t in tasks}
    print("success per task:", per)
    print("failure reasons (s<stage>_<skill>.<reason>):", reasons)
    if worlds is not None:
        print(f"task worlds: {converted}; not converted: {len(unconverted)}")
    res = {"episodes": rows, "success": per, "failures": reasons, "unconverted": unconverted}
    if record is not None:
        res["recorded"] = merge_and_sheet(record, tasks)
        print("recorded:", res["recorded"])
    return res


@pytest.mark.benchmark
def test_house_tasks(tmp_path):
    res = run(tmp_path, 2, ["heat_food"], [1])
    Path("bench_results").mkdir(exist_ok=True)
    Path("bench_results/house_tasks.json").write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--houses", type=int, default=4)
    ap.add_argument("--tasks", nargs="+", default=["heat_food"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1])
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--room", choices=tuple(ROOM_CATEGORIES), default="kitchen")
    ap.add_argument("--worlds", type=int, default=None,
                    help="run in the first N flats whose room converts (conversion failures listed apart)")
    ap.add_argument("--record", type=Path, default=None,
                    help="record the episodes (3 cameras, 128x96) into OUT/datasets/<task> and OUT/sheets/<task>.png")
    a = ap.parse_args()
    t0 = time.time()
    work = a.work or Path(tempfile.mkdtemp(prefix="house_tasks_"))
    res = run(work, a.houses, a.tasks, a.seeds, a.room, a.worlds, a.record)
    res["wall_seconds"] = round(time.time() - t0, 1)
    Path("bench_results").mkdir(exist_ok=True)
    Path("bench_results/house_tasks.json").write_text(json.dumps(res, indent=1))
