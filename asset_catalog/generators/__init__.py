"""Built-in procedural asset library: seeded parametric generators for household assets.

The registry ``GENERATORS`` is data: one ``GeneratorSpec`` per category with its generator function,
room types, placement kind, material class, co-occurring categories, whether the base is fixed, and
the plausible range of its bounding-box size (used by tests and by anyone who needs sizes up front).

    from asset_catalog.generators import GENERATORS, generate
    asset = generate(GENERATORS_BY_CATEGORY["mug"], np.random.default_rng(0), "mug_00")

``generate`` returns a ``GeneratedAsset`` (an ``AssetModel`` plus handles and joint roles);
``write_asset`` writes its source files (OBJ or URDF + OBJ meshes) for the ingest stage.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from asset_catalog.annotations import PlacementKind, RoomType
from asset_catalog.generators import appliances, furniture, objects
from asset_catalog.generators._builder import AssetBuilder, GeneratedAsset, HandleInfo, JointInfo
from asset_catalog.generators._writer import annotations_text, write_asset
from asset_catalog.materials import MaterialClass

__all__ = ["GENERATORS", "GENERATORS_BY_CATEGORY", "GeneratedAsset", "GeneratorSpec", "HandleInfo",
           "JointInfo",
           "annotations_text", "door_for_opening", "generate", "write_asset"]

LR, KI, BR, BA, HW = (RoomType.LIVING_ROOM, RoomType.KITCHEN, RoomType.BEDROOM, RoomType.BATHROOM,
                      RoomType.HALLWAY)
FLOOR, WALL, SURF, WALLM = (PlacementKind.ON_FLOOR, PlacementKind.AGAINST_WALL, PlacementKind.ON_SURFACE,
                            PlacementKind.WALL_MOUNTED)
M = MaterialClass


@dataclass(frozen=True)
class GeneratorSpec:
    """One category of the built-in library.

    fn: draws one variant into an AssetBuilder, returns a target total mass [kg] or None (density x volume);
    fixed_base: articulated furniture that stands on the floor and must not slide when a door or drawer
    is pulled (fridge, cabinets, oven, closet, dresser, counter, door frame);
    rigid_format: "obj" for near-convex rigid objects (collider = convex hull), "urdf" otherwise (the
    URDF carries exact convex collision pieces, so no decomposition is needed);
    size_min, size_max: plausible bounding-box size (x, y, z) [m] of every variant.
    """

    category: str
    fn: Callable[[AssetBuilder], float | None]
    room_types: tuple[RoomType, ...]
    placement: PlacementKind
    material: MaterialClass
    size_min: tuple[float, float, float]
    size_max: tuple[float, float, float]
    interactable: bool = False
    co_occurrence: tuple[str, ...] = ()
    fixed_base: bool = False
    rigid_format: Literal["obj", "urdf"] = "urdf"


def _s(category, fn, rooms, placement, material, size_min, size_max, **kw) -> GeneratorSpec:
    return GeneratorSpec(category, fn, tuple(rooms), placement, material, size_min, size_max, **kw)


F, A, O = furniture, appliances, objects
GENERATORS: tuple[GeneratorSpec, ...] = (
    # basic furniture
    _s("sofa", F.sofa, [LR], WALL, M.FABRIC, (0.7, 1.5, 0.7), (1.0, 3.2, 0.95),
       co_occurrence=("coffee_table", "rug", "tv_stand")),
    _s("armchair", F.armchair, [LR, BR], FLOOR, M.FABRIC, (0.7, 0.7, 0.7), (1.0, 1.0, 0.95),
       co_occurrence=("coffee_table", "floor_lamp")),
    _s("coffee_table", F.coffee_table, [LR], FLOOR, M.WOOD, (0.8, 0.45, 0.35), (1.35, 0.8, 0.5),
       co_occurrence=("sofa", "rug")),
    _s("tv_stand", F.tv_stand, [LR, BR], WALL, M.WOOD, (0.34, 1.15, 0.95), (0.46, 1.85, 1.6),
       co_occurrence=("sofa",)),
    _s("bookshelf", F.bookshelf, [LR, BR, HW], WALL, M.WOOD, (0.24, 0.58, 1.05), (0.37, 1.02, 2.05),
       co_occurrence=("book",)),
    _s("bed", F.bed, [BR], WALL, M.FABRIC, (1.95, 0.88, 0.8), (2.15, 1.9, 1.25),
       co_occurrence=("nightstand", "pillow")),
    _s("nightstand", F.nightstand, [BR], WALL, M.WOOD, (0.35, 0.4, 0.5), (0.52, 0.56, 0.66),
       interactable=True,
       co_occurrence=("bed", "alarm_clock"), fixed_base=True),
    _s("wardrobe", F.wardrobe, [BR, HW], WALL, M.WOOD, (0.57, 0.8, 1.8), (0.7, 1.26, 2.11), interactable=True,
       co_occurrence=("hanger", "bed"), fixed_base=True),
    _s("dresser", F.dresser, [BR], WALL, M.WOOD, (0.47, 0.8, 0.75), (0.63, 1.41, 1.01), interactable=True,
       co_occurrence=("bed",), fixed_base=True),
    _s("dining_table", F.dining_table, [KI, LR], FLOOR, M.WOOD, (0.75, 0.75, 0.72), (2.0, 1.2, 0.78),
       co_occurrence=("chair",)),
    _s("chair", F.chair, [KI, LR, BR], FLOOR, M.WOOD, (0.38, 0.38, 0.78), (0.5, 0.5, 0.96),
       co_occurrence=("dining_table",)),
    _s("kitchen_counter", F.kitchen_counter, [KI], WALL, M.WOOD, (0.6, 1.5, 1.1), (0.7, 3.2, 1.25),
       interactable=True,
       co_occurrence=("fridge", "oven", "microwave"), fixed_base=True),
    _s("rug", F.rug, [LR, BR, HW], FLOOR, M.FABRIC, (0.78, 0.78, 0.005), (3.0, 2.2, 0.02), rigid_format="obj",
       co_occurrence=("sofa", "bed")),
    _s("floor_lamp", F.floor_lamp, [LR, BR], FLOOR, M.METAL, (0.24, 0.24, 1.35), (0.52, 0.52, 1.85),
       co_occurrence=("sofa", "armchair")),
    # articulated interactables
    _s("fridge", A.fridge, [KI], WALL, M.METAL, (0.6, 0.55, 1.5), (0.75, 0.92, 1.92), interactable=True,
       co_occurrence=("kitchen_counter",), fixed_base=True),
    _s("microwave", A.microwave, [KI], SURF, M.METAL, (0.34, 0.45, 0.26), (0.47, 0.57, 0.33),
       interactable=True,
       co_occurrence=("kitchen_counter", "mug", "bowl")),
    _s("oven", A.oven, [KI], WALL, M.METAL, (0.6, 0.58, 0.85), (0.72, 0.77, 0.95), interactable=True,
       co_occurrence=("kitchen_counter", "pitcher")),
    _s("cabinet", F.cabinet, [KI, LR, BR, BA, HW], WALL, M.WOOD, (0.45, 0.4, 0.72), (0.65, 0.91, 0.91),
       interactable=True,
       fixed_base=True),
    _s("closet", F.closet, [BR, HW], WALL, M.WOOD, (0.55, 0.9, 2.0), (0.7, 2.45, 2.41), interactable=True,
       co_occurrence=("hanger",), fixed_base=True),
    _s("door", A.room_door, [LR, KI, BR, BA, HW], WALLM, M.WOOD, (0.1, 0.88, 2.03), (0.22, 0.99, 2.11),
       interactable=True,
       fixed_base=True),
    # rigid interactables
    _s("bowl", O.bowl, [KI, LR], SURF, M.CERAMIC, (0.12, 0.12, 0.045), (0.2, 0.2, 0.085), interactable=True,
       co_occurrence=("dining_table", "kitchen_counter", "apple", "orange")),
    _s("plate", O.plate, [KI, LR], SURF, M.CERAMIC, (0.2, 0.2, 0.015), (0.28, 0.28, 0.028), interactable=True,
       rigid_format="obj", co_occurrence=("dining_table", "kitchen_counter")),
    _s("mug", O.mug, [KI, LR], SURF, M.CERAMIC, (0.07, 0.1, 0.08), (0.1, 0.15, 0.11), interactable=True,
       co_occurrence=("coffee_table", "kitchen_counter", "microwave")),
    _s("cup", O.cup, [KI, LR, BA], SURF, M.PLASTIC, (0.064, 0.064, 0.08), (0.09, 0.09, 0.13),
       interactable=True,
       co_occurrence=("dining_table", "kitchen_counter")),
    _s("bottle", O.bottle, [KI, LR], SURF, M.PLASTIC, (0.06, 0.06, 0.18), (0.09, 0.09, 0.3),
       interactable=True,
       rigid_format="obj", co_occurrence=("kitchen_counter", "fridge")),
    _s("pitcher", O.pitcher, [KI, LR], SURF, M.CERAMIC, (0.1, 0.16, 0.17), (0.14, 0.26, 0.26),
       interactable=True,
       co_occurrence=("dining_table", "kitchen_counter", "coffee_table", "cup")),
    _s("book", O.book, [LR, BR], SURF, M.PAPER, (0.15, 0.11, 0.01), (0.26, 0.19, 0.05), interactable=True,
       rigid_format="obj", co_occurrence=("bookshelf", "nightstand", "coffee_table")),
    _s("box", O.box, [LR, BR, HW, KI], SURF, M.PAPER, (0.15, 0.12, 0.08), (0.5, 0.4, 0.35), interactable=True,
       rigid_format="obj", co_occurrence=("closet", "bookshelf")),
    _s("can", O.can, [KI, LR], SURF, M.METAL, (0.064, 0.064, 0.1), (0.084, 0.084, 0.135), interactable=True,
       rigid_format="obj", co_occurrence=("kitchen_counter", "fridge")),
    _s("apple", O.apple, [KI, LR], SURF, M.FOOD, (0.065, 0.065, 0.06), (0.1, 0.1, 0.106), interactable=True,
       rigid_format="obj", co_occurrence=("bowl", "dining_table")),
    _s("orange", O.orange, [KI, LR], SURF, M.FOOD, (0.068, 0.068, 0.058), (0.092, 0.092, 0.09),
       interactable=True,
       rigid_format="obj", co_occurrence=("bowl", "dining_table")),
    _s("banana", O.banana, [KI, LR], SURF, M.FOOD, (0.02, 0.1, 0.028), (0.08, 0.26, 0.04), interactable=True,
       co_occurrence=("bowl", "kitchen_counter")),
    _s("crumpled_paper", O.crumpled_paper, [LR, BR, KI, HW], SURF, M.PAPER, (0.035, 0.035, 0.03),
       (0.12, 0.12, 0.12),
       interactable=True, rigid_format="obj", co_occurrence=("coffee_table", "dining_table")),
    _s("pillow", O.pillow, [BR, LR], SURF, M.FABRIC, (0.4, 0.3, 0.09), (0.65, 0.45, 0.16), interactable=True,
       rigid_format="obj", co_occurrence=("bed", "sofa", "armchair")),
    _s("cushion", O.cushion, [BR, LR], SURF, M.FABRIC, (0.055, 0.28, 0.05), (0.07, 0.4, 0.065),
       interactable=True, rigid_format="obj", co_occurrence=("bed", "sofa")),
    _s("sponge", O.sponge, [KI, BA], SURF, M.RUBBER, (0.09, 0.06, 0.024), (0.13, 0.08, 0.045),
       interactable=True,
       rigid_format="obj", co_occurrence=("kitchen_counter",)),
    _s("alarm_clock", A.alarm_clock, [BR], SURF, M.PLASTIC, (0.035, 0.09, 0.1), (0.075, 0.14, 0.16),
       interactable=True,
       co_occurrence=("nightstand",)),
    _s("hanger", O.hanger, [BR, HW], SURF, M.PLASTIC, (0.13, 0.38, 0.003), (0.32, 0.47, 0.032),
       interactable=True,
       co_occurrence=("closet", "wardrobe")),
    # open containers for the household tasks (clean the table, clean dishes)
    _s("trash_can", O.trash_can, [LR, KI, BR, BA], FLOOR, M.PLASTIC, (0.2, 0.22, 0.26), (0.36, 0.38, 0.45),
       interactable=True, co_occurrence=("coffee_table", "kitchen_counter", "crumpled_paper")),
    _s("dish_rack", O.dish_rack, [KI], SURF, M.METAL, (0.26, 0.34, 0.084), (0.34, 0.44, 0.125),
       interactable=True, co_occurrence=("kitchen_counter", "plate", "sponge")),
)
GENERATORS_BY_CATEGORY: dict[str, GeneratorSpec] = {s.category: s for s in GENERATORS}


def generate(spec: GeneratorSpec, rng: np.random.Generator, asset_id: str, source: str | None = None,
             overrides: dict[str, float] | None = None) -> GeneratedAsset:
    """Draw one variant of ``spec`` from ``rng``. ``source`` is the annotation's source path (relative
    to the catalog folder); default ``<category>/<asset_id>/<asset_id>.<obj|urdf>``. ``overrides`` fixes
    named parameters (see ``GeneratedAsset.params`` for the names, e.g. a sofa's "seat_height" [m])."""
    b = AssetBuilder(rng, overrides)
    target = spec.fn(b)
    ext = "obj" if spec.rigid_format == "obj" and len(b.links) == 1 else "urdf"
    src = source or f"{spec.category}/{asset_id}/{asset_id}.{ext}"
    return b.build(asset_id=asset_id, category=spec.category, source=src, room_types=spec.room_types,
                   placement=spec.placement, material=spec.material, interactable=spec.interactable,
                   co_occurrence=spec.co_occurrence, fixed_base=spec.fixed_base, target_mass=target,
                   rigid_format=spec.rigid_format)


def door_for_opening(width: float, height: float, wall_thickness: float, rng: np.random.Generator,
                     asset_id: str = "door") -> GeneratedAsset:
    """A room door whose frame exactly fills a wall opening of ``width`` x ``height`` [m] in a wall of
    ``wall_thickness`` [m]: leaf = width - 2 x (jamb 0.04 + gap 0.003), height - 0.053. The asset's origin
    is the opening's centre at floor level; the leaf swings towards +X (90 degrees)."""
    jamb_and_gap = 2 * (appliances.DOOR_JAMB + appliances.DOOR_GAP)
    head = appliances.DOOR_FLOOR_GAP + appliances.DOOR_GAP + appliances.DOOR_JAMB
    leaf_w, leaf_h = width - jamb_and_gap, height - head
    if not (0.5 <= leaf_w <= 1.2 and 1.8 <= leaf_h <= 2.6 and 0.05 <= wall_thickness <= 0.5):
        raise ValueError(f"opening {width:.3f} x {height:.3f} m in a {wall_thickness:.3f} m wall is outside "
                         "0.59-1.29 m x 1.85-2.65 m, wall 0.05-0.5 m")
    return generate(GENERATORS_BY_CATEGORY["door"], rng, asset_id,
                    overrides={"leaf_width": leaf_w, "leaf_height": leaf_h, "wall_thickness": wall_thickness})
