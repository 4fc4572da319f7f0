"""The kitchen catalog job of the demos, engine, teleop and policy tests (its session fixtures,
``kitchen_catalog``, ``kitchen_library`` and ``kitchen_room``, are in conftest.py).

The default catalog's kitchen categories and one package of each (the graspable mug variant among
them): the job :func:`stages.teleop.world.teleop_kitchen` runs, so a teleop work dir holding a copy
of it reuses both steps from the runner's cache.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from stages.teleop.world import KITCHEN_CATEGORIES as KITCHEN
from stages.teleop.world import KITCHEN_PACKAGES as PACKAGES

__all__ = ["KITCHEN", "PACKAGES", "copy_kitchen_catalog", "kitchen_job", "link_kitchen_catalog"]


def kitchen_job(out: Path, extra_steps: list | None = None, name: str = "kitchen_catalog") -> dict:
    """The kitchen catalog job (default catalog, then the ingest of PACKAGES) in ``out``, with
    ``extra_steps`` after its two steps."""
    return {"job": {"name": name, "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
            "step": [{"name": "catalog", "kind": "default_catalog",
                      "config": {"variants": 5, "categories": list(KITCHEN)}},
                     {"name": "assets", "kind": "ingest",
                      "config": {"catalog_step": "catalog", "only": list(PACKAGES)}},
                     *(extra_steps or [])]}


def copy_kitchen_catalog(catalog: Path, dst: Path) -> Path:
    """A fresh work dir for a job that adds steps to the kitchen catalog job: the runner's state and
    the files at the top copied, the ``catalog`` and ``assets`` folders linked to the shared ones (the
    ingest items' keys hold the resolved catalog path, so both steps are cached and nothing is
    written into the links)."""
    dst.mkdir(parents=True)
    for p in catalog.iterdir():
        if p.name in ("catalog", "assets"):
            (dst / p.name).symlink_to(p, target_is_directory=True)
        elif p.is_dir():
            shutil.copytree(p, dst / p.name, symlinks=True)
        else:
            shutil.copy2(p, dst / p.name)
    return dst


def link_kitchen_catalog(catalog: Path, work_dir: Path) -> Path:
    """``work_dir`` for :func:`stages.teleop.world.teleop_kitchen` (and the policy evaluation's
    kitchens, built by it) with ``catalog_job`` linked to the shared kitchen catalog: the same job, so
    both its steps come from the runner's cache and only the kitchen is written."""
    work_dir.mkdir(parents=True, exist_ok=True)
    (work_dir / "catalog_job").symlink_to(catalog, target_is_directory=True)
    return work_dir


def clock_library(out: Path, clocks: tuple[str, ...]):
    """The kitchen categories plus the alarm clocks ``clocks`` (package ids) in ``out`` by the real
    catalog and ingest steps (~20 s on 2 shared cores), as an ``AssetLibrary`` (the set_alarm_clock
    tests: ``test_skill_press.py``, ``test_skill_press_engine.py``)."""
    from pipeline import build_job, run_job
    from stages.demos.kitchen import AssetLibrary

    job = {"job": {"name": "clock", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": [*KITCHEN, "alarm_clock"]}},
                    {"name": "assets", "kind": "ingest",
                     "config": {"catalog_step": "catalog", "only": [*PACKAGES, *clocks]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0}
    return AssetLibrary.from_folder(out / "assets", out / "catalog" / "default" / "generated.json")


def shard_begin(shard, world):
    """An engine ``begin(w, ticket)`` callback that opens the episode of ``ticket`` in ``shard``
    (scene ``world.scene_id``) and returns the shard's frame sink."""
    from stages.dataset import EpisodeInfo

    def begin(w, ticket):
        shard.begin_episode(EpisodeInfo(task=ticket.instruction, task_kind=ticket.task, scene_id=world.scene_id,
                                        seed=ticket.seed, asset_ids=ticket.asset_ids))
        return shard.add_frame

    return begin
