"""The task world a teleop session runs in: a kitchen of the built-in default catalog.

:func:`teleop_kitchen` runs (or reuses: the runner caches every item) a two-step job in
``work_dir`` — the default catalog's kitchen categories, then the ingest of one package of each —
and writes a kitchen from ``world_seed`` (:func:`stages.demos.kitchen.write_kitchen`). The same
work dir and seed give the same kitchen, which is what a replay needs. About 20 s the first time
on 2 cores, under 2 s after.
"""

from __future__ import annotations

from pathlib import Path

KITCHEN_CATEGORIES = ("kitchen_counter", "microwave", "fridge", "oven", "door", "dining_table", "mug", "bowl", "can")
KITCHEN_PACKAGES = ("kitchen_counter_00", "microwave_00", "fridge_00", "oven_00", "door_00", "dining_table_00",
                    "mug_04", "bowl_00", "can_00")


def teleop_kitchen(work_dir: Path, world_seed: int = 5, *, scene_id: str = "teleop_kitchen"):
    """A :class:`~stages.demos.kitchen.KitchenWorld` built in ``work_dir`` (see the module docstring)."""
    import numpy as np

    from pipeline import build_job, run_job
    from stages.demos.kitchen import AssetLibrary, write_kitchen

    work_dir = Path(work_dir).resolve()
    out = work_dir / "catalog_job"
    job = {"job": {"name": "teleop_kitchen", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": list(KITCHEN_CATEGORIES)}},
                    {"name": "assets", "kind": "ingest",
                     "config": {"catalog_step": "catalog", "only": list(KITCHEN_PACKAGES)}}]}
    summary = run_job(build_job(job, source="<teleop>", base_dir=work_dir), progress=False)
    failed = {s.name: s.failed for s in summary.steps if s.failed}
    if failed:
        raise RuntimeError(f"teleop: building the kitchen's assets failed in {out} ({failed}); see {out}/logs")
    lib = AssetLibrary.from_folder(out / "assets", out / "catalog" / "default" / "generated.json")
    return write_kitchen(work_dir / f"kitchen_{world_seed}", lib, scene_id=scene_id,
                         rng=np.random.default_rng(world_seed))
