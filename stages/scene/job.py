"""The ``scene`` job kind: populated, lit, material-varied scenes from layouts and ingested assets.

One work item per (layout house x population); each writes ``scene.usda`` (+ sublayers, textures,
``scene.json``) into ``<out>/<step>/<layout id>_p<k>/``. Job file::

    [[step]]
    name = "scenes"
    kind = "scene"
    [step.config]
    assets_step = "assets"          # an ingest step: its index <out>/catalog.sqlite lists the packages
    layouts_step = "layouts"        # a layout step: floor plans + layout layers
    # rules = "../stages/scene/rules/default.toml"   # placement rules, relative to the job file (default: built in)
    attempts = 4                    # populate attempts per scene (different sub-seeds) before failing
    looks = 3                       # material variants per scene (variant set "look")
    # settle_early_exit = true      # stop the 2 s settle once every body is still (see StillExit)
    [[step.config.group]]
    id = "living"                   # a name for the summary
    layouts = ["living_*"]          # layout item ids (fnmatch patterns)
    populations = 5                 # scenes per layout
    rooms = ["living_room"]         # room types to populate (default: all rooms of the house)

Each attempt that fails (a required rule cannot be met, a check fails after repairs) is recorded
with its reason in the item's result; an item fails (ItemError) only when all its attempts did.
``finalize`` writes ``<out>/reports/<step>_summary.json``: scenes emitted, failed items with their
reasons, attempts rejected by reason, room arrangements given up by reason (a required entry could
not be placed, the room was arranged again), candidate placements rejected by reason, settle
repairs (instances dropped) by reason.
"""

from __future__ import annotations

import fnmatch
import json
import logging
import shutil
from collections import Counter
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemContext, ItemError, JobKind, PlanContext, PlannedFailure, WorkItem
from stages.scene.rules import DEFAULT_RULES, rule_files

log = logging.getLogger(__name__)

FN = "stages.scene.job:build_scene_item"
CODE_DEPS = ("stages.scene", "stages.layout.floorplan", "asset_catalog.index")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SceneGroup(_Strict):
    """id: name of the group; layouts: fnmatch patterns of layout item ids; populations: scenes per
    layout; rooms: room types to populate (empty: all)."""

    id: str = Field(pattern=r"^[a-z0-9][a-z0-9_]{0,47}$")
    layouts: tuple[str, ...] = ("*",)
    populations: int = Field(default=1, ge=1, le=1000)
    rooms: tuple[str, ...] = ()


class SceneConfig(_Strict):
    """See the module docstring. settle_seconds [s], settle_tolerance [m]; validate/settle switch
    the checks (both on for real jobs)."""

    assets_step: str
    layouts_step: str
    rules: Path | None = None
    attempts: int = Field(default=4, ge=1, le=50)
    looks: int = Field(default=3, ge=1, le=16)
    settle_seconds: float = Field(default=2.0, gt=0.0)
    settle_tolerance: float = Field(default=0.01, gt=0.0)
    max_repairs: int = Field(default=2, ge=0, le=10)
    validate_usd: bool = True
    settle: bool = True
    settle_early_exit: bool = True
    group: tuple[SceneGroup, ...] = Field(min_length=1)


class SceneParams(_Strict):
    """One scene: the layout's plan and USD, the catalog index, the rules file, the rooms to populate,
    the population number and the options."""

    layout_id: str
    population: int
    group: str
    plan: str
    layout_usd: str
    index: str
    rules: str
    rooms: tuple[str, ...]
    attempts: int
    looks: int
    settle_seconds: float
    settle_tolerance: float
    max_repairs: int
    validate_usd: bool
    settle: bool
    settle_early_exit: bool = True


class RejectedAttempt(_Strict):
    attempt: int
    reason: str


class SceneResult(_Strict):
    """scene: final path of scene.usda; instances, rooms; rejected: the attempts that failed and why;
    repairs: instances dropped by the settle check; settle_max_move [m]; validation_warnings;
    candidates_rejected: rejected candidate placements by reason; arrangements_rejected: room
    arrangements given up (a required entry failed; the room was arranged again) by reason, in the
    attempt that succeeded; settle_simulated: seconds simulated by the settle check (early exit);
    seconds by phase."""

    scene: str
    group: str
    layout_id: str
    attempt: int
    instances: int
    rooms: dict[str, str]
    rejected: tuple[RejectedAttempt, ...]
    repairs: tuple[str, ...]
    settle_max_move: float
    validation_warnings: int
    candidates_rejected: dict[str, int]
    arrangements_rejected: dict[str, int] = {}
    settle_simulated: float = 0.0
    seconds: dict[str, float]


def plan_scenes(config: SceneConfig, ctx: PlanContext) -> list[WorkItem | PlannedFailure]:
    """One item per (layout matching a group x population)."""
    from asset_catalog.index import index_path

    layouts = ctx.previous.get(config.layouts_step)
    if layouts is None:
        return [PlannedFailure(g.id, f"{ctx.job_file}: scene step: layouts_step {config.layouts_step!r} has no "
                                     f"results (is it an earlier step?)") for g in config.group]
    if config.assets_step not in ctx.previous:
        return [PlannedFailure(g.id, f"{ctx.job_file}: scene step: assets_step {config.assets_step!r} has no "
                                     f"results (is it an earlier step?)") for g in config.group]
    index = index_path(ctx.work_dir)
    rules = Path(config.rules) if config.rules else DEFAULT_RULES
    items: list[WorkItem | PlannedFailure] = []
    for g in config.group:
        ids = sorted(i for i in layouts if any(fnmatch.fnmatchcase(i, p) for p in g.layouts))
        if not ids:
            items.append(PlannedFailure(g.id, f"{ctx.job_file}: scene group {g.id!r}: no layout matches "
                                              f"{list(g.layouts)}"))
            continue
        for lid in ids:
            lr = layouts[lid]
            for k in range(g.populations):
                p = SceneParams(layout_id=lid, population=k, group=g.id, plan=lr.plan, layout_usd=lr.usd,
                                index=str(index), rules=str(rules), rooms=g.rooms, attempts=config.attempts,
                                looks=config.looks, settle_seconds=config.settle_seconds,
                                settle_tolerance=config.settle_tolerance, max_repairs=config.max_repairs,
                                validate_usd=config.validate_usd, settle=config.settle,
                                settle_early_exit=config.settle_early_exit)
                items.append(WorkItem(item_id=f"{lid}_p{k}", fn=FN, params=p,
                                      input_files=(Path(lr.plan), Path(lr.usd), index, *rule_files(rules)),
                                      depends_on=(f"{config.layouts_step}/{lid}",)))
    return items


def build_scene_item(params: SceneParams, ctx: ItemContext) -> SceneResult:
    """Stage function: up to ``attempts`` attempts at one scene; the first that passes every check wins."""
    from stages.scene.build import BuildOptions, SceneRejected, build_scene
    from stages.scene.rules import RulesError, load_rules
    from stages.scene.solver import Library

    try:
        rules = load_rules(params.rules)
    except RulesError as e:
        raise ItemError(str(e)) from None
    try:
        library = Library.from_index(Path(params.index))
    except FileNotFoundError as e:
        raise ItemError(str(e)) from None
    opts = BuildOptions(rooms=params.rooms, n_looks=params.looks, settle_seconds=params.settle_seconds,
                        settle_tolerance=params.settle_tolerance, max_repairs=params.max_repairs,
                        validate=params.validate_usd, settle=params.settle,
                        settle_early_exit=params.settle_early_exit,
                        cache_dir=ctx.work_dir / "cache" / "scene_checks")
    rejected: list[RejectedAttempt] = []
    for a in range(params.attempts):
        if ctx.out_dir.exists():
            shutil.rmtree(ctx.out_dir)
        ctx.out_dir.mkdir(parents=True)
        try:
            s = build_scene(Path(params.plan), Path(params.layout_usd), library, rules, ctx.rng(f"attempt{a}"),
                            ctx.out_dir, ctx.final_dir, opts)
        except SceneRejected as e:
            log.info("%s attempt %d rejected: %s", ctx.item_id, a, e)
            rejected.append(RejectedAttempt(attempt=a, reason=str(e)))
            continue
        return SceneResult(scene=str(ctx.final_dir / "scene.usda"), group=params.group, layout_id=params.layout_id,
                           attempt=a, instances=len(s.instances), rooms=s.rooms, rejected=tuple(rejected),
                           repairs=s.repairs, settle_max_move=s.settle_max_move,
                           validation_warnings=s.validation_warnings, candidates_rejected=s.candidates_rejected,
                           arrangements_rejected=s.arrangements_rejected, settle_simulated=s.settle_simulated,
                           seconds=s.seconds)
    raise ItemError(f"{ctx.item_id}: no valid scene in {params.attempts} attempts: "
                    + " | ".join(r.reason for r in rejected)[:600])


def reason_kind(reason: str) -> str:
    """A short class of a rejection reason (its text up to the first detail)."""
    head = reason.split(":", 1)[0]
    if head == "placement":
        tail = reason.split(":", 2)[-1]
        return "placement: " + tail.split("(")[0].strip()
    return head


def finalize_scenes(config: SceneConfig, ctx: PlanContext, results: dict[str, Any]) -> None:
    """Write ``<work_dir>/reports/<step>_summary.json`` and log the totals."""
    failed = ctx.failed.get(ctx.step, {}) if ctx.step else {}
    attempts = Counter(reason_kind(r.reason) for res in results.values() for r in res.rejected)
    cands: Counter[str] = Counter()
    arrangements: Counter[str] = Counter()
    for res in results.values():
        cands.update(res.candidates_rejected)
        arrangements.update(res.arrangements_rejected)
    by_group = Counter(res.group for res in results.values())
    summary = {
        "scenes_emitted": len(results),
        "scenes_failed": len(failed),
        "scenes_by_group": dict(sorted(by_group.items())),
        "instances_total": sum(r.instances for r in results.values()),
        "attempts_rejected": sum(len(r.rejected) for r in results.values()),
        "attempts_rejected_by_reason": dict(attempts.most_common()),
        "failed_items": failed,
        "room_arrangements_rejected": sum(arrangements.values()),
        "room_arrangements_rejected_by_reason": dict(arrangements.most_common(30)),
        "settle_repairs": sum(len(r.repairs) for r in results.values()),
        "settle_repairs_by_reason": dict(Counter(_repair_kind(x) for r in results.values() for x in r.repairs)
                                         .most_common(20)),
        "settle_max_move_m": max((r.settle_max_move for r in results.values()), default=0.0),
        "settle_simulated_s_median": _median([r.settle_simulated for r in results.values()]),
        "candidates_rejected_by_reason": dict(cands.most_common(40)),
        "seconds_median": _median_seconds(results),
    }
    out = ctx.work_dir / "reports" / f"{ctx.step or 'scenes'}_summary.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    log.info("scenes: %d emitted, %d failed, %d attempts rejected (%s) -> %s", len(results), len(failed),
             summary["attempts_rejected"], ", ".join(f"{k}: {v}" for k, v in attempts.most_common(5)), out)


def _repair_kind(repair: str) -> str:
    """'dropped book_03 (moved 1.4 cm)' -> 'dropped book'."""
    head = repair.split(" (")[0]
    return head.rsplit("_", 1)[0] if head[-2:].isdigit() else head


def _median(values: list[float]) -> float:
    import numpy as np

    return round(float(np.median(values)), 3) if values else 0.0


def _median_seconds(results: dict[str, Any]) -> dict[str, float]:
    import numpy as np

    keys = sorted({k for r in results.values() for k in r.seconds})
    return {k: round(float(np.median([r.seconds.get(k, 0.0) for r in results.values()])), 3) for k in keys}


SCENE_JOB = JobKind(name="scene", config=SceneConfig, plan=plan_scenes, finalize=finalize_scenes,
                    description="populated, lit, material-varied scene USDs from layouts + ingested assets")
