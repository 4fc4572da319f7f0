"""One generated 3-room flat, one room populated by the scene job with the household-task rules from
given default-catalog packages: the house fixtures of the house task-world tests
(test_demos_house.py: the kitchen, test_demos_house_living.py: the living room)."""

from __future__ import annotations

from pathlib import Path

from stages.scene.rules import HOUSEHOLD_TASK_RULES


def populate_flat(out: Path, name: str, packages: tuple[str, ...], room: str, *, count: int = 1,
                  settle: bool = False, scene: str | None = None) -> tuple[Path, Path]:
    """Run the job (catalog of the packages' categories, 5 variants; ingest of ``packages``; ``count``
    flats with a living room, a kitchen and a bedroom; their ``room`` populated, settled or not) in
    ``out``; assert no step failed. Returns (the scene folder ``scene`` (default: the first), the
    catalog's generated.json)."""
    from pipeline import build_job, run_job

    cats = sorted({p.rsplit("_", 1)[0] for p in packages})
    job = {"job": {"name": name, "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog", "config": {"variants": 5, "categories": cats}},
                    {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog", "only": list(packages)}},
                    {"name": "layouts", "kind": "layout", "config": {"house": [
                        {"id": "flat", "count": count, "spec": {"rooms": {"living_room": 1, "kitchen": 1, "bedroom": 1}}}]}},
                    {"name": "scenes", "kind": "scene", "config": {
                        "assets_step": "assets", "layouts_step": "layouts", "rules": str(HOUSEHOLD_TASK_RULES),
                        "looks": 1, "validate_usd": False, "settle": settle,
                        "group": [{"id": "flat", "layouts": ["flat_*"], "rooms": [room]}]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0, "layouts": 0, "scenes": 0}
    folder = out / "scenes" / scene if scene else next((out / "scenes").iterdir())
    return folder, out / "catalog" / "default" / "generated.json"


def populate_layout_room(library, root: Path, seed: int, room_type: str, rules, attempts: int = 4):
    """Layout ``seed`` (a flat with a living room, a kitchen and a bedroom, written under ``root``) with its
    ``room_type`` room populated by a :class:`~stages.scene.solver.Populator` with ``rules`` (random stream
    ``[seed, attempt]``, up to ``attempts`` tries; the test fails naming every try's reason). Returns
    (populator, room, floor plan)."""
    import numpy as np
    import pytest

    from stages.layout.build import generate_layout
    from stages.layout.floorplan import load_floor_plan
    from stages.layout.spec import LayoutSpec
    from stages.scene.solver import PlacementFailure, Populator

    lay = generate_layout(LayoutSpec(rooms={"living_room": 1, "bedroom": 1, "kitchen": 1}), seed,
                          root / f"layout_{seed}")
    plan = load_floor_plan(lay.plan_json)
    room = next(r for f in plan.floors for r in f.rooms if str(r.type) == room_type)
    why = []
    for attempt in range(attempts):
        pop = Populator(plan, lay.usd, library, rules, np.random.default_rng([seed, attempt]))
        try:
            pop.populate_room(room)
            return pop, room, plan
        except PlacementFailure as e:
            why.append(str(e))
    pytest.fail(f"layout {seed}: the {room_type} was not populated in {attempts} attempts: {why}")
