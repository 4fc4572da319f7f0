"""The floor plan as written to disk: ``floorplan.json`` (this pydantic model) plus per floor an
occupancy image (``occupancy_f<i>.png``) and a room-index image (``rooms_f<i>.png``).

All lengths are meters, in the layout USD's frame (Z up; floor ``i``'s walking surface at
``z = elevation``). Room polygons follow the wall centerlines inside the house and the outer wall
faces at the footprint boundary (counter-clockwise). Later stages read plans with
``load_floor_plan(path)`` and grids with ``FloorPlan.occupancy(floor)``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, PrivateAttr

from asset_catalog.annotations import RoomType
from stages.layout.occupancy import OccupancyGrid
from stages.layout.model import HousePlan, Opening, Wall
from stages.layout.spec import LayoutSpec

FORMAT = "agentworld.floorplan/1"
XY = tuple[float, float]
Box2 = tuple[float, float, float, float]


class _M(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class RoomModel(_M):
    """polygon: CCW outline [m]; area [m^2]; shape: rect | l."""

    id: str
    type: RoomType
    floor: int
    polygon: tuple[XY, ...]
    area: float
    shape: Literal["rect", "l"]


class WallModel(_M):
    """start/end: axis of the wall at mid-thickness [m]; box: 2-D footprint (x0, y0, x1, y1) [m];
    thickness, height [m]."""

    id: str
    floor: int
    start: XY
    end: XY
    box: Box2
    thickness: float
    height: float
    exterior: bool


class DoorModel(_M):
    """position: center of the opening at mid-wall [m]; width: clear width [m]; height [m];
    rooms: (room, other room or None for outside); normal: unit vector from rooms[0] towards rooms[1]."""

    id: str
    floor: int
    wall: str
    position: XY
    width: float
    height: float
    rooms: tuple[str, str | None]
    normal: XY
    exterior: bool


class WindowModel(_M):
    """position: center at mid-wall [m]; width [m]; sill, top: heights above the floor [m]."""

    id: str
    floor: int
    wall: str
    room: str
    position: XY
    width: float
    sill: float
    top: float


class StairModel(_M):
    """A staircase from floor_from to floor_to. rise [m], run, width [m]; bottom: where to stand
    before the first step (floor_from), top: where one arrives (floor_to), [m]; direction: unit
    ascent direction of the first flight; footprint: boxes the stairs cover on floor_from; opening:
    boxes cut from floor_to's slab [m]."""

    id: str
    shape: Literal["straight", "l_shaped"]
    floor_from: int
    floor_to: int
    n_risers: int
    rise: float
    run: float
    width: float
    bottom: XY
    top: XY
    direction: XY
    footprint: tuple[Box2, ...]
    opening: tuple[Box2, ...]


class GridRef(_M):
    """Occupancy grid of a floor: image (0 occupied, 128 too close for the robot, 255 traversable)
    and rooms image (room index + 1, 0 none), both relative to the plan file; row 0 at y = origin[1];
    origin [m], cell [m], robot_radius [m], shape (rows, cols)."""

    image: str
    rooms_image: str
    origin: XY
    cell: float
    robot_radius: float
    shape: tuple[int, int]


class FloorModel(_M):
    """elevation: z of the walking surface [m]; ceiling_height: clear height [m]."""

    index: int
    elevation: float
    ceiling_height: float
    rooms: tuple[RoomModel, ...]
    walls: tuple[WallModel, ...]
    doors: tuple[DoorModel, ...]
    windows: tuple[WindowModel, ...]
    grid: GridRef


class FloorPlan(_M):
    """A house plan. footprint (x0, y0, x1, y1) [m]; floor_height: floor-to-floor [m]; slab and
    wall thicknesses [m]; score in [0, 1]; attempts: plans sampled to find it."""

    format: Literal["agentworld.floorplan/1"] = FORMAT
    spec: LayoutSpec
    seed: int
    footprint: Box2
    floor_height: float
    slab_thickness: float
    ceiling_thickness: float
    exterior_wall: float
    interior_wall: float
    floors: tuple[FloorModel, ...]
    stairs: tuple[StairModel, ...]
    score: float
    attempts: int
    _base: Path | None = PrivateAttr(default=None)

    def occupancy(self, floor: int) -> OccupancyGrid:
        """The occupancy grid of a floor, read from the images beside the plan file."""
        from PIL import Image

        if self._base is None:
            raise ValueError("occupancy grids need a plan read with load_floor_plan(path)")
        g = self.floors[floor].grid
        occ = np.asarray(Image.open(self._base / g.image))
        rooms = np.asarray(Image.open(self._base / g.rooms_image))
        if occ.shape != tuple(g.shape) or rooms.shape != tuple(g.shape):
            raise ValueError(f"{self._base / g.image}: grid shape {occ.shape} != {tuple(g.shape)}")
        return OccupancyGrid.from_images(floor, g.origin, g.cell, g.robot_radius, occ, rooms)

    def room(self, rid: str) -> RoomModel:
        for f in self.floors:
            for r in f.rooms:
                if r.id == rid:
                    return r
        raise KeyError(rid)


def load_floor_plan(path: str | Path) -> FloorPlan:
    """Read ``floorplan.json``; raises ValueError naming the file when it is not a valid plan."""
    from pydantic import ValidationError

    path = Path(path)
    try:
        plan = FloorPlan.model_validate_json(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: floor plan not found") from None
    except ValidationError as e:
        first = e.errors()[0]
        loc = ".".join(str(x) for x in first["loc"])
        raise ValueError(f"{path}: not a valid floor plan ({loc}: {first['msg']})") from None
    plan._base = path.parent
    return plan


# ----------------------------------------------------------------------------------------------


def _m(v: float) -> float:
    """cm -> m, rounded to 0.1 mm so the JSON holds no float noise."""
    return round(v / 100.0, 4)


def _box(r) -> Box2:
    return (_m(r.x0), _m(r.y0), _m(r.x1), _m(r.y1))


def _wall_model(w: Wall, height: float) -> WallModel:
    c0, c1 = w.across
    a0, a1 = w.along
    mid = (c0 + c1) / 2
    start, end = ((a0, mid), (a1, mid)) if w.horizontal else ((mid, a0), (mid, a1))
    return WallModel(id=w.id, floor=w.floor, start=(_m(start[0]), _m(start[1])), end=(_m(end[0]), _m(end[1])),
                     box=_box(w.box), thickness=_m(w.thickness), height=round(height, 4), exterior=w.exterior)


def _door_model(o: Opening, w: Wall, fl) -> DoorModel:
    c0, c1 = w.across
    mid = (c0 + c1) / 2
    pos = (o.center, mid) if w.horizontal else (mid, o.center)
    # normal from rooms[0] to rooms[1]: the side of the wall rooms[0] lies on
    probe = (pos[0], c0 - 30) if w.horizontal else (c0 - 30, pos[1])
    first_on_minus = fl.room(o.rooms[0]).contains(*probe)
    sgn = 1.0 if first_on_minus else -1.0
    normal = (0.0, sgn) if w.horizontal else (sgn, 0.0)
    return DoorModel(id=o.id, floor=o.floor, wall=o.wall, position=(_m(pos[0]), _m(pos[1])), width=_m(o.width),
                     height=round(o.z1 - o.z0, 4), rooms=o.rooms, normal=normal, exterior=o.kind == "exterior_door")


def to_floor_plan(plan: HousePlan, spec: LayoutSpec, seed: int, grids: list[OccupancyGrid]) -> FloorPlan:
    """The JSON model of a plan (grid images named occupancy_f<i>.png / rooms_f<i>.png)."""
    floors = []
    for fl, g in zip(plan.floors, grids, strict=True):
        walls = {w.id: w for w in fl.walls}
        rooms = tuple(RoomModel(id=r.id, type=r.type, floor=r.floor, polygon=tuple((_m(x), _m(y)) for x, y in r.outline),
                                area=round(r.area / 1e4, 4), shape="l" if r.is_l else "rect") for r in fl.rooms)
        doors = tuple(_door_model(o, walls[o.wall], fl) for o in fl.openings if o.kind != "window")
        windows = []
        for o in fl.openings:
            if o.kind == "window":
                w = walls[o.wall]
                mid = sum(w.across) / 2
                pos = (o.center, mid) if w.horizontal else (mid, o.center)
                windows.append(WindowModel(id=o.id, floor=o.floor, wall=o.wall, room=o.rooms[0],
                                           position=(_m(pos[0]), _m(pos[1])), width=_m(o.width),
                                           sill=round(o.z0, 4), top=round(o.z1, 4)))
        grid = GridRef(image=f"occupancy_f{fl.index}.png", rooms_image=f"rooms_f{fl.index}.png",
                       origin=g.origin, cell=g.cell, robot_radius=g.robot_radius, shape=g.occupied.shape)
        floors.append(FloorModel(index=fl.index, elevation=round(fl.index * plan.floor_height, 4),
                                 ceiling_height=plan.ceiling_height,
                                 rooms=rooms, walls=tuple(_wall_model(w, plan.ceiling_height) for w in fl.walls),
                                 doors=doors, windows=tuple(windows), grid=grid))
    stairs = []
    for s in plan.stairs:
        t0 = s.treads[0][0]
        cx, cy = (t0.x0 + t0.x1) / 2, (t0.y0 + t0.y1) / 2
        d = (cx - s.bottom[0], cy - s.bottom[1])
        n = max(abs(d[0]), abs(d[1]))
        stairs.append(StairModel(id=s.id, shape=s.shape, floor_from=s.floor, floor_to=s.floor + 1,
                                 n_risers=s.n_risers, rise=round(s.rise, 6), run=_m(s.run), width=_m(s.width),
                                 bottom=(_m(s.bottom[0]), _m(s.bottom[1])), top=(_m(s.top[0]), _m(s.top[1])),
                                 direction=(round(d[0] / n), round(d[1] / n)),
                                 footprint=tuple(_box(r) for r in s.footprint),
                                 opening=tuple(_box(r) for r in s.opening)))
    fp = plan.footprint
    return FloorPlan(spec=spec, seed=seed, footprint=_box(fp), floor_height=round(plan.floor_height, 6),
                     slab_thickness=plan.slab_thickness, ceiling_thickness=plan.ceiling_thickness,
                     exterior_wall=_m(plan.t_ext), interior_wall=_m(plan.t_int), floors=tuple(floors),
                     stairs=tuple(stairs), score=round(plan.score, 6), attempts=plan.attempts)


def write_floor_plan(fp: FloorPlan, grids: list[OccupancyGrid], out_dir: Path, name: str = "floorplan.json") -> Path:
    """Write the JSON and the grid images into ``out_dir``; returns the JSON path."""
    from PIL import Image

    out_dir.mkdir(parents=True, exist_ok=True)
    for fl, g in zip(fp.floors, grids, strict=True):
        Image.fromarray(g.to_image()).save(out_dir / fl.grid.image)
        Image.fromarray((g.room_index + 1).astype(np.uint8)).save(out_dir / fl.grid.rooms_image)
    path = out_dir / name
    path.write_text(fp.model_dump_json(indent=1) + "\n", encoding="utf-8")
    return path
