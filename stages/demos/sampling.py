"""Task instances, sampled from a seed in a :class:`~stages.demos.kitchen.KitchenWorld`.

An *instance* (:func:`sample_instance`) is one episode: the robot's start pose (free floor between
the table and the counter, clear of every obstacle by 0.5 m), the poses of the objects it handles
(the mug on the table, on the counter or in the microwave; the bowl and the object to push on the
table), the initial positions of scene joints (the microwave door open for the microwave tasks),
the instruction text and the asset ids involved.

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from pipeline.types import ItemError
from stages.demos.kitchen import KitchenWorld
from stages.demos.parts import parts_of_package
from stages.demos.tasks import ARTICULATED, task

log = logging.getLogger(__name__)

MICROWAVE_OPEN = math.radians(88.0)  # microwave door opening of the microwave tasks [rad]
FRIDGE_OPEN = 0.9  # fridge door opening of pick_place_fridge [fraction of its travel], as open_fridge leaves it
PUSH_DIRECTION = (0.0, 1.0)
POUR_SKILLS = ("pick_pitcher", "pour_drink", "place_pitcher")  # stages.demos.skill_pour
WARDROBE_SKILLS = ("open_wardrobe", "hang_on_rail", "close_wardrobe")  # stages.demos.skill_wardrobe
BOOK_SKILLS = ("shelve_book_1", "shelve_book_2")  # stages.demos.skill_books: the k-th book of the world


@dataclass(frozen=True, kw_only=True)
class TaskInstance:
    """One episode. task; seed; world; instruction; names: words of the instruction; start_base
    (x, y, yaw) [m, rad]; objects: free body prim path -> (x, y, z, yaw) start pose [m, rad];
    joints: scene joint prim path -> initial position [m or rad]; push_direction (2,) unit;
    target: (x, y) where the object goes (counter spot, bowl or cavity centre) [m]; asset_ids;
    part: the articulated part of an open/close task, or the door a place task reaches through
    (None otherwise); place: where a place task's object ends (e.g. a
    :class:`~stages.demos.skill_fridge.Shelf`; None otherwise)."""

    task: str
    seed: int
    world: KitchenWorld
    instruction: str
    names: dict
    start_base: tuple[float, float, float]
    objects: dict
    joints: dict
    push_direction: tuple[float, float]
    target: tuple[float, float]
    asset_ids: tuple[str, ...]
    part: object = None
    place: object = None


def object_coords(pose) -> tuple[float, ...]:
    """A free body's start pose (x, y, z, yaw) or (x, y, z, yaw, roll) [m, rad] (roll about the
    body's X, then yaw about world Z) as its free joint's coordinates: position, quaternion x, y, z, w."""
    x, y, z, yaw, *rest = (float(v) for v in pose)
    roll = rest[0] if rest else 0.0
    cz, sz, cx, sx = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(roll / 2), math.sin(roll / 2)
    return (x, y, z, cz * sx, sz * sx, sz * cx, cz * cx)


def free_start(world: KitchenWorld, rng: np.random.Generator) -> tuple[float, float, float]:
    """A start pose in the world's start area (:meth:`~stages.demos.kitchen.KitchenWorld.start_area`:
    the free floor between the south wall and the counter front), clear of every footprint of its
    ``start_boxes`` by 0.5 m, random heading. A world with an ``anchor`` (x, y) [m] (a house's room:
    :class:`~stages.demos.house_room.HouseRoom`) starts only where the base planner finds a path to
    it (a free pocket behind the sofa is no start)."""
    from stages.demos.driver import ROBOT_RADIUS
    from stages.demos.planner import NavGrid, NoPathError, astar

    grid = NavGrid.from_boxes(world.nav_bounds(), world.start_boxes())
    blocked = grid.inflate(0.5)
    anchor = getattr(world, "anchor", None)
    nav = world.grid() if anchor is not None else None
    nav_blocked = nav.inflate(ROBOT_RADIUS) if nav is not None else None

    def reaches(x: float, y: float) -> bool:
        if nav is None:
            return True
        try:
            astar(nav_blocked, nav.cell_of(x, y), nav.cell_of(*anchor))
        except NoPathError:
            return False
        return True

    x0, y0, x1, y1 = world.start_area()
    for _ in range(400):
        x = float(rng.uniform(x0, x1))
        y = float(rng.uniform(y0, y1))
        iy, ix = grid.cell_of(x, y)
        if 0 <= iy < blocked.shape[0] and 0 <= ix < blocked.shape[1] and not blocked[iy, ix] and reaches(x, y):
            return x, y, float(rng.uniform(-np.pi, np.pi))
    raise ItemError(f"{world.usd}: no free start pose for the robot")


def _on_table(world: KitchenWorld, rng, role: str, dx: float = 0.03, dy: float = 0.02) -> tuple:
    p = world.placed[role].position
    return (p[0] + float(rng.uniform(-dx, dx)), p[1] + float(rng.uniform(-dy, dy)), world.table_z + 0.002)


def sample_instance(task_name: str, world: KitchenWorld, seed: int) -> TaskInstance:
    """The episode of ``task_name`` in ``world`` drawn from ``seed`` (start pose, object poses,
    initial joints, instruction)."""
    spec = task(task_name)
    rng = np.random.default_rng(seed)
    pl = world.placed
    # a world without a table (a house's kitchen, stages.demos.house) has no bowl or object to push
    # a house's living room (stages.demos.house_living) has no mug either: its tasks move their own objects
    mug, bowl, pusher = (pl[k].body() if k in pl else None for k in ("mug", "bowl", "pusher"))
    mug_yaw = float(rng.uniform(-0.25, 0.25))  # the handle (+Y of the mug) points away from the robot
    objects = {mug: (*_on_table(world, rng, "mug"), mug_yaw)} if mug else {}
    if bowl:
        objects[bowl] = (*_on_table(world, rng, "bowl"), 0.0)
    if pusher:
        objects[pusher] = (*_on_table(world, rng, "pusher", 0.02, 0.02), float(rng.uniform(-0.3, 0.3)))
    # parked (stages.demos.kitchen): every episode starts them there
    for role in ("plate", "sponge", "dish_rack", "paper", "trash_can", "pitcher", "cup", "clock"):
        if role in pl:
            objects[pl[role].body()] = (*pl[role].position, pl[role].yaw)
    objects.update(world.drink_parked() if hasattr(world, "drink_parked") else {})
    joints: dict[str, float] = {}
    cav = world.cavity
    cav_c = ((cav[0] + cav[2]) / 2, (cav[1] + cav[3]) / 2)
    spot = (world.counter_spot[0] + float(rng.uniform(-0.02, 0.02)),
            world.counter_spot[1] + float(rng.uniform(-0.02, 0.02)))
    target = (float(objects[bowl][0]), float(objects[bowl][1])) if bowl else spot
    names = {"object": "mug", "container": "bowl", "panel": "microwave"}
    ids = [pl[k] for k in ("mug", "bowl") if k in pl]
    if task_name in ("pick_place_microwave", "pick_from_microwave"):
        joints[pl["microwave"].joint("door_joint")] = MICROWAVE_OPEN
        names["container"] = "microwave"
        ids = [pl["mug"], pl["microwave"], pl["counter"]]
        # 7 cm behind the cavity's front: the wrist stays in front of the counter's edge
        inside = (cav_c[0] + float(rng.uniform(-0.03, 0.03)), cav[1] + 0.07 + float(rng.uniform(0.0, 0.01)))
        if task_name == "pick_place_microwave":
            objects[mug] = (*spot, world.counter_z + 0.002, mug_yaw)
            target = inside
        else:
            objects[mug] = (*inside, world.cavity_z + 0.002, mug_yaw)
            target = spot
    elif task_name == "push_object":
        names["object"] = pl["pusher"].asset.category
        ids = [pl["pusher"], pl["table"]]
        target = tuple(float(v) for v in np.asarray(objects[pusher][:2]) + 0.15 * np.asarray(PUSH_DIRECTION))
    elif task_name == "press_button":
        ids = [pl["microwave"]]
        target = tuple(world.button[:2])
    part = place = None
    if task_name == "pick_place_fridge":
        from stages.demos.skill_fridge import fridge_shelf

        part = world_part(world, "fridge")
        joints[part.joint_path] = part.closed + FRIDGE_OPEN * part.travel
        objects[mug] = (*spot, world.counter_z + 0.002, mug_yaw)
        place = fridge_shelf(world, part, world.mug_radius, world.mug_height)
        target = place.spot
        names["container"] = "fridge"
        ids = [pl["mug"], pl["fridge"], pl["counter"]]
    if task_name == "wipe_plate":
        from stages.demos.skill_wipe import wipe_setup

        moved, place = wipe_setup(world, rng)
        objects.update(moved)
        names.update(object="plate", tool="sponge")
        ids = [pl["plate"], pl["sponge"]]
        target = tuple(float(v) for v in objects[pl["plate"].body()][:2])
    if task_name == "place_in_rack":
        if "dish_rack" not in pl:
            raise ItemError(f"{world.usd}: no dish rack in this task world (a house kitchen with dishes, "
                            f"stages.demos.house_dishes, or a task kitchen from a catalog with a dish rack)")
        names.update(object="plate", container="dish rack")
        ids = [pl["plate"], pl["dish_rack"]]
        target = tuple(float(v) for v in objects[pl["dish_rack"].body()][:2])
    if task_name in ("press_clock_button", "slide_clock_switch"):
        from stages.demos.skill_press import clock_setup

        moved, rest = clock_setup(world)
        objects.update(moved)
        joints.update(rest)
        names.update(object="alarm clock")
        ids = [pl["clock"]]
        target = tuple(float(v) for v in pl["clock"].position[:2])
    if "book_1" in pl:  # a living room with books (stages.demos.house_living): standing on the table
        from stages.demos.skill_books import book_setup

        objects.update(book_setup(world, seed))
    if task_name in BOOK_SKILLS:
        k = BOOK_SKILLS.index(task_name)
        names.update(object="book", container="bookshelf", which=("first", "second")[k])
        ids = [pl[f"book_{k + 1}"], pl["bookshelf"]]
        target = tuple(float(v) for v in pl["bookshelf"].position[:2])
    if task_name == "throw_away":
        from stages.demos.skill_trash import trash_setup

        objects.update(trash_setup(world, rng))
        names.update(object="paper", container="trash can")
        ids = [pl["paper"], pl["trash_can"]]
        target = tuple(float(v) for v in pl["trash_can"].position[:2])
    if task_name == "place_pillow":
        names.update(object="cushion", container="bed")
        ids = [pl["cushion"], pl["bed"]]
        target = tuple(world.pillow_spot)
    if "cushion" in pl:  # a bedroom (stages.demos.house_bedroom): every episode starts it on the blanket
        from stages.demos.skill_bed import cushion_start

        objects.update(cushion_start(world, seed))
    if "hanger" in pl and getattr(world, "rail", None) is not None:
        # a bedroom with a wardrobe (stages.demos.house_bedroom): the hanger lies on the bed's near edge
        from stages.demos.skill_wardrobe import hanger_start

        objects.update(hanger_start(world, seed))
        if task_name in WARDROBE_SKILLS:  # the paper and the cushion off the hanger's way: the bed's far side
            from stages.demos.skill_wardrobe import aside

            objects.update(aside(world))
    if task_name == "hang_on_rail":
        part = world_part(world, "wardrobe")
        joints[part.joint_path] = part.closed + FRIDGE_OPEN * part.travel
        names.update(object="hanger", container="wardrobe")
        ids = [pl["hanger"], pl["wardrobe"]]
        target = tuple(float(v) for v in world.rail.p0[:2])
    if task_name in POUR_SKILLS:
        from stages.demos.drink import pour_setup

        moved, place = pour_setup(world, rng)
        objects.update(moved)
        names.update(object="pitcher", container="cup")
        ids = [pl["pitcher"], pl["cup"]]
        target = place.cup_xy
    kind, _, which = task_name.partition("_")
    if which in ARTICULATED and kind in ("open", "close"):
        role = ARTICULATED[which][0]
        part = world_part(world, which)
        names["furniture"] = ARTICULATED[which][2]
        ids = [pl[role]]
        if kind == "close":
            joints[part.joint_path] = part.closed + float(rng.uniform(0.6, 0.85)) * part.travel
        else:  # (a multistage task that opens it later starts with it closed)
            joints[part.joint_path] = part.closed
        target = tuple(float(v) for v in part.handle[:2])
    instruction = spec.templates[int(rng.integers(len(spec.templates)))].format(**names)
    start = free_start(world, rng)
    return TaskInstance(task=task_name, seed=int(seed), world=world, instruction=instruction, names=names,
                        start_base=start, objects=objects, joints=joints, push_direction=PUSH_DIRECTION,
                        target=target, asset_ids=tuple(p.asset.asset_id for p in ids), part=part, place=place)


def world_part(world: KitchenWorld, which: str):
    """The :class:`~stages.demos.parts.ArticulatedPart` of an open/close task target
    (``ARTICULATED`` key): the microwave, oven or room door, the fridge door whose handle is
    nearest 1 m high, the counter's top drawer."""
    role, part_role, _ = ARTICULATED[which]
    if role not in world.placed:
        raise ItemError(f"{world.usd}: the task world has no {role} for the {which} tasks")
    p = world.placed[role]
    parts = [q for q in parts_of_package(p.info, asset_id=p.asset.asset_id, prim_root=p.prim,
                                         pose=(*p.position, p.yaw), package_usd=p.asset.usd)
             if q.role == part_role]
    if not parts:
        raise ItemError(f"{p.asset.usd}: {p.asset.asset_id} has no {part_role} for the {which} tasks")
    if which == "drawer":
        return max(parts, key=lambda q: q.handle[2])
    if which == "wardrobe" and getattr(world, "wardrobe_door", ""):  # the bedroom's door with room (house_bedroom)
        parts = [q for q in parts if q.joint_path == world.wardrobe_door] or parts
    return min(parts, key=lambda q: abs(q.handle[2] - 1.0))
