"""Procedural house layouts: rooms, thick walls, doors, windows, connectivity, multi-floor stairs.

Public API::

    from stages.layout import LayoutSpec, generate_layout, load_floor_plan

    out = generate_layout(LayoutSpec(rooms={"living_room": 1, "kitchen": 1, "bedroom": 2}, floors=2),
                          seed=0, out_dir=Path("out/house"))      # layout.usdc + floorplan.json + grids
    plan = load_floor_plan(out.plan_json)                           # FloorPlan (pydantic, meters)
    grid = plan.occupancy(0)                                        # OccupancyGrid of floor 0
    grid.is_traversable(x, y); grid.traversable; grid.room_index

    house, grids = plan_house(spec, seed)                           # in memory, no files
    stages.layout.render.render_plan_png(plan, path)                # top-down picture (pillow)
    stages.layout.render.render_3d_png(usd_path, path)              # Newton SensorCamera, CPU
    stages.layout.simcheck.roll_sphere_down_stairs(usd_path, plan)  # Newton physics check

Job kind ``layout`` (``stages.layout.job``), command ``agentworld render-layout``. Modules: ``spec``
(what to build, room rules), ``model`` (the plan's data in integer cm), ``openings`` (walls, doors,
windows, stairs), ``plan`` (sampling), ``checks`` (validity), ``occupancy``
(grids), ``floorplan`` (JSON model), ``geometry`` (manifold3d solids and box colliders), ``usd``
(the layer, Sdf in a ChangeBlock), ``render``, ``simcheck``, ``build`` (end to end).
Importing this package loads no pxr, warp or newton.
"""

from __future__ import annotations

from stages.layout.build import LayoutOutput, generate_layout, plan_house
from stages.layout.floorplan import FloorPlan, load_floor_plan
from stages.layout.occupancy import OccupancyGrid
from stages.layout.model import HousePlan, LayoutError
from stages.layout.spec import ROOM_RULES, LayoutSpec, RoomRule

__all__ = [
    "ROOM_RULES",
    "FloorPlan",
    "HousePlan",
    "LayoutError",
    "LayoutOutput",
    "LayoutSpec",
    "OccupancyGrid",
    "RoomRule",
    "generate_layout",
    "load_floor_plan",
    "plan_house",
]
