"""The ``layout`` job kind: one work item per house; each writes ``layout.usdc``, ``floorplan.json``
and the occupancy images into its item folder (``<out>/<step>/<item_id>/``).

Job file::

    [[step]]
    name = "layouts"
    kind = "layout"
    [[step.config.house]]
    id = "cottage"                 # item ids: cottage_000, cottage_001, ...
    count = 3                      # houses of this spec (different seeds)
    spec = { rooms = { living_room = 1, kitchen = 1, bedroom = 2 }, floors = 2 }

A house's seed is ``spec.seed + k`` when the spec gives one, else the item's seed (derived from the
job seed, the step kind and the item id).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemContext, ItemError, JobKind, PlanContext, PlannedFailure, WorkItem
from stages.layout.spec import LayoutSpec

FN = "stages.layout.job:build_layout"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class HouseEntry(_Strict):
    """id: [a-z0-9_]+ prefix of the item ids; count: houses of this spec; spec: the LayoutSpec."""

    id: str = Field(pattern=r"^[a-z0-9][a-z0-9_]{0,47}$")
    count: int = Field(default=1, ge=1, le=100000)
    spec: LayoutSpec


class LayoutConfig(_Strict):
    house: tuple[HouseEntry, ...] = Field(min_length=1)


class LayoutParams(_Strict):
    """One house: its spec and, when fixed, its seed (else the item's seed is used)."""

    spec: LayoutSpec
    seed: int | None = None


class LayoutResult(_Strict):
    """Paths of the written files (final locations), the seed used, counts and timings [s]."""

    usd: str
    plan: str
    seed: int
    floors: int
    rooms: int
    doors: int
    windows: int
    score: float
    attempts: int
    seconds: dict[str, float]


def plan_layouts(config: LayoutConfig, ctx: PlanContext) -> list[WorkItem | PlannedFailure]:
    """One item per house (entry x count)."""
    items: list[WorkItem | PlannedFailure] = []
    seen: set[str] = set()
    for entry in config.house:
        if entry.id in seen:
            items.append(PlannedFailure(entry.id, f"{ctx.job_file}: duplicate house id {entry.id!r}"))
            continue
        seen.add(entry.id)
        for k in range(entry.count):
            seed = None if entry.spec.seed is None else entry.spec.seed + k
            items.append(WorkItem(item_id=f"{entry.id}_{k:03d}", fn=FN, params=LayoutParams(spec=entry.spec, seed=seed)))
    return items


def build_layout(params: LayoutParams, ctx: ItemContext) -> LayoutResult:
    """Stage function: sample, check and write one house."""
    from stages.layout.build import generate_layout
    from stages.layout.model import LayoutError

    seed = params.seed if params.seed is not None else ctx.seed
    try:
        out = generate_layout(params.spec, seed, ctx.out_dir)
    except LayoutError as e:
        raise ItemError(f"{ctx.item_id}: {e}") from None
    fp = out.plan
    return LayoutResult(
        usd=str(ctx.final_dir / out.usd.name), plan=str(ctx.final_dir / out.plan_json.name), seed=seed,
        floors=len(fp.floors), rooms=sum(len(f.rooms) for f in fp.floors),
        doors=sum(len(f.doors) for f in fp.floors), windows=sum(len(f.windows) for f in fp.floors),
        score=fp.score, attempts=fp.attempts, seconds={k: round(v, 4) for k, v in out.seconds.items()})


LAYOUT_JOB = JobKind(name="layout", config=LayoutConfig, plan=plan_layouts,
                     description="procedural house layouts: plan JSON + occupancy grids + layout USD")
