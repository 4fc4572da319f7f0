"""The task world: a kitchen furnished from the ingested default catalog.

:func:`write_kitchen` authors one scene USD (``scene.usda``) in a folder: a rectangular room (floor,
four walls, the south wall with a catalog room door standing in an opening, lights) and catalog
packages REFERENCED from the ingest step's output (never copied): along the north wall a fridge, a
kitchen counter (drawers, doors) and an oven, a microwave on the counter, a table (dining or coffee
table) in the room with a mug, a bowl and an object to push (a can; a sponge if the catalog has no
can) on it. Asset
variants and positions are drawn from the world's ``rng``, then its look (``stages.demos.looks``:
colours of floor and walls and of the packages' materials, the lights) from a child generator.

Frame: world, Z up, metres, radians; the room spans ``[0, size[0]] x [0, size[1]]``. Appliances
face south (asset +X -> world -Y, yaw -90 deg); the robot works on the counter and the table from
their south side, facing +Y. Every package's facts come from its ``generated.json`` record
(surfaces, handles, joint roles, parameters) and its USD bounds; a placed package is a
:class:`~stages.demos.packages.Placed` (the articulated tasks build their parts from it).

::

    lib = AssetLibrary.from_folder(Path("out/main/assets"), Path("out/main/catalog/default/generated.json"))
    world = write_kitchen(out_dir, lib, scene_id="kitchen_000", rng=np.random.default_rng(0))
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.demos.looks import KitchenLook, sample_look
from stages.demos.packages import CatalogAsset, Placed, link_bounds

log = logging.getLogger(__name__)

#: categories the kitchen is furnished from
KITCHEN_CATEGORIES = ("kitchen_counter", "microwave", "fridge", "oven", "door", "dining_table",
                      "coffee_table", "mug", "bowl", "can", "sponge", "plate", "crumpled_paper", "trash_can",
                      "alarm_clock", "pitcher", "cup", "dish_rack")
#: the placed roles that are free bodies (the tasks set their poses per episode)
FREE_ROLES = ("mug", "bowl", "pusher", "plate", "sponge", "paper", "trash_can", "pitcher", "cup", "clock",
              "cushion", "book_1", "book_2", "hanger", "dish_rack")
CLOCK_END_GAP = 0.35    # a parked clock stands this far [m] from the counter top's ends (the base's room)
CLOCK_BUSY_GAP = 0.30   # ... and from the microwave and the mug's counter spot [m]
CLOCK_FRONT = 0.075     # its centre this far [m] behind the counter's front edge
GRASP_MAX_DIAMETER = 0.076  # [m] widest mug body the Franka hand (80 mm stroke) grasps across
WALL_T, WALL_H = 0.10, 2.5  # wall thickness and height [m]
SOUTH = -math.pi / 2        # yaw of an asset whose front (+X) faces world -Y
ROW_GAP = 0.35              # between the fridge, the counter and the oven [m]
END_GAP = 1.0               # from the row's ends to the side walls [m]
ROOM_DEPTH = 5.4            # [m] (y): >= 2 m free between the table and the counter's front


@dataclass(frozen=True, eq=False)
class AssetLibrary:
    """Ingested default-catalog packages by id."""

    assets: dict[str, CatalogAsset]

    def of(self, category: str) -> list[CatalogAsset]:
        """The packages of ``category``, sorted by id."""
        return sorted((a for a in self.assets.values() if a.category == category), key=lambda a: a.asset_id)

    @staticmethod
    def from_packages(usd_by_id: dict[str, Path], generated_json: Path,
                      categories: tuple[str, ...] = KITCHEN_CATEGORIES) -> AssetLibrary:
        """From package root layers by asset id and the catalog's ``generated.json``; only ``categories``."""
        from stages.demos.parts import load_generated_info

        info = load_generated_info(generated_json)
        out = {}
        for aid, usd in sorted(usd_by_id.items()):
            rec = info.get(aid)
            if rec is None or rec.get("category") not in categories:
                continue
            if not Path(usd).is_file():
                raise ItemError(f"{usd}: asset package of {aid} not found")
            out[aid] = CatalogAsset(asset_id=aid, category=rec["category"], usd=Path(usd).resolve(), info=rec)
        return AssetLibrary(out)

    @staticmethod
    def from_folder(assets_dir: Path, generated_json: Path,
                    categories: tuple[str, ...] = KITCHEN_CATEGORIES) -> AssetLibrary:
        """From an ingest output folder (``<assets_dir>/<id>/<id>.usda``) and ``generated.json``."""
        assets_dir = Path(assets_dir)
        usd = {p.parent.name: p for p in assets_dir.glob("*/*.usda") if p.stem == p.parent.name}
        if not usd:
            raise ItemError(f"{assets_dir}: no asset packages (<id>/<id>.usda)")
        return AssetLibrary.from_packages(usd, generated_json, categories)


@dataclass(frozen=True, kw_only=True, eq=False)
class KitchenWorld:
    """One task world. usd: scene file; scene_id; size (x, y) [m]; placed: packages by role
    ("counter", "microwave", "fridge", "oven", "door", "table", "mug", "bowl", "pusher", and where the
    catalog has them "plate" and "sponge"); spawn:
    robot root (x, y, yaw) for the build; counter_z / table_z: support heights [m]; table_rect /
    counter_rect: (xmin, ymin, xmax, ymax) of the support surfaces [m]; counter_spot: (x, y) on the
    counter beside the microwave; cavity: microwave cavity floor (xmin, ymin, xmax, ymax) [m] at
    cavity_z with cavity_height of clearance; button: centre of the button face at rest (3,) [m],
    button_travel [m], button_push (3,) unit push direction; mug_radius, mug_height [m];
    materials: floor and wall colours (name -> linear rgb); look: the packages' material
    overrides and the lights (:class:`~stages.demos.looks.KitchenLook`)."""

    usd: Path
    scene_id: str
    size: tuple[float, float]
    wall_thickness: float
    placed: dict[str, Placed]
    spawn: tuple[float, float, float]
    counter_z: float
    counter_rect: tuple[float, float, float, float]
    counter_spot: tuple[float, float]
    table_z: float
    table_rect: tuple[float, float, float, float]
    cavity: tuple[float, float, float, float]
    cavity_z: float
    cavity_height: float
    button: tuple[float, float, float]
    button_travel: float
    button_push: tuple[float, float, float]
    mug_radius: float
    mug_height: float
    bowl_radius: float
    materials: dict
    look: KitchenLook
    drink: tuple[str, ...] = ()

    def drink_parked(self) -> dict:
        """The drink's spheres where the kitchen parks them (body -> (x, y, z, yaw)): in the parked
        pitcher (:func:`stages.demos.drink.drink_world`); empty without a drink."""
        if not self.drink:
            return {}
        from stages.demos.drink import drink_world

        p = self.placed["pitcher"]
        pts = drink_world((*p.position, p.yaw), p.asset.params, len(self.drink))
        return {b: (*(float(v) for v in c), 0.0) for b, c in zip(self.drink, pts, strict=True)}

    def nav_boxes(self) -> np.ndarray:
        """Obstacle footprints (K, 4) [xmin, ymin, xmax, ymax] for base planning: walls, the floor
        furniture (fridge, counter, oven, table, door frame)."""
        sx, sy = self.size
        t = self.wall_thickness
        boxes = [(-t, -t, sx + t, 0.0), (-t, sy, sx + t, sy + t), (-t, -t, 0.0, sy + t),
                 (sx, -t, sx + t, sy + t)]
        boxes += [self.placed[k].footprint() for k in ("fridge", "counter", "oven", "table", "door", "trash_can")
                  if k in self.placed]
        return np.asarray(boxes, float)

    def nav_bounds(self) -> tuple[float, float, float, float]:
        """The planning grid's extent (xmin, ymin, xmax, ymax) [m]: the room and 0.2 m around it."""
        return (-0.2, -0.2, self.size[0] + 0.2, self.size[1] + 0.2)

    def grid(self):
        from stages.demos.planner import NavGrid

        return NavGrid.from_boxes(self.nav_bounds(), self.nav_boxes())

    def start_area(self) -> tuple[float, float, float, float]:
        """Where a robot start pose is drawn (xmin, ymin, xmax, ymax) [m]: 0.6 m from the walls, up to
        1.3 m before the counter's front (an open fridge door reaches ~0.8 m out)."""
        return (0.6, 0.6, self.size[0] - 0.6, self.counter_rect[1] - 1.3)

    def start_boxes(self) -> np.ndarray:
        """Footprints (K, 4) [m] a start pose keeps 0.5 m from: :meth:`nav_boxes` and the room
        door's swing (1.1 m around the opening: the leaf may stand open, close_door)."""
        dx, dy = self.placed["door"].position[:2]
        return np.vstack([self.nav_boxes(), [(dx - 1.1, dy, dx + 1.1, dy + 1.1)]])

    def asset_ids(self) -> dict[str, str]:
        return {k: p.asset.asset_id for k, p in self.placed.items()}


# --------------------------------------------------------------------------------------------
# choosing the assets
# --------------------------------------------------------------------------------------------


def _pick(lib: AssetLibrary, rng: np.random.Generator, categories: tuple[str, ...], ok=lambda a: True,
          what: str = "") -> CatalogAsset:
    cands = [a for c in categories for a in lib.of(c) if ok(a)]
    if not cands:
        raise ItemError(f"default catalog: no usable {what or '/'.join(categories)} among the ingested "
                        f"packages "
                        f"({', '.join(categories)}: {sum(len(lib.of(c)) for c in categories)} packages)")
    return cands[int(rng.integers(len(cands)))]


def _mug_ok(a: CatalogAsset) -> bool:
    return 2.0 * float(a.params.get("radius", 1.0)) <= GRASP_MAX_DIAMETER


def _bowl_fits(bowl: CatalogAsset, mug: CatalogAsset, margin: float = 0.002) -> bool:
    """Whether ``mug`` stands flat on ``bowl``'s floor (radius: foot radius less the wall, as the
    catalog's bowl generator lathes it) with ``margin`` [m] to spare; on a smaller floor it rests
    on the curved wall and tips."""
    p = bowl.params
    floor = float(p.get("rim_radius", 0.0)) * float(p.get("foot_ratio", 0.0)) - float(p.get("wall", 0.0))
    return float(mug.params.get("radius", 1.0)) + margin <= floor


def _counter_segment(a: CatalogAsset, need: float) -> dict | None:
    """The counter's widest top surface segment (asset frame) if it is at least ``need`` [m] long."""
    tops = [s for s in a.info.get("surfaces", []) if not s["inside"] and s["link"] == "base"]
    if not tops:
        return None
    best = max(tops, key=lambda s: s["hi"][1] - s["lo"][1])
    return best if best["hi"][1] - best["lo"][1] >= need else None


def _top(a: CatalogAsset) -> dict:
    tops = [s for s in a.info.get("surfaces", []) if not s["inside"]]
    if not tops:
        raise ItemError(f"{a.usd}: no top surface in its generated.json record")
    return max(tops, key=lambda s: s["z"])


def _dishes(lib: AssetLibrary, rng: np.random.Generator, table_rect, table_z: float) -> dict[str, Placed]:
    """The household skills' objects where the catalog has them and the table is at least 0.7 m deep
    (else none): a plate and a sponge narrow enough to grasp across (stages.demos.skill_wipe) and a
    piece of crumpled paper (stages.demos.skill_trash) on the table's far band; a trash can on the
    floor off the table's west end; a dish rack (stages.demos.skill_rack) on the floor under the
    table (clean dishes' wipe sets it on the table)."""
    out: dict[str, Placed] = {}
    if table_rect[3] - table_rect[1] < 0.7:
        return out
    from stages.demos.skill_trash import BIN_GAP, MAX_PAPER_RADIUS

    tx, far = 0.5 * (table_rect[0] + table_rect[2]), table_rect[3]
    sponges = [a for a in lib.of("sponge") if float(a.params.get("width", 1.0)) <= 0.072]
    if lib.of("plate") and sponges:
        plate, sponge = _pick(lib, rng, ("plate",)), sponges[int(rng.integers(len(sponges)))]
        out["plate"] = Placed("Plate", plate, (tx - 0.18, far - 0.17, table_z + 0.002), 0.0)
        out["sponge"] = Placed("Sponge", sponge, (tx + 0.22, far - 0.10, table_z + 0.002), 0.0)
    papers = [a for a in lib.of("crumpled_paper") if float(a.params.get("radius", 1.0)) <= MAX_PAPER_RADIUS]
    if papers and lib.of("trash_can"):
        paper, can = papers[int(rng.integers(len(papers)))], _pick(lib, rng, ("trash_can",))
        out["paper"] = Placed("Paper", paper, (tx + 0.02, far - 0.08, table_z + 0.002), 0.0)
        x = table_rect[0] - BIN_GAP - can.hi[0]  # its east side BIN_GAP off the table's west end
        out["trash_can"] = Placed("TrashCan", can, (x, table_rect[1] + 0.15, 0.0), 0.0)
    if "plate" in out and lib.of("dish_rack"):  # clean dishes' rack: parked on the floor under the table
        rack = _pick(lib, rng, ("dish_rack",))  # (the last draw: the objects above stay what they were)
        out["dish_rack"] = Placed("DishRack", rack, (tx, 0.5 * (table_rect[1] + far), 0.0), 0.0)
    return out


def _clock(lib: AssetLibrary, rng: np.random.Generator, counter_rect, counter_z: float,
           busy: tuple[float, float]) -> dict[str, Placed]:
    """An alarm clock parked on the counter top (when the catalog has one and the counter has room):
    on the longer free stretch of the counter beside the microwave and the mug's spot (``busy``:
    their x extent [m]), CLOCK_END_GAP from the counter's ends and CLOCK_BUSY_GAP from ``busy``,
    CLOCK_FRONT behind the front edge, facing the wall (its back, with the switch, to the room)."""
    if not lib.of("alarm_clock"):
        return {}
    x0, y0, x1, _ = counter_rect
    spans = [(x0 + CLOCK_END_GAP, busy[0] - CLOCK_BUSY_GAP), (busy[1] + CLOCK_BUSY_GAP, x1 - CLOCK_END_GAP)]
    lo, hi = max(spans, key=lambda s: s[1] - s[0])
    if hi < lo:
        log.warning("kitchen: no room for the alarm clock on the counter (%s)", counter_rect)
        return {}
    clock = _pick(lib, rng, ("alarm_clock",))
    x = float(rng.uniform(lo, hi))
    return {"clock": Placed("Clock", clock, (x, y0 + CLOCK_FRONT, counter_z + 0.002), math.pi / 2)}


def watched_joints(world: KitchenWorld) -> list[str]:
    """The momentary scene joints whose peaks the engines track: the microwave's button and a
    parked clock's button (a world without a microwave, a house's, watches no microwave button)."""
    out = [world.placed["microwave"].joint("button_joint")] if "microwave" in world.placed else []
    if "clock" in world.placed:
        joints = world.placed["clock"].info.get("joints", {})
        out += [world.placed["clock"].joint(n) for n, role in joints.items() if role == "button"]
    return out


def _cavity(a: CatalogAsset) -> dict:
    cav = [s for s in a.info.get("surfaces", []) if s["inside"]]
    if not cav:
        raise ItemError(f"{a.usd}: microwave without a cavity surface (inside=true)")
    return cav[0]


# --------------------------------------------------------------------------------------------
# writing the scene
# --------------------------------------------------------------------------------------------


def _rel(target: Path, layer_dir: Path) -> str:
    r = os.path.relpath(Path(target).resolve(), Path(layer_dir).resolve()).replace(os.sep, "/")
    return r if r.startswith(".") else f"./{r}"


def _write_scene(path: Path, size, placed: list[Placed], colors: dict, door_gap: tuple[float, float],
                 look: KitchenLook, drink: dict | None = None) -> None:
    """Author the scene layer: physics scene, floor, walls (the south one split around the door
    opening ``door_gap`` (x0, x1)), one referencing Xform per placed package, and the look (material
    overrides of the packages, lights)."""
    from pxr import Gf, Sdf

    from stages.demos.looks import add_look
    from stages.simulate.demo_scene import _box, _labels, _Writer, _xform_attrs

    sx, sy = size
    t, h = WALL_T, WALL_H
    w = _Writer()
    w.prim("/World", "Xform", meta={"kind": "assembly"})
    w.prim("/World/PhysicsScene", "PhysicsScene", attrs={
        "physics:gravityDirection": (Sdf.ValueTypeNames.Vector3f, Gf.Vec3f(0, 0, -1)),
        "physics:gravityMagnitude": (Sdf.ValueTypeNames.Float, 9.81)})
    _box(w, "/World/Floor", (sx / 2, sy / 2, -0.05), (sx + 2 * t, sy + 2 * t, 0.1), colors["floor"],
         label="floor")
    x0, x1 = door_gap
    walls = {"WallNorth": ((sx / 2, sy + t / 2, h / 2), (sx + 2 * t, t, h)),
             "WallWest": ((-t / 2, sy / 2, h / 2), (t, sy, h)),
             "WallEast": ((sx + t / 2, sy / 2, h / 2), (t, sy, h)),
             "WallSouthW": (((x0 - t) / 2, -t / 2, h / 2), (x0 + t, t, h)),
             "WallSouthE": (((x1 + sx + t) / 2, -t / 2, h / 2), (sx + t - x1, t, h)),
             "WallSouthTop": (((x0 + x1) / 2, -t / 2, (h + 2.2) / 2), (x1 - x0, t, h - 2.2))}
    for name, (c, s) in walls.items():
        _box(w, f"/World/{name}", c, s, colors["wall"], label="wall")
    for p in placed:
        la, lv = _labels(p.asset.category)
        ref = Sdf.Reference(_rel(p.asset.usd, path.parent))
        w.prim(p.prim, "Xform", apis=la, attrs={**_xform_attrs(p.position, p.yaw), **lv},
               meta={"references": Sdf.ReferenceListOp.Create(prependedItems=[ref])})
    if drink:
        from stages.demos.drink import write_drink

        write_drink(w, drink)
    add_look(w, look, size)
    w.write(Path(path), "World")


def write_kitchen(out_dir: Path, lib: AssetLibrary, *, scene_id: str,
                  rng: np.random.Generator, household: bool = False, drink: bool = False,
                  clock: bool = False) -> KitchenWorld:
    """Author one kitchen world in ``out_dir`` (``scene.usda``) from ``lib`` and ``rng`` (see module doc).
    ``household``: also park the household skills' objects (plate, sponge, paper, trash can: only the
    tasks that use them ask, :func:`stages.demos.multistage.needs_household`; the others' worlds stay
    as they were); ``drink``: also park a pitcher holding the drink's spheres and a cup
    (stages.demos.drink; :func:`stages.demos.multistage.needs_drink`); ``clock``: also park an
    alarm clock on the counter (the press and slide skills, :func:`stages.demos.multistage.needs_clock`)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    micro = _pick(lib, rng, ("microwave",))
    mw_w = micro.hi[1] - micro.lo[1]
    counter = _pick(lib, rng, ("kitchen_counter",), lambda a: _counter_segment(a, mw_w + 0.33) is not None,
                    "kitchen counter with a top segment for a microwave and a mug")
    fridge, oven = _pick(lib, rng, ("fridge",)), _pick(lib, rng, ("oven",))
    door = _pick(lib, rng, ("door",))
    tables = ("dining_table",) if lib.of("dining_table") else ("coffee_table",)
    table = _pick(lib, rng, tables)
    mug = _pick(lib, rng, ("mug",), lambda a: _mug_ok(a) and any(_bowl_fits(b, a) for b in lib.of("bowl")),
                f"mug narrower than {GRASP_MAX_DIAMETER * 1000:.0f} mm that stands flat in a bowl")
    bowl = _pick(lib, rng, ("bowl",), lambda b: _bowl_fits(b, mug), f"bowl whose floor holds {mug.asset_id}")
    # the object to push: a can (a 10-25 g sponge was not pushed in a measured world); else a sponge
    pusher = _pick(lib, rng, ("can",) if lib.of("can") else ("sponge",))

    # along the north wall, west to east: fridge, counter, oven (or oven first), ROW_GAP apart, at
    # least END_GAP from the side walls (room for the base beside a door swinging open)
    row = [fridge, counter, oven] if rng.random() < 0.5 else [oven, counter, fridge]
    widths = [a.hi[1] - a.lo[1] for a in row]
    length = sum(widths) + 2 * ROW_GAP
    sx = max(5.0, length + 2 * END_GAP + 0.2)
    sy = ROOM_DEPTH
    x = END_GAP + float(rng.uniform(0.0, sx - 2 * END_GAP - length))
    placed: dict[str, Placed] = {}
    roles = {id(fridge): "fridge", id(counter): "counter", id(oven): "oven"}
    for a, wdt in zip(row, widths, strict=True):
        role = roles[id(a)]
        # yaw -90 deg: asset +Y -> world +X, asset +X -> world -Y; the back (asset lo x) 1 cm off the wall
        cx = x - a.lo[1]
        cy = sy - 0.01 + a.lo[0]
        placed[role] = Placed(role.capitalize(), a, (cx, cy, 0.0), SOUTH)
        x += wdt + ROW_GAP
    cnt = placed["counter"]
    seg = _counter_segment(counter, mw_w + 0.33)
    top_z = float(seg["z"])
    # microwave on the segment, along it with room for the mug spot on one side
    # the mug's spot is on the side of the door's free edge (the handle): the open door swings
    # out on the hinge side and would stand between the spot and the cavity
    door_handle = [h for h in micro.info.get("handles", []) if h["link"] == "door"]
    mug_side = 1.0 if not door_handle or door_handle[0]["center"][1] >= 0 else -1.0
    y_lo, y_hi = seg["lo"][1] + 0.03, seg["hi"][1] - 0.03
    # the hand (0.2 m wide across its fingers) grasps the mug from the front: the spot is 0.17 m
    # beside the microwave
    span = (y_lo - micro.lo[1] + (0.27 if mug_side < 0 else 0.0),
            y_hi - micro.hi[1] - (0.27 if mug_side > 0 else 0.0))
    my = float(rng.uniform(*span)) if span[1] > span[0] else 0.5 * (span[0] + span[1])
    # near the counter's front edge: the hand reaches the mug with its wrist in front of the edge
    mx = seg["hi"][0] - 0.01 - micro.hi[0]
    mw_pos = cnt.to_world((mx, my, top_z + 0.001))
    placed["microwave"] = Placed("Microwave", micro, tuple(mw_pos), SOUTH)
    spot_local = (seg["hi"][0] - 0.07, my + (micro.hi[1] + 0.17 if mug_side > 0 else micro.lo[1] - 0.17))
    counter_spot = tuple(float(v) for v in cnt.to_world((*spot_local, 0.0))[:2])
    counter_rect = cnt.rect(seg["lo"], seg["hi"])

    # the room door in the south wall, opening into the room (asset +X -> world +Y)
    dw = door.hi[1] - door.lo[1]
    # >= 1.1 m from the west wall: the leaf opened against that side leaves room for the base
    # between it and the wall (a robot closing the door pushes the leaf's room-side face from there)
    door_x = float(rng.uniform(1.1 + dw / 2, 1.5 + dw / 2))
    placed["door"] = Placed("Door", door, (door_x, -WALL_T / 2, 0.0), math.pi / 2)
    door_gap = (door_x - dw / 2 + 0.002, door_x + dw / 2 - 0.002)

    # the table: long side along x, in the eastern part of the room, clear of the door swing
    ttop = _top(table)
    t_len, t_wid = table.hi[0] - table.lo[0], table.hi[1] - table.lo[1]
    tx_lo, tx_hi = max(door_x + dw / 2 + 0.9 + t_len / 2, 1.0 + t_len / 2), sx - 0.9 - t_len / 2
    tx = float(rng.uniform(tx_lo, tx_hi)) if tx_hi > tx_lo else 0.5 * (tx_lo + tx_hi)
    ty = 1.45 + t_wid / 2 + float(rng.uniform(0.0, 0.15))
    placed["table"] = Placed("Table", table, (tx, ty, 0.0), 0.0)
    table_rect = placed["table"].rect(ttop["lo"], ttop["hi"])
    table_z = float(ttop["z"])
    south = table_rect[1]
    # objects along the table's south edge (poses are re-sampled per episode)
    placed["mug"] = Placed("Mug", mug, (tx - 0.18, south + 0.22, table_z + 0.002), 0.0)
    placed["bowl"] = Placed("Bowl", bowl, (tx + 0.10, south + 0.22, table_z + 0.002), 0.0)
    placed["pusher"] = Placed("Pusher", pusher, (tx + 0.40, south + 0.14, table_z + 0.002), 0.0)

    cav = _cavity(micro)
    mwp = placed["microwave"]
    cavity = mwp.rect(cav["lo"], cav["hi"])
    cavity_z = float(mwp.position[2] + cav["z"])
    blo, bhi = link_bounds(micro.usd, "button")
    bface = np.array([bhi[0], (blo[1] + bhi[1]) / 2, (blo[2] + bhi[2]) / 2])
    button = mwp.to_world(bface)
    push = mwp.dir_to_world((-1.0, 0.0, 0.0))

    # the look (floor, walls, materials, lights) from a child generator spawned after every other
    # draw: the picks and poses above stay what they were for a seed, whatever the look draws
    look = sample_look(placed, rng.spawn(1)[0])
    colors = {"floor": look.floor, "wall": look.wall}
    # the wipe task's plate and sponge, parked on the table's far band (when the catalog has them and
    # the table is deep enough), from a second child generator: nothing above changes with them
    if household:
        placed.update(_dishes(lib, rng.spawn(1)[0], table_rect, table_z))
    if clock:  # from the third child generator, whether or not the dishes drew the second
        spare = rng.spawn(2)[1] if not household else rng.spawn(1)[0]
        mw_fp = placed["microwave"].footprint()
        busy = (min(mw_fp[0], counter_spot[0]), max(mw_fp[2], counter_spot[0]))
        placed.update(_clock(lib, spare, counter_rect, top_z, busy))
    drink_bodies: tuple[str, ...] = ()
    if drink:
        from stages.demos.drink import park_drink

        more, drink_bodies = park_drink(lib, rng.spawn(1)[0], table_rect, table_z)
        placed.update(more)
    usd = out_dir / "scene.usda"
    parked = None
    if drink_bodies:
        from stages.demos.drink import drink_world

        p = placed["pitcher"]
        parked = dict(zip(drink_bodies, drink_world((*p.position, p.yaw), p.asset.params, len(drink_bodies)),
                          strict=True))
    _write_scene(usd, (sx, sy), list(placed.values()), colors, door_gap, look, parked)
    spawn = (float(tx), float(south - 0.9), math.pi / 2)
    world = KitchenWorld(
        usd=usd, scene_id=scene_id, size=(sx, sy), wall_thickness=WALL_T, placed=placed, spawn=spawn,
        counter_z=float(top_z), counter_rect=counter_rect, counter_spot=counter_spot, table_z=table_z,
        table_rect=table_rect, cavity=cavity, cavity_z=cavity_z, cavity_height=float(cav["clear_height"]),
        button=tuple(float(v) for v in button), button_travel=float(micro.params.get("button_travel", 0.005)),
        button_push=tuple(float(v) for v in push), mug_radius=float(mug.params["radius"]),
        mug_height=float(mug.params["height"]), bowl_radius=float(bowl.params.get("rim_radius", 0.07)),
        materials=colors, look=look, drink=drink_bodies)
    log.info("kitchen %s: %s", scene_id, world.asset_ids())
    return world
