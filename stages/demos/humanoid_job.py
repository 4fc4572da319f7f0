"""The ``humanoid_demos`` job kind: humanoid demonstrations (``stages.demos.humanoid_run``) in the
demos job's kitchens, one dataset shard per kitchen, merged, with a success report and a contact
sheet of the head and wrist views.

Job file (after a ``default_catalog`` step and an ``ingest`` step of the same job, as ``demos``)::

    [[step]]
    name = "humanoid"
    kind = "humanoid_demos"
    [step.config]
    catalog_step = "catalog"
    assets_step = "assets"
    spec = "g1_29dof"                 # an embodiment spec with a legged-with-policy base
    tasks = ["close_drawer"]          # tasks with a humanoid expert (stages.demos.humanoid_experts)
    worlds = 2                        # kitchens (world seeds as the demos job's: the same kitchens)
    episodes_per_task = 15            # per kitchen; episode k has seed 1 + k
    cameras = ["head", "left_wrist", "right_wrist"]   # [] for the success rate only
    width = 128
    height = 96

Items ``<spec>_w<k>``; ``finalize`` merges the shards into ``<out>/datasets/<step>``, writes
``<out>/reports/<step>.json`` (attempts, successes, rates and failure reasons per task, every
episode) and ``<out>/reports/<step>_contact_sheet.png``.
"""

from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

from pipeline.types import ItemContext, ItemError, JobKind, PlanContext, PlannedFailure, WorkItem, derive_seed

log = logging.getLogger(__name__)

FN = "stages.demos.humanoid_job:record_kitchen"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class HumanoidDemosConfig(_Strict):
    """The step's table (module docstring)."""

    catalog_step: str = "catalog"
    assets_step: str = "assets"
    spec: str = "g1_29dof"
    tasks: tuple[str, ...] = ("close_drawer",)
    worlds: int = Field(default=1, ge=1)
    episodes_per_task: int = Field(default=2, ge=1)
    cameras: tuple[str, ...] = ("head", "left_wrist", "right_wrist")
    width: int = Field(default=128, gt=0)
    height: int = Field(default=96, gt=0)
    max_seconds: float = Field(default=40.0, gt=0)

    @field_validator("tasks")
    @classmethod
    def _known(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        from stages.demos.humanoid_experts import HUMANOID_EXPERTS

        bad = [t for t in v if t not in HUMANOID_EXPERTS]
        if bad:
            raise ValueError(f"no humanoid expert for {bad}; have {sorted(HUMANOID_EXPERTS)}")
        return v


class KitchenParams(_Strict):
    """One item: kitchen ``world`` (world seed), the step's settings, the catalog inputs."""

    world: int
    world_seed: int
    config: HumanoidDemosConfig
    generated: str
    packages: dict[str, str]


class KitchenResult(_Strict):
    """scene_id; dataset: the item's shard (final location) or None; episodes: their records."""

    scene_id: str
    dataset: str | None
    episodes: tuple[dict, ...]


def plan_humanoid(config: HumanoidDemosConfig, ctx: PlanContext) -> list[WorkItem | PlannedFailure]:
    from stages.demos.job import _catalog_inputs
    from stages.embodiment import load_spec
    from stages.embodiment.spec import EmbodimentError, spec_files

    ids = [f"{config.spec}_w{w:03d}" for w in range(config.worlds)]
    try:
        load_spec(config.spec)
        generated, packages = _catalog_inputs(config, ctx)
    except (ItemError, EmbodimentError, FileNotFoundError) as e:
        return [PlannedFailure(i, f"{ctx.job_file}: {e}") for i in ids]
    inputs = (generated, *spec_files(config.spec), *sorted(Path(p) for p in packages.values()))
    return [WorkItem(item_id=i, fn=FN, input_files=inputs,
                     params=KitchenParams(world=w, world_seed=derive_seed(ctx.seed, "demos-world", str(w)),
                                          config=config, generated=str(generated), packages=packages))
            for w, i in enumerate(ids)]


def record_kitchen(params: KitchenParams, ctx: ItemContext) -> KitchenResult:
    """Stage function: author the kitchen, run the episodes on the humanoid engine, write the shard."""
    import numpy as np

    from stages.demos.humanoid_run import HumanoidRunConfig, run_kitchen
    from stages.demos.kitchen import AssetLibrary, write_kitchen

    c = params.config
    lib = AssetLibrary.from_packages({k: Path(v) for k, v in params.packages.items()}, Path(params.generated))
    kitchen = write_kitchen(ctx.out_dir / "world", lib, scene_id=f"kitchen_{params.world:03d}",
                            rng=np.random.default_rng(params.world_seed))
    cfg = HumanoidRunConfig(tasks=c.tasks, episodes=c.episodes_per_task, spec=c.spec, cameras=c.cameras,
                            width=c.width, height=c.height, max_seconds=c.max_seconds)
    episodes, shard = run_kitchen(kitchen, cfg, shards_dir=ctx.out_dir, shard_id="dataset")
    written = shard is not None and any(e["success"] for e in episodes)
    return KitchenResult(scene_id=kitchen.scene_id,
                         dataset=str(ctx.final_dir / "dataset") if written else None,
                         episodes=tuple(episodes))


def finalize_humanoid(config: HumanoidDemosConfig, ctx: PlanContext, results: dict[str, Any]) -> None:
    """Merge the shards into ``<work>/datasets/<step>``, write the report and the contact sheet."""
    from stages.dataset import merge_datasets
    from stages.dataset.writer import write_json_atomic
    from stages.demos.humanoid_run import contact_sheet, summarize

    res = [r if isinstance(r, KitchenResult) else KitchenResult.model_validate(r) for r in results.values()]
    step = ctx.step or "humanoid"
    episodes = [e for r in res for e in r.episodes]
    report = summarize(episodes, config.tasks, 0.0)
    del report["wall_seconds"]
    report.update(spec=config.spec, failed_items=dict(ctx.failed.get(step, {})), dataset=None,
                  contact_sheet=None)
    roots = [Path(r.dataset) for r in res if r.dataset]
    if roots:
        out = ctx.work_dir / "datasets" / step
        if out.exists():
            shutil.rmtree(out)      # the previous run's merge; the shards are the source of truth
        merged = merge_datasets(roots, out, repo_id=f"agentworld/{step}")
        report["dataset"] = {"root": str(merged.root), "episodes": merged.episodes, "frames": merged.frames}
        sheet = contact_sheet(merged.root, ctx.work_dir / "reports" / f"{step}_contact_sheet.png")
        report["contact_sheet"] = str(sheet)
    path = ctx.work_dir / "reports" / f"{step}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, report)
    log.info("humanoid demos: %d/%d episodes succeeded; report %s\n%s", report["successes"],
             report["attempts"], path, json.dumps({k: v["rate"] for k, v in report["tasks"].items()}))


HUMANOID_DEMOS_JOB = JobKind(name="humanoid_demos", config=HumanoidDemosConfig, plan=plan_humanoid,
                             finalize=finalize_humanoid,
                             description="humanoid demonstrations (legged-policy base, CLIK arms) in task "
                                         "kitchens: LeRobot shards, merged, success report, contact sheet")
