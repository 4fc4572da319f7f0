"""One house end to end: spec + seed -> plan (checked) -> occupancy grids -> JSON -> geometry -> USD."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stages.layout.floorplan import FloorPlan, to_floor_plan, write_floor_plan
from stages.layout.occupancy import OccupancyGrid
from stages.layout.model import HousePlan
from stages.layout.plan import sample_plan_and_grids
from stages.layout.spec import LayoutSpec

log = logging.getLogger(__name__)

USD_NAME = "layout.usdc"
PLAN_NAME = "floorplan.json"


@dataclass(frozen=True, eq=False)
class LayoutOutput:
    """usd, plan_json: written files; plan: the JSON model; house: the plan in cm; grids: one per
    floor; seconds: wall time per step (plan incl. checks and grids, json, geometry, usd)."""

    usd: Path
    plan_json: Path
    plan: FloorPlan
    house: HousePlan
    grids: tuple[OccupancyGrid, ...]
    seconds: dict[str, float] = field(default_factory=dict)


def plan_house(spec: LayoutSpec, seed: int) -> tuple[HousePlan, list[OccupancyGrid]]:
    """Sample a checked plan and its occupancy grids (no files)."""
    return sample_plan_and_grids(spec, np.random.default_rng(seed))


def generate_layout(spec: LayoutSpec, seed: int, out_dir: Path, *, usd_name: str = USD_NAME) -> LayoutOutput:
    """Write ``floorplan.json`` (+ grid images) and the layout USD layer into ``out_dir``."""
    from stages.layout.geometry import build_geometry
    from stages.layout.usd import write_layout_usd

    out_dir = Path(out_dir)
    t = {}
    t0 = time.perf_counter()
    house, grids = sample_plan_and_grids(spec, np.random.default_rng(seed))
    t["plan"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fp = to_floor_plan(house, spec, seed, grids)
    plan_json = write_floor_plan(fp, grids, out_dir, PLAN_NAME)
    t["json"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    elements = build_geometry(house)
    t["geometry"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    room_types = {r.id: r.type.value for fl in house.floors for r in fl.rooms}
    usd = write_layout_usd(elements, room_types, len(house.floors), out_dir / usd_name, seed=seed)
    t["usd"] = time.perf_counter() - t0
    log.debug("layout seed %d: %s", seed, t)
    return LayoutOutput(usd, plan_json, fp, house, tuple(grids), t)
