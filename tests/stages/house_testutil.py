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
