"""Task worlds and task instances, sampled from a seed.

A *world* (:func:`write_task_room`) is one scene USD: the simulate stage's furnished demo room
(floor, walls, table, mug, cabinet with a drawer and a hinged door; ``write_demo_room``) with the
table moved, plus an overlay layer that sublayers it and adds a bowl (a static ring of boxes on
the table), a block to push (rigid, 5 cm) and randomized materials (``over`` specs of the display
colours of floor, walls, table, cabinet fronts, bowl, block). An *instance* (:func:`sample_instance`)
is one episode in a world: the robot's start pose, the objects' poses on the table, the initial
joint positions of the cabinet (open for the close tasks) and the instruction text.

Frame: world, Z up, metres, radians. The table is approached from its -Y side.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.demos.tasks import BUTTON_JOINT, DOOR_JOINT, DRAWER_JOINT, task

log = logging.getLogger(__name__)

TABLE_SIZE = (0.6, 0.9)
TABLE_HEIGHT = 0.55
BOWL_OFFSET = (0.07, -0.22)   # bowl centre from the table centre [m]
MUG_OFFSET = (-0.15, -0.25)
BLOCK_OFFSET = (0.24, -0.34)
BLOCK_SIZE = 0.05
BOWL_INNER = 0.085
BUTTON_TRAVEL = 0.010   # [m] from the rest position to the panel face
BUTTON_SIZE = (0.012, 0.04, 0.04)


@dataclass(frozen=True, kw_only=True)
class TaskRoom:
    """One world. usd: the scene file (overlay); scene_id; table_xy: table centre [m];
    table_height [m]; bowl_xy, bowl_inner_radius [m]; drawer_handle / door_handle / door_hinge
    (3,) at the closed configuration [m]; drawer_travel [m]; door_range [rad]; size: room (x, y)
    [m]; wall_thickness [m]; cabinet_box: (xmin, ymin, xmax, ymax) footprint incl. handles [m];
    materials: name -> rgb used."""

    usd: Path
    scene_id: str
    size: tuple[float, float]
    wall_thickness: float
    table_xy: tuple[float, float]
    table_height: float
    bowl_xy: tuple[float, float]
    bowl_inner_radius: float
    drawer_handle: tuple[float, float, float]
    door_handle: tuple[float, float, float]
    door_hinge: tuple[float, float, float]
    drawer_travel: float
    door_range: float
    button: tuple[float, float, float]
    button_travel: float
    cabinet_box: tuple[float, float, float, float]
    materials: dict

    def nav_boxes(self, door_open: bool = False) -> np.ndarray:
        """Obstacle footprints (K, 4) [xmin, ymin, xmax, ymax] for base planning: walls, table,
        cabinet (and the swept area of its door when it may stand open)."""
        sx, sy = self.size
        t = self.wall_thickness
        tx, ty = self.table_xy
        hx, hy = TABLE_SIZE[0] / 2, TABLE_SIZE[1] / 2
        boxes = [(-t, -t, sx + t, 0.0), (-t, sy, sx + t, sy + t), (-t, -t, 0.0, sy + t),
                 (sx, -t, sx + t, sy + t),
                 (tx - hx, ty - hy, tx + hx, ty + hy), self.cabinet_box]
        if door_open:
            hxg, hyg = self.door_hinge[:2]
            boxes.append((hxg - 0.45, hyg - 0.45, hxg, hyg + 0.05))
        return np.asarray(boxes, float)


@dataclass(frozen=True, kw_only=True)
class TaskInstance:
    """One episode. task: task name; seed; room; instruction; names: words of the instruction;
    start_base (x, y, yaw) [m, rad]; mug_xy / block_xy: object positions on the table [m];
    push_direction (2,) unit; joints: initial scene joint positions by prim path [m or rad];
    asset_ids: ids of the assets involved."""

    task: str
    seed: int
    room: TaskRoom
    instruction: str
    names: dict
    start_base: tuple[float, float, float]
    mug_xy: tuple[float, float]
    block_xy: tuple[float, float]
    push_direction: tuple[float, float]
    joints: dict
    asset_ids: tuple[str, ...]


def _rgb(rng, lo=0.15, hi=0.9) -> tuple[float, float, float]:
    return tuple(float(v) for v in rng.uniform(lo, hi, 3))


def _button_parts(front_x: float, y: float, top_z: float) -> tuple[tuple, tuple, tuple]:
    """The control panel on the cabinet top (static box: centre, size) and its push button
    (box centre at rest); the panel's front face is at ``front_x``, the button in front of it."""
    panel = ((front_x + 0.06, y, top_z + 0.07), (0.12, 0.22, 0.14))
    button = (front_x - BUTTON_TRAVEL - BUTTON_SIZE[0] / 2, y, top_z + 0.07)
    return panel, button, BUTTON_SIZE


def _add_button(w, front_x: float, y: float, top_z: float, colors: dict) -> None:
    """Panel + button body on a prismatic joint along +X (0 at rest .. BUTTON_TRAVEL pressed), no
    spring: a pressed button stays in."""
    from pxr import Gf, Sdf

    from stages.simulate.demo_scene import _box, _labels

    (pc, ps), bc, bs = _button_parts(front_x, y, top_z)
    la, lv = _labels("control_panel")
    w.prim("/World/ControlPanel", "Xform", apis=la, attrs=lv)
    _box(w, "/World/ControlPanel/Box", pc, ps, colors["panel"])
    la, lv = _labels("button")
    w.prim("/World/Button", "Xform", apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI", *la],
           attrs={**lv, "physics:mass": (Sdf.ValueTypeNames.Float, 0.05)})
    _box(w, "/World/Button/Cap", bc, bs, colors["button"])
    zero = Gf.Vec3f(0, 0, 0)
    w.prim("/World/ButtonJoint", "PhysicsPrismaticJoint", attrs={
        "physics:localRot0": (Sdf.ValueTypeNames.Quatf, Gf.Quatf(1, 0, 0, 0)),
        "physics:localRot1": (Sdf.ValueTypeNames.Quatf, Gf.Quatf(1, 0, 0, 0)),
        "physics:axis": (Sdf.ValueTypeNames.Token, "X"),
        "physics:lowerLimit": (Sdf.ValueTypeNames.Float, 0.0),
        "physics:upperLimit": (Sdf.ValueTypeNames.Float, BUTTON_TRAVEL),
        "physics:localPos0": (Sdf.ValueTypeNames.Point3f, zero),
        "physics:localPos1": (Sdf.ValueTypeNames.Point3f, zero),
    }, rels={"physics:body1": ["/World/Button"]})


def _overlay(path: Path, base: str, room, bowl_xy, block_xy, colors: dict, button_at: tuple) -> None:
    """Write the overlay layer: sublayer ``base``, add bowl, block, control panel with a button,
    override display colours."""
    from pxr import Gf, Sdf

    from stages.simulate.demo_scene import _box, _labels, _Writer, _xform_attrs

    w = _Writer()
    top_z = TABLE_HEIGHT
    w.prim("/World/Bowl", "Xform", apis=_labels("bowl")[0], attrs=_labels("bowl")[1])
    n, r_out, wall_h, wall_t = 10, BOWL_INNER + 0.01, 0.045, 0.012
    seg = 2 * (r_out - wall_t / 2) * np.tan(np.pi / n) + 0.004
    for k in range(n):
        a = 2 * np.pi * k / n
        c = (bowl_xy[0] + (r_out - wall_t / 2) * np.cos(a), bowl_xy[1] + (r_out - wall_t / 2) * np.sin(a),
             top_z + wall_h / 2 + 0.001)
        _box(w, f"/World/Bowl/Wall{k}", c, (wall_t, seg, wall_h), colors["bowl"], yaw=a)
    _box(w, "/World/Bowl/Bottom", (*bowl_xy, top_z + 0.0035), (2 * r_out, 2 * r_out, 0.005), colors["bowl"])
    la, lv = _labels("block")
    w.prim("/World/Block", "Xform", apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI", *la],
           attrs={**_xform_attrs((*block_xy, top_z + BLOCK_SIZE / 2 + 0.001)), **lv,
                  "physics:mass": (Sdf.ValueTypeNames.Float, 0.15)})
    _box(w, "/World/Block/Geom", (0, 0, 0), (BLOCK_SIZE,) * 3, colors["block"])
    _add_button(w, *button_at, colors)
    overs = {"/World/Floor": "floor", "/World/Table/Top": "table",
             "/World/Cabinet/Drawer/Front": "cabinet_front",
             "/World/Cabinet/Door/Panel": "cabinet_front"}
    overs.update({f"/World/{b}": "wall" for b in ("WallSouth", "WallNorth", "WallWest", "WallEast")})
    w.write(path, "World")
    # sublayer the room and override the display colours of its prims
    layer = Sdf.Layer.FindOrOpen(str(path))
    with Sdf.ChangeBlock():
        layer.subLayerPaths.append(base)
        for p, key in overs.items():
            spec = Sdf.CreatePrimInLayer(layer, p)
            spec.specifier = Sdf.SpecifierOver
            a = Sdf.AttributeSpec(spec, "primvars:displayColor", Sdf.ValueTypeNames.Color3fArray)
            a.default = [Gf.Vec3f(*colors[key])]
    layer.Save()


def write_task_room(out_dir: Path, *, shared_assets: Path, scene_id: str,
                    rng: np.random.Generator) -> TaskRoom:
    """Author one world in ``out_dir`` (``room.usda`` + overlay ``scene.usda``) from ``rng``:
    table position, bowl and block, materials. ``shared_assets``: the third-party assets folder
    (the mug mesh)."""
    from stages.simulate.demo_scene import CabinetSpec, cabinet_parts, write_demo_room

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    table_xy = (2.3 + float(rng.uniform(-0.1, 0.1)), 3.7 + float(rng.uniform(-0.05, 0.05)))
    cab = CabinetSpec()
    room = write_demo_room(out_dir / "room.usda", shared_assets=shared_assets, table_xy=table_xy,
                           mug_xy=(table_xy[0] + MUG_OFFSET[0], table_xy[1] + MUG_OFFSET[1]), cabinet=cab,
                           mug_scale=0.8)
    colors = {"floor": _rgb(rng, 0.3, 0.7), "wall": _rgb(rng, 0.6, 0.95), "table": _rgb(rng, 0.2, 0.7),
              "cabinet_front": _rgb(rng), "bowl": _rgb(rng), "block": _rgb(rng), "panel": _rgb(rng, 0.1, 0.5),
              "button": _rgb(rng, 0.5, 1.0)}
    bowl_xy = (table_xy[0] + BOWL_OFFSET[0], table_xy[1] + BOWL_OFFSET[1])
    block_xy = (table_xy[0] + BLOCK_OFFSET[0], table_xy[1] + BLOCK_OFFSET[1])
    usd = out_dir / "scene.usda"
    parts = cabinet_parts(cab)
    xmin = min(b.center[0] - b.size[0] / 2 for p in parts.values() for b in p)
    front = min(b.center[0] - b.size[0] / 2 for b in parts["drawer"] if b.name == "Front")
    button_at = (front, cab.origin[1] - cab.size[1] / 2 + 0.15 + float(rng.uniform(0.0, 0.1)), cab.size[2])
    _overlay(usd, "room.usda", room, bowl_xy, block_xy, colors, button_at)
    _, bc, bs = _button_parts(*button_at)
    d, wdt, _ = cab.size
    box = (xmin - 0.01, cab.origin[1] - wdt / 2, cab.origin[0] + d / 2, cab.origin[1] + wdt / 2)
    return TaskRoom(usd=usd, scene_id=scene_id, size=room.size, wall_thickness=room.wall_thickness,
                    table_xy=table_xy,
                    table_height=TABLE_HEIGHT, bowl_xy=bowl_xy, bowl_inner_radius=BOWL_INNER,
                    drawer_handle=tuple(room.drawer_handle), door_handle=tuple(room.door_handle),
                    door_hinge=tuple(room.door_hinge), drawer_travel=cab.drawer_travel,
                    door_range=cab.door_range,
                    button=(bc[0] - bs[0] / 2, bc[1], bc[2]), button_travel=BUTTON_TRAVEL, cabinet_box=box,
                    materials=colors)


def _free_start(room: TaskRoom, rng: np.random.Generator, door_open: bool) -> tuple[float, float, float]:
    """A start pose in the free west part of the room, clear of every obstacle by 0.5 m."""
    from stages.demos.planner import NavGrid

    grid = NavGrid.from_boxes((-0.2, -0.2, room.size[0] + 0.2, room.size[1] + 0.2), room.nav_boxes(door_open))
    blocked = grid.inflate(0.5)
    for _ in range(200):
        x, y = float(rng.uniform(0.7, 1.7)), float(rng.uniform(0.8, 3.6))
        iy, ix = grid.cell_of(x, y)
        if not blocked[iy, ix]:
            return x, y, float(rng.uniform(-np.pi, np.pi))
    raise ItemError(f"{room.usd}: no free start pose for the robot")


def sample_instance(task_name: str, room: TaskRoom, seed: int) -> TaskInstance:
    """The episode of ``task_name`` in ``room`` drawn from ``seed`` (start pose, object poses,
    initial joints, instruction)."""
    spec = task(task_name)
    rng = np.random.default_rng(seed)
    tx, ty = room.table_xy
    mug = (tx + MUG_OFFSET[0] + float(rng.uniform(-0.03, 0.03)),
           ty + MUG_OFFSET[1] + float(rng.uniform(-0.03, 0.03)))
    block = (tx + BLOCK_OFFSET[0] + float(rng.uniform(-0.02, 0.02)),
             ty + BLOCK_OFFSET[1] + float(rng.uniform(-0.02, 0.02)))
    joints = {DRAWER_JOINT: 0.0, DOOR_JOINT: 0.0, BUTTON_JOINT: 0.0}
    if task_name == "close_drawer":
        joints[DRAWER_JOINT] = -float(rng.uniform(0.6, 0.9)) * room.drawer_travel
    if task_name == "close_door":
        joints[DOOR_JOINT] = -float(rng.uniform(0.75, 0.9)) * room.door_range
    names = {"object": "mug" if spec.family == "pick_place" else "block", "container": "bowl",
             "furniture": "cabinet", "panel": "control panel"}
    instruction = spec.templates[int(rng.integers(len(spec.templates)))].format(**names)
    start = _free_start(room, rng, door_open=task_name == "close_door")
    ids = {"pick_place_bowl": ("mug", "bowl"), "push_object": ("block", "table"),
           "press_button": ("control_panel",)}.get(task_name, ("cabinet",))
    return TaskInstance(task=task_name, seed=int(seed), room=room, instruction=instruction, names=names,
                        start_base=start, mug_xy=mug, block_xy=block, push_direction=(0.0, 1.0),
                        joints=joints,
                        asset_ids=tuple(f"{room.scene_id}/{a}" for a in ids))
