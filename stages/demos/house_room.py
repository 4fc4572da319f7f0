"""What every room of a generated house needs to become a task world (issue 16), whatever the room:
the scene's records of one room (:func:`read_room`), the rigid motion of the whole house into the
task frame (:class:`RoomFrame`: a multiple of 90 deg about +Z, the room's corner at the origin), the
task scene layer that sublayers the house, moves it, deactivates cut instances and moves single
instances (:func:`write_task_scene`), and the world base class whose planner obstacles are the
floor's walls and the room's floor furniture and whose robot starts inside the room
(:class:`HouseRoom`, its kitchen-only fields filled by :func:`room_fields`), and the checks the rooms
share (:func:`top_surface`, :func:`overlaps`, :func:`base_free`). The kitchen
(:mod:`stages.demos.house`), the living room (:mod:`stages.demos.house_living`) and the bedroom
(:mod:`stages.demos.house_bedroom`) build on it.

Frame: the task frame, Z up, metres, radians: ``p_task = Rz(theta) p_house + t``
(:attr:`HouseRoom.frame` = (tx, ty, theta)).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from pipeline.types import ItemError
from stages.demos.kitchen import KitchenWorld
from stages.demos.packages import CatalogAsset, Placed

FLOOR_MIN_HEIGHT = 0.03  # floor furniture lower than this (rugs) is no obstacle [m]


@dataclass(frozen=True, kw_only=True, eq=False)
class HouseRoom(KitchenWorld):
    """A :class:`~stages.demos.kitchen.KitchenWorld` in one room of a generated house. house: the
    house's scene USD; room: the room's id; frame (tx, ty, theta) [m, rad]: house -> task frame; area:
    the room's floor (xmin, ymin, xmax, ymax) in the task frame [m]; walls: footprints (K, 4) of the
    floor's walls [m]; furniture: the room's floor furniture by instance name (task frame); cut: the
    instances the task scene deactivates; moved: (instance, its position in the house frame [m])
    where the task scene moved one instance, else None; anchor: a floor point (x, y) [m] the task's
    base drives to (None: any free start), starts are drawn only where a path to it exists
    (:func:`~stages.demos.sampling.free_start`)."""

    house: Path
    room: str
    frame: tuple[float, float, float]
    area: tuple[float, float, float, float]
    walls: tuple[tuple[float, float, float, float], ...]
    furniture: dict
    cut: tuple[str, ...]
    moved: tuple | None = None
    anchor: tuple[float, float] | None = None

    def nav_boxes(self) -> np.ndarray:
        return np.asarray(list(self.walls) + obstacles(self.furniture.values()), float)

    def nav_bounds(self) -> tuple[float, float, float, float]:
        x0, y0, x1, y1 = self.area
        return (x0 - 0.2, y0 - 0.2, x1 + 0.2, y1 + 0.2)

    def start_area(self) -> tuple[float, float, float, float]:
        """The room's floor less 0.3 m along the walls (a house's room is smaller than the task
        kitchen: no band before the work surface is kept free of starts)."""
        x0, y0, x1, y1 = self.area
        return (x0 + 0.3, y0 + 0.3, x1 - 0.3, y1 - 0.3)

    def start_boxes(self) -> np.ndarray:
        return self.nav_boxes()

    #: placed roles the room's tasks go to besides the work surface (the kitchen's fridge, the living
    #: room's bookshelf): the third-person camera keeps them in view too
    VIEW_ROLES: ClassVar[tuple[str, ...]] = ()

    def third_person_view(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """The engine's third-person camera (eye, target) [m, task frame], 2.1 m high inside the room
        (the kitchen's corner view would look at a house room's wall). Without :attr:`VIEW_ROLES`:
        behind the base's side of the work surface (-Y), the first of a few spots (left, right, then
        straight behind, farther first) 0.25 m clear of the walls and the floor furniture, looking at
        the surface's middle. With them: :func:`view_over` of the work surface with the floor before
        it (where the base stands) and those roles' footprints with the floor around them."""
        x0, y0, x1, y1 = self.area
        cx0, cy0, cx1, cy1 = self.counter_rect
        cx, cy = 0.5 * (cx0 + cx1), 0.5 * (cy0 + cy1)
        boxes = list(self.walls) + obstacles(self.furniture.values())
        roles = [self.placed[r].footprint() for r in self.VIEW_ROLES if r in self.placed]
        if roles:
            rects = [(cx0, cy0 - VIEW_BASE_STRIP, cx1, cy1)] + [
                (a - VIEW_AROUND, b - VIEW_AROUND, c + VIEW_AROUND, d + VIEW_AROUND) for a, b, c, d in roles]
            got = view_over(rects, self.area, boxes, float(self.counter_z))
            if got is not None:
                return got
        spots = [(cx + dx, cy0 + dy) for dy in (-1.8, -1.4, -1.0) for dx in (-1.0, 1.0, -0.5, 0.5, 0.0)]
        inside = [p for p in spots if x0 + 0.2 <= p[0] <= x1 - 0.2 and y0 + 0.2 <= p[1] <= y1 - 0.2]
        free = [p for p in inside if not any(b[0] - 0.25 < p[0] < b[2] + 0.25 and b[1] - 0.25 < p[1] < b[3] + 0.25
                                              for b in boxes)]
        ex, ey = (free or inside or [(min(max(cx, x0 + 0.2), x1 - 0.2), min(max(cy0 - 1.0, y0 + 0.2), y1 - 0.2))])[0]
        return (float(ex), float(ey), 2.1), (float(cx), float(cy), float(self.counter_z))


VIEW_HEIGHT = 2.1       # the third-person camera's height [m]
VIEW_HALF_ANGLE = 0.5   # [rad] half the third-person camera's vertical field of view (the engine's 1.0 rad)
VIEW_ASPECT = 4 / 3     # the third-person image's width / height the view is chosen for (128 x 96, 320 x 240)
VIEW_BASE_STRIP = 0.5   # floor before the work surface where the base stands, kept in view [m]
VIEW_AROUND = 0.3       # floor around a VIEW_ROLES footprint kept in view (the base before it) [m]
VIEW_MIN_DISTANCE = 2.0  # [m] an eye nearer the target sees the robot's back more than the task


def view_over(rects, area, boxes, z: float, step: float = 0.25) -> tuple | None:
    """A third-person view (eye, target) [m] that sees every rectangle of ``rects`` (xmin, ymin, xmax,
    ymax), clipped to the room ``area``, at height ``z`` [m]: the eye on a ``step`` grid of the room's
    floor 0.2 m inside its walls, 0.25 m clear of ``boxes`` (walls, furniture), :data:`VIEW_HEIGHT`
    high, looking at the rectangles' middle at height ``z``; the 4 corners of their bounding box at
    height ``z`` within the view (half angles :data:`VIEW_HALF_ANGLE` and its :data:`VIEW_ASPECT`
    wider horizontal one, less 5%). Of the eyes that see all, the nearest one at least
    :data:`VIEW_MIN_DISTANCE` from the target on the rectangles' -Y side (the base's side of the work
    surface), else the nearest such one anywhere, else the farthest; None when no eye sees all."""
    x0, y0, x1, y1 = area
    bx0 = max(min(r[0] for r in rects), x0)
    by0 = max(min(r[1] for r in rects), y0)
    bx1 = min(max(r[2] for r in rects), x1)
    by1 = min(max(r[3] for r in rects), y1)
    target = np.array([0.5 * (bx0 + bx1), 0.5 * (by0 + by1), z])
    corners = np.array([(x, y, z) for x in (bx0, bx1) for y in (by0, by1)])
    tan = math.tan(VIEW_HALF_ANGLE) * 0.95
    tan_h = tan * VIEW_ASPECT
    best = None
    for ex in np.arange(x0 + 0.2, x1 - 0.2 + 1e-9, step):
        for ey in np.arange(y0 + 0.2, y1 - 0.2 + 1e-9, step):
            if any(b[0] - 0.25 < ex < b[2] + 0.25 and b[1] - 0.25 < ey < b[3] + 0.25 for b in boxes):
                continue
            eye = np.array([ex, ey, VIEW_HEIGHT])
            f = target - eye
            dist = float(np.linalg.norm(f))
            f /= dist
            right = np.cross(f, (0.0, 0.0, 1.0))
            right /= np.linalg.norm(right)
            up = np.cross(right, f)
            d = corners - eye
            depth = d @ f
            if (depth <= 0.1).any() or (np.abs(d @ right) > tan_h * depth).any() or (np.abs(d @ up) > tan * depth).any():
                continue
            key = (dist < VIEW_MIN_DISTANCE, ey > target[1], dist if dist >= VIEW_MIN_DISTANCE else -dist)
            if best is None or key < best[0]:
                best = (key, (float(ex), float(ey), VIEW_HEIGHT))
    return None if best is None else (best[1], tuple(float(v) for v in target))


def obstacles(placed) -> list[tuple[float, float, float, float]]:
    """Footprints [m] of the floor furniture among ``placed`` that the base cannot cross (rugs can)."""
    return [p.footprint() for p in placed if p.asset.hi[2] - p.asset.lo[2] >= FLOOR_MIN_HEIGHT]


def room_fields(rs: RoomScene, rf: RoomFrame, rect: tuple[float, float, float, float], z: float,
                spot: tuple[float, float]) -> dict:
    """The :class:`HouseRoom` fields a non-kitchen room fills the same way: its work surface
    ``rect`` (xmin, ymin, xmax, ymax) at height ``z`` [m] as both the table and the counter (``spot``
    (x, y) [m]: the counter spot), the kitchen-only facts (microwave cavity, button, mug, bowl, looks)
    zero, the spawn to be drawn (:func:`spawn_in`), and the house, room and frame of ``rs`` / ``rf``."""
    return dict(size=rf.size, wall_thickness=0.0, spawn=(0.0, 0.0, 0.0), counter_z=z, counter_rect=rect,
                counter_spot=spot, table_z=z, table_rect=rect, cavity=(0.0, 0.0, 0.0, 0.0), cavity_z=0.0,
                cavity_height=0.0, button=(0.0, 0.0, 0.0), button_travel=0.0, button_push=(0.0, 1.0, 0.0),
                mug_radius=0.0, mug_height=0.0, bowl_radius=0.0, materials={}, look=None, house=rs.house.resolve(),
                room=rs.room, frame=rf.frame, area=rf.area, walls=rf.walls)


def top_surface(placed: Placed) -> tuple[tuple[float, float, float, float], float]:
    """The highest top (not inside) surface of furniture ``placed``: its rectangle (xmin, ymin, xmax,
    ymax) and height in the task frame [m]. ItemError when it has none."""
    tops = [s for s in placed.info.get("surfaces", []) if not s["inside"]]
    if not tops:
        raise ItemError(f"{placed.asset.usd}: {placed.asset.asset_id} has no top surface")
    top = max(tops, key=lambda s: s["z"])
    return placed.rect(top["lo"], top["hi"]), float(placed.position[2] + top["z"])


def overlaps(a, b, margin: float) -> bool:
    """Whether boxes ``a`` and ``b`` (xmin, ymin, xmax, ymax) [m] come nearer than ``margin`` [m]."""
    return a[0] < b[2] + margin and b[0] < a[2] + margin and a[1] < b[3] + margin and b[1] < a[3] + margin


def base_free(goal, walls, boxes) -> bool:
    """Whether the staging pose of base pose ``goal`` (x, y, yaw facing +Y), COUNTER_STAGE behind it,
    is free of ``walls`` and ``boxes`` (the base inflated by its radius, as the planner does; the goal
    itself stands nearer the table than that, as in the task kitchen: stages.demos.house._reachable_y)."""
    from stages.demos.driver import ROBOT_RADIUS
    from stages.demos.experts import COUNTER_STAGE
    from stages.demos.planner import NavGrid

    xs = [b[0] for b in walls] + [b[2] for b in walls]
    ys = [b[1] for b in walls] + [b[3] for b in walls]
    grid = NavGrid.from_boxes((min(xs), min(ys), max(xs), max(ys)), np.asarray(list(walls) + list(boxes), float))
    blocked = grid.inflate(ROBOT_RADIUS)
    cells = [grid.cell_of(goal[0] + dx, goal[1] - COUNTER_STAGE) for dx in (-0.05, 0.0, 0.05)]
    return all(0 <= iy < blocked.shape[0] and 0 <= ix < blocked.shape[1] and not blocked[iy, ix] for iy, ix in cells)


def rot2(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _rel(target: Path, layer_dir: Path) -> str:
    r = os.path.relpath(Path(target).resolve(), Path(layer_dir).resolve()).replace(os.sep, "/")
    return r if r.startswith(".") else f"./{r}"


def floor_plan_of(scene_usd: Path) -> Path:
    """The ``floorplan.json`` beside the layout layer that a scene's ``/World/Layout`` references."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(scene_usd))
    prim = layer.GetPrimAtPath("/World/Layout") if layer else None
    refs = list(prim.referenceList.GetAddedOrExplicitItems()) if prim else []
    if not refs:
        raise ItemError(f"{scene_usd}: no /World/Layout reference to a layout layer")
    plan = (Path(scene_usd).parent / refs[0].assetPath).resolve().parent / "floorplan.json"
    if not plan.is_file():
        raise ItemError(f"{scene_usd}: the layout's floor plan {plan} is missing")
    return plan


def asset_of(rec: dict, info: dict[str, dict]) -> CatalogAsset:
    """The catalog package of a scene instance record (``scene.json``)."""
    gen = info.get(rec["asset_id"])
    if gen is None:
        raise ItemError(f"{rec['asset_id']}: not in the catalog's generated.json")
    return CatalogAsset(asset_id=rec["asset_id"], category=rec["category"], usd=Path(rec["usd"]).resolve(),
                        info=gen)


@dataclass(frozen=True, eq=False)
class RoomScene:
    """One room's records of a populated scene: house: ``scene.usda``; room: its id; recs: every
    instance record by name; mine: the room's; info: the catalog's generated records by asset id."""

    scene_dir: Path
    house: Path
    room: str
    recs: dict[str, dict]
    mine: dict[str, dict]
    info: dict[str, dict]

    def one(self, category: str, ok=lambda r: True) -> dict | None:
        """The room's first instance of ``category`` that passes ``ok`` (None if none)."""
        c = [r for r in self.mine.values() if r["category"] == category and ok(r)]
        return c[0] if c else None

    def asset(self, rec: dict) -> CatalogAsset:
        return asset_of(rec, self.info)

    def other_rooms_objects(self) -> list[str]:
        """The instances standing on something in the other rooms (the task scene cuts them away)."""
        return [n for n, r in self.recs.items() if r["room"] != self.room and r["support"] is not None]


def read_room(scene_dir: Path, generated_json: Path, room_type: str, room: str | None = None) -> RoomScene:
    """The records of the ``room_type`` room ``room`` (default: the house's first populated one) of
    the scene in ``scene_dir`` (``scene.usda`` + ``scene.json``). ItemError when there is none."""
    from stages.demos.parts import load_generated_info

    scene_dir = Path(scene_dir)
    try:
        summary = json.loads((scene_dir / "scene.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise ItemError(f"{scene_dir}: cannot read scene.json ({e})") from None
    rooms = [r for r, t in summary["rooms"].items() if t == room_type]
    room = room or (rooms[0] if rooms else None)
    if room not in rooms:
        raise ItemError(f"{scene_dir}: no populated {room_type} {room or ''} (rooms: {summary['rooms']})")
    recs = {r["name"]: r for r in summary["instances"]}
    return RoomScene(scene_dir=scene_dir, house=scene_dir / "scene.usda", room=room, recs=recs,
                     mine={n: r for n, r in recs.items() if r["room"] == room},
                     info=load_generated_info(generated_json))


@dataclass(frozen=True, eq=False)
class RoomFrame:
    """The house moved by ``theta`` (a multiple of 90 deg, rounded to one) about +Z and shifted so
    that the room's floor polygon starts at the origin. frame: (tx, ty, theta); size: the room's
    (x, y) extent [m]; walls: the room's floor's wall footprints in the task frame [m]."""

    frame: tuple[float, float, float]
    size: tuple[float, float]
    walls: tuple[tuple[float, float, float, float], ...]

    @property
    def R(self) -> np.ndarray:
        return rot2(self.frame[2])

    @property
    def t(self) -> np.ndarray:
        return np.asarray(self.frame[:2], float)

    @property
    def area(self) -> tuple[float, float, float, float]:
        return (0.0, 0.0, *self.size)

    def placed(self, rec: dict, asset: CatalogAsset) -> Placed:
        """A scene instance record in the task frame."""
        xy = self.R @ np.asarray(rec["position"][:2]) + self.t
        return Placed(f"Objects/{rec['name']}", asset, (float(xy[0]), float(xy[1]), float(rec["position"][2])),
                      wrap(rec["yaw"] + self.frame[2]))

    def to_house(self, xy) -> np.ndarray:
        """A task-frame point (2,) [m] in the house frame."""
        return rot2(-self.frame[2]) @ (np.asarray(xy, float) - self.t)

    def box(self, b) -> tuple[float, float, float, float]:
        pts = np.array([[b[0], b[1]], [b[2], b[3]]]) @ self.R.T + self.t
        return (*pts.min(axis=0), *pts.max(axis=0))


def room_frame(house: Path, room: str, theta: float) -> RoomFrame:
    """The task frame that turns the house by ``theta`` (rounded to a multiple of 90 deg: the walls
    stay axis-aligned) with room ``room``'s corner at the origin."""
    from stages.layout.floorplan import load_floor_plan

    theta = round(wrap(theta) / (math.pi / 2)) * (math.pi / 2)
    R = rot2(theta)
    plan = load_floor_plan(floor_plan_of(house))
    rm = next(r for f in plan.floors for r in f.rooms if r.id == room)
    poly = np.asarray(rm.polygon) @ R.T
    t = -poly.min(axis=0)
    size = tuple(float(v) for v in poly.max(axis=0) - poly.min(axis=0))
    f = RoomFrame((float(t[0]), float(t[1]), float(theta)), size, ())
    walls = tuple(f.box(w.box) for w in plan.floors[rm.floor].walls)
    return RoomFrame(f.frame, size, walls)


def write_task_scene(path: Path, house: Path, frame: tuple[float, float, float], cut: list[str],
                     moved: tuple[str, tuple] | None, layers: list[Path] = ()) -> None:
    """The task scene layer: the house's scene as a sublayer, ``/World`` moved by ``frame`` (translate
    (tx, ty, 0), then rotate theta about +Z), the ``cut`` instances (``/World/Objects/<name>``) inactive;
    ``moved``: (instance, new position in the house frame [m]) or None; ``layers``: more sublayers
    (stronger than the house's) whose prims under ``/World`` the same motion moves (the drink)."""
    from pxr import Gf, Sdf

    layer = Sdf.Layer.CreateAnonymous(".usda")
    root = layer.pseudoRoot
    root.SetInfo("upAxis", "Z")
    root.SetInfo("metersPerUnit", 1.0)
    root.SetInfo("kilogramsPerUnit", 1.0)
    layer.defaultPrim = "World"
    for extra in layers:
        layer.subLayerPaths.append(_rel(extra, path.parent))
    layer.subLayerPaths.append(_rel(house, path.parent))
    world = Sdf.PrimSpec(root, "World", Sdf.SpecifierOver)
    tx, ty, th = frame
    t = Sdf.AttributeSpec(world, "xformOp:translate", Sdf.ValueTypeNames.Double3)
    t.default = Gf.Vec3d(tx, ty, 0.0)
    r = Sdf.AttributeSpec(world, "xformOp:rotateZ", Sdf.ValueTypeNames.Double)
    r.default = math.degrees(th)
    o = Sdf.AttributeSpec(world, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          variability=Sdf.VariabilityUniform)
    o.default = ["xformOp:translate", "xformOp:rotateZ"]
    objs = Sdf.PrimSpec(world, "Objects", Sdf.SpecifierOver)
    for name in sorted(cut):
        Sdf.PrimSpec(objs, name, Sdf.SpecifierOver).active = False
    if moved:
        m = Sdf.AttributeSpec(Sdf.PrimSpec(objs, moved[0], Sdf.SpecifierOver), "xformOp:translate",
                              Sdf.ValueTypeNames.Double3)
        m.default = Gf.Vec3d(*moved[1])
    path.parent.mkdir(parents=True, exist_ok=True)
    layer.Export(str(path))


def spawn_in(world: HouseRoom) -> HouseRoom:
    """``world`` with its build spawn set to a free start pose inside its room (seed 0)."""
    from stages.demos.sampling import free_start

    object.__setattr__(world, "spawn", free_start(world, np.random.default_rng(0)))
    return world
