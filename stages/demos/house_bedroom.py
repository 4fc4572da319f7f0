"""A generated house's bedroom as the task world (issue 16, make the bed): the scene stage's output
turned into the facts the bedroom skills read, on the shared house-room machinery
(:mod:`stages.demos.house_room`).

:func:`house_bedroom` picks the bedroom's bed, with a piece of crumpled paper and a neck-roll cushion
on it that the hand grasps, the trash can, and the nightstands (the household rules place them:
``stages/scene/rules/household_tasks.toml``). It turns the house by the multiple of 90 deg about +Z
that lays the bed along X with one long side facing world -Y (the experts work at a surface from its
south side, facing +Y): first with the bed's foot (its local +X; the headboard is at local -X) to
the west, else to the east (``foot`` -1 / +1), whichever leaves free floor for the base before the
paper and before the head band and room for the trash can off the bed's foot. The trash can is moved
onto the floor off the bed's foot (:data:`~stages.demos.house_living.CAN_GAP` off its footprint,
0.15 m north of the top's front), where it stands clear of the walls and the floor furniture. The
work surface (``table_rect`` / ``table_z``, as the living room's coffee table) is the strip of the
blanket's top at the bed's foot where the paper is set (:func:`stages.demos.skill_trash.trash_setup`:
``PAPER_AT`` in from the strip's west end), slid up to :data:`PAPER_SLIDE` head-ward where the base's
pose before the foot is blocked. The head band (between the headboard and the blanket's start) is
where the cushion goes (:mod:`stages.demos.skill_bed`: across the bed, just foot-ward of the bed's own
pillows); the base's pose for it stands as near the spot as the floor allows (a nightstand on the
robot's side takes the floor before the head). The task scene deactivates the other rooms' objects
and the bed's other objects (the pillows and books: they lie where the cushion and paper go).
Conversion needs about 1.05 m of free floor along the bed's side (the base's staging pose, inflated
by its radius): many generated bedrooms lack it (ItemError names what failed on each side).

Facts (task frame, Z up, metres, radians): ``placed`` roles "bed" (also "table"), "paper",
"trash_can", "cushion" and, where present, "nightstand" (the first); ``head_band``: (xmin, ymin,
xmax, ymax) of the bed's head band; ``blanket_x``: the blanket's start (the band's foot-side end);
``foot``: -1 (the bed's foot to the west) or +1 (east); ``mattress_z``: the mattress's top; ``pillow_spot``: (x, y) where
the cushion's centre is put; ``pillow_base_x``: the x of the base's pose (facing +Y) for the cushion.

::

    world = house_bedroom(Path("out/scenes_household/scenes/flat_000_p0"), Path("out/task"),
                          Path("out/scenes_household/catalog/default/generated.json"), scene_id="flat_000_p0")
    inst = sample_task("make_bed", world, seed=1)
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.demos.house_living import CAN_CLEAR, CAN_GAP, CAN_NORTH
from stages.demos.house_room import (HouseRoom, base_free, obstacles, overlaps, read_room, room_fields, room_frame,
                                     spawn_in, top_surface, write_task_scene)
from stages.demos.packages import Placed
from stages.demos.skill_bed import MAX_CUSHION_WIDTH, PILLOW_REACH, PILLOW_SPOT_IN
from stages.demos.skill_trash import MAX_PAPER_RADIUS, PAPER_AT

log = logging.getLogger(__name__)

HEADBOARD = 0.06    # the bed generator's headboard thickness [m] (asset_catalog.generators.furniture.bed)
PAPER_STRIP = 0.24  # table_rect: the blanket top's foot-end strip this long [m] (the paper: PAPER_AT
                    # in from its west end)
HANGER_CLEAR = 0.03  # the hanger lies this far [m] at least from the blanket's ends
LEAF_SWEEP = 0.6     # the wardrobe's open leaves reach this share of its footprint's longer side out from it
ARM_BACK = 0.65      # the arm pinching the hanger's neck sweeps from this far [m] before the blanket's edge ...
ARM_SIDE = 0.25      # ... to this far [m] beyond the base's x (the base PICK_SIDE along +X from the neck)
FRONT_OUT = 0.75    # the base's way before the wardrobe: this far [m] out from its front's middle
PAPER_SLIDE = 0.15  # the strip slides this far [m] at most from the foot end (the can stays within reach)


@dataclass(frozen=True, kw_only=True, eq=False)
class HouseBedroom(HouseRoom):
    """A :class:`~stages.demos.house_room.HouseRoom` whose room is a bedroom (see the module doc)."""

    head_band: tuple[float, float, float, float]
    mattress_z: float
    blanket_x: float
    foot: int
    pillow_spot: tuple[float, float]
    pillow_base_x: float
    blanket_edge: float = 0.0
    hanger_x: float = 0.0
    rail: object = None
    #: the joint path of the wardrobe door the wardrobe tasks open (:func:`_door_with_room`; "": the first)
    wardrobe_door: str = ""
    #: the engine steps this world with MuJoCo's multi-CCD contacts (:class:`~stages.simulate.world.SolverSettings`):
    #: with one contact point per convex pair, the hanger, cushion and paper crept 3-8 mm/s across the blanket.
    #: Off unless asked (make_bed's base, driven up to the bed, stopped 1 cm short with it: flat_008 seed 1)
    multiccd: bool = False


def _bed_facts(bed: Placed, foot: int) -> tuple[tuple[float, float, float, float], float, float]:
    """The bed's head band (task frame; the bed along X, its foot to ``foot`` (-1: west, +1: east)),
    its mattress's top [m] and the blanket's start x [m] (the band's foot-side end), from the bed
    generator's parameters."""
    p = bed.asset.params
    try:
        length, fh, mt, bs = (float(p[k]) for k in ("length", "frame_height", "mattress_thickness", "blanket_start"))
    except KeyError as e:
        raise ItemError(f"{bed.asset.usd}: {bed.asset.asset_id} lacks the bed parameter {e}") from None
    x0, y0, x1, y1 = bed.rect((-length / 2, bed.asset.lo[1]), (length / 2, bed.asset.hi[1]))
    head = x1 - HEADBOARD if foot < 0 else x0 + HEADBOARD
    blanket = head + foot * (length - 0.1) * bs
    band = (min(head, blanket), y0 + 0.04, max(head, blanket), y1 - 0.04)
    return band, float(bed.position[2] + fh - 0.04 + mt), blanket


def _side(rs, bed: dict, can: dict, cushion: dict, foot: int):
    """The bed turned with its foot to ``foot`` (-1: west, +1: east) and its free long side to -Y:
    (frame, furniture, moved can, paper strip, surface z, band, mattress z, blanket x, goal of the
    throw, the cushion's spot, the base's x for it) or a one-line reason why not."""
    from stages.demos.counter import facing_north_goal

    can_asset = rs.asset(can)
    rf = room_frame(rs.house, rs.room, (math.pi if foot < 0 else 0.0) - bed["yaw"])
    furniture = {n: rf.placed(r, rs.asset(r)) for n, r in rs.mine.items() if r["support"] is None}
    bp = furniture[bed["name"]]
    top, z = top_surface(bp)
    band, mattress_z, blanket = _bed_facts(bp, foot)
    bfp = bp.footprint()
    cx = bfp[0] - CAN_GAP - can_asset.hi[0] if foot < 0 else bfp[2] + CAN_GAP - can_asset.lo[0]
    cp = Placed(f"Objects/{can['name']}", can_asset, (float(cx), float(top[1] + CAN_NORTH), float(can["position"][2])),
                0.0)
    fp = cp.footprint()
    x0, y0, x1, y1 = rf.area
    others = [p for n, p in furniture.items() if n != can["name"]]
    boxes = obstacles(others + [cp])
    inside = (x0 + CAN_CLEAR <= fp[0] and fp[2] <= x1 - CAN_CLEAR
              and y0 + CAN_CLEAR <= fp[1] and fp[3] <= y1 - CAN_CLEAR)
    clash = [b for b in list(rf.walls) + obstacles(others) if overlaps(fp, b, CAN_CLEAR)]
    if not inside or clash:
        return "the can's place off the bed's foot is " + ("off the floor" if not inside else "taken")
    # the paper's strip: the blanket top's foot end, slid head-ward up to PAPER_SLIDE where the base's
    # pose before the foot is blocked (trash_setup sets the paper PAPER_AT in from the strip's west end)
    for d in np.arange(0.0, PAPER_SLIDE + 1e-9, 0.05):
        rect = ((top[0] + d, top[1], top[0] + d + PAPER_STRIP, top[3]) if foot < 0 else
                (top[2] - d - PAPER_STRIP, top[1], top[2] - d, top[3]))
        goal = facing_north_goal(rect[1], rect[0] + PAPER_AT[0])
        if x0 < goal[0] < x1 and y0 < goal[1] < y1 and base_free(goal, rf.walls, boxes):
            break
    else:
        return "no room for the base before the bed's foot"
    # the cushion's spot in the head band; the base's pose for it: the nearest free one foot-ward of the spot
    head = band[2] if foot < 0 else band[0]
    c = rs.asset(cushion)
    spot = (float(head + foot * (PILLOW_SPOT_IN + 0.5 * c.params.get("width", 0.07))),
            float(rect[1] - 0.03 + 0.5 * c.params.get("length", 0.4)))
    base_x = next((float(spot[0] + foot * d) for d in np.arange(0.0, PILLOW_REACH + 1e-9, 0.05)
                   if x0 < spot[0] + foot * d < x1
                   and base_free(facing_north_goal(rect[1], float(spot[0] + foot * d)), rf.walls, boxes)), None)
    if base_x is None:
        return f"no free floor for the base within {PILLOW_REACH} m of the head band"
    return rf, furniture, cp, rect, z, band, mattress_z, blanket, goal, spot, base_x


def _floor_to_front(rf, boxes: list, wp: Placed, pick: tuple[float, float, float]) -> bool:
    """Whether the base (the planner's footprint disc) gets from ``pick`` (x, y, yaw: its pose before the
    hanger's spot) to before the closed wardrobe ``wp`` (FRONT_OUT [m] out from its front's middle, or a
    free point within 0.3 m of there) on the room's floor (walls and ``boxes``, footprints [m]): flat_013's
    wardrobe stood behind a 0.76 m gap between its corner and the bed's, the base's disc 0.8 m wide."""
    from stages.demos.part_planning import connected, is_free
    from stages.demos.planner import NavGrid

    x0, y0, x1, y1 = rf.area
    grid = NavGrid.from_boxes((x0 - 0.2, y0 - 0.2, x1 + 0.2, y1 + 0.2), np.asarray(list(rf.walls) + list(boxes), float))
    on = connected(grid, pick[:2], reach=0.3)
    f = np.asarray(wp.dir_to_world((1.0, 0.0, 0.0)), float)[:2]
    out = np.asarray(wp.to_world((wp.asset.hi[0], 0.0, 0.0)), float)[:2] + FRONT_OUT * f / max(float(np.linalg.norm(f)), 1e-9)
    return any(is_free(grid, ~on, float(out[0] + r * math.cos(a)), float(out[1] + r * math.sin(a)))
               for r in (0.0, 0.1, 0.2, 0.3) for a in np.linspace(0.0, 2 * math.pi, 12, endpoint=False))


def _door_with_room(rf, boxes: list, wp: Placed, picks: list) -> tuple[int, str] | None:
    """``(k, joint path)``: the first of the hanger's base poses ``picks`` (x, y, yaw facing +Y) with a door of the
    wardrobe ``wp`` (in :func:`~stages.demos.sampling.world_part`'s order) whose leaf, open to its stop, to 0.9 and to
    0.8 of its travel (open_wardrobe's stage may end short), leaves the base (the planner's disc) on the room's floor
    (walls and ``boxes`` [m]) the staging point of that pose (or drive_to's nearer one), a pose round the leaf's
    free edge to push it shut (the push plan's candidates, the turned fists' 140 deg:
    :func:`~stages.demos.part_planning._swing_bases`) and the staging point of the hang pose
    (:func:`~stages.demos.base_approach.staging`), all on one floor; None where no pose has such a door (the
    40-flat bench's flat_023: the leaf ended 0.39 m from a wall, no base to push it shut; flat_028: the open leaf
    cut the floor between the bed and the hang pose; flat_013 at 0.8 of the travel: the leaf blocked the pinch
    pose's staging point). The grid, the doors and each open leaf's grid and hang staging are made once."""
    from types import SimpleNamespace

    from stages.demos.base_approach import leaf_points, staging
    from stages.demos.counter import COUNTER_STAGE
    from stages.demos.driver import NEAR_STAGING, ExpertFailure
    from stages.demos.part_planning import _swing_bases, connected, is_free, swept_grid
    from stages.demos.parts import parts_of_package
    from stages.demos.planner import NavGrid
    from stages.demos.skill_wardrobe import hang_base, rail_facts

    x0, y0, x1, y1 = rf.area
    grid = NavGrid.from_boxes((x0 - 0.2, y0 - 0.2, x1 + 0.2, y1 + 0.2), np.asarray(list(rf.walls) + list(boxes), float))
    doors = [q for q in parts_of_package(wp.info, asset_id=wp.asset.asset_id, prim_root=wp.prim,
                                         pose=(*wp.position, wp.yaw), package_usd=wp.asset.usd)
             if q.role == "door" and q.kind == "revolute"]
    doors.sort(key=lambda q: abs(q.handle[2] - 1.0))  # stable: world_part's first door first
    rail, world = rail_facts(wp), SimpleNamespace(placed={"wardrobe": wp})
    opened: dict = {}  # (door index, fraction) -> (its grid, the hang pose's staging point or None)

    def leaf_open(n: int, frac: float):
        if (n, frac) not in opened:
            part = doors[n]
            q = part.closed + frac * part.travel
            g = swept_grid(grid, part, q, q)
            try:
                point, _ = staging(g, hang_base(world, rail, part, q)[0], leaf_points(part, q))
            except ExpertFailure:
                point = None
            opened[n, frac] = g, point
        return opened[n, frac]

    def room_for(n: int, pick) -> bool:
        part = doors[n]
        for frac in (1.0, 0.9, 0.8):
            q = part.closed + frac * part.travel
            g, point = leaf_open(n, frac)
            on = connected(g, pick[:2], reach=1.0)
            if not any(is_free(g, ~on, pick[0], pick[1] - back) for back in (COUNTER_STAGE, NEAR_STAGING)):
                return False
            if not _swing_bases(part, g, q, list(np.linspace(q, part.closed, 8)), spread=140.0, within=on):
                return False
            if point is None or not on[g.cell_of(*point)]:
                return False
        return True

    return next(((k, doors[n].joint_path) for k, pick in enumerate(picks) for n in range(len(doors))
                 if room_for(n, pick)), None)


def _wardrobe(rs, rf, furniture: dict, pl: dict, bp: Placed, foot: int) -> dict | None:
    """The organize-wardrobe facts (:mod:`stages.demos.skill_wardrobe`), or None where the bedroom
    has no wardrobe with a lower rail and a hanger in it (make_bed does not need them): adds
    ``placed`` "wardrobe" and "hanger"; returns the fields ``blanket_edge`` (the blanket's near edge y),
    ``hanger_x`` (where the hanger lies on it: where the base's pose for its neck is free) and ``rail``."""
    from stages.demos.counter import facing_north_goal
    from stages.demos.skill_wardrobe import PICK_GAP, PICK_SIDE, rail_facts

    wr = rs.one("wardrobe", lambda r: r["support"] is None and "low_rail" in rs.asset(r).params)
    # of the wardrobe's hangers (2-3), the one with the thickest rod: a wire hanger (1.8-2.5 mm) rolled about its
    # neck in the pinch (its one-sided boss turned aside and the neck slid: flat_000)
    hangers = [r for r in rs.mine.values() if r["category"] == "hanger" and wr is not None
               and r["support"] == wr["name"] and "neck_stop" in rs.asset(r).params]
    hanger = max(hangers, key=lambda r: float(rs.asset(r).params.get("rod", 0.0)), default=None)
    if wr is None or hanger is None:
        log.info("bedroom %s: no wardrobe with a lower rail and a hanger: no organize_wardrobe", rs.room)
        return None
    edge = float(bp.footprint()[1] + 0.01)
    top, _ = top_surface(bp)
    boxes = obstacles(list(furniture.values()))
    wp = furniture[wr["name"]]
    hp = rf.placed(hanger, rs.asset(hanger))
    half = 0.5 * float(hp.asset.params.get("width", 0.45)) + HANGER_CLEAR
    # the open doors' leaves sweep about the wardrobe's half width out from its footprint: the arm, reaching
    # the neck from +X, kept clear of that (flat_039: the leaf stood where the elbow went; the base was pushed)
    fp = wp.footprint()
    keep = float(LEAF_SWEEP * max(fp[2] - fp[0], fp[3] - fp[1]))
    keep_out = (fp[0] - keep, fp[1] - keep, fp[2] + keep, fp[3] + keep)
    free, clear = [], []
    for d in np.arange(0.26, 1.2, 0.06):
        x = float(top[0] + d if foot < 0 else top[2] - d)
        if x - half < top[0] or x + half > top[2]:  # flat on the blanket (the cushion goes aside: sampling)
            continue
        if not base_free(facing_north_goal(edge, x + PICK_SIDE, gap=PICK_GAP), rf.walls, boxes):
            continue
        free.append(x)
        arm = (x - 0.05, edge - ARM_BACK, x + PICK_SIDE + ARM_SIDE, edge + 0.1)
        if not overlaps(arm, keep_out, 0.0):
            clear.append(x)
    if not free:
        log.info("bedroom %s: no free base pose before the hanger's spot on the bed", rs.room)
        return None
    x = (clear or free)[0]
    if not _floor_to_front(rf, boxes, wp, facing_north_goal(edge, x + PICK_SIDE, gap=PICK_GAP)):
        log.info("bedroom %s: no floor for the base from the bed to the wardrobe's front", rs.room)
        return None
    # the first spot (arm clear of the leaves first) with a door whose open leaf leaves the base its floor
    spots = clear + [v for v in free if v not in clear]
    found = _door_with_room(rf, boxes, wp, [facing_north_goal(edge, v + PICK_SIDE, gap=PICK_GAP) for v in spots])
    if found is None:
        log.info("bedroom %s: no wardrobe door whose open leaf leaves the base room to hang and to push it shut", rs.room)
        return None
    x, door = spots[found[0]], found[1]
    pl["wardrobe"] = wp
    pl["hanger"] = hp
    return {"blanket_edge": edge, "hanger_x": float(x), "rail": rail_facts(pl["wardrobe"]), "wardrobe_door": door}


def house_bedroom(scene_dir: Path, out_dir: Path, generated_json: Path, *, scene_id: str,
                  room: str | None = None, multiccd: bool = False) -> HouseBedroom:
    """The task world of the bedroom ``room`` (default: the house's first populated bedroom) of the
    scene in ``scene_dir``, written to ``out_dir/scene.usda`` (see the module doc; ``multiccd``: the
    world's field, for the wardrobe tasks). ItemError names what the room lacks or why neither long
    side of the bed works."""
    from stages.demos.experts import COUNTER_STAGE

    scene_dir, out_dir = Path(scene_dir), Path(out_dir)
    rs = read_room(scene_dir, generated_json, "bedroom", room)
    bed = rs.one("bed", lambda r: r["support"] is None)
    on_bed = (lambda r: bed is not None and r["support"] == bed["name"])
    paper = rs.one("crumpled_paper", lambda r: on_bed(r)
                   and float(rs.asset(r).params.get("radius", 1.0)) <= MAX_PAPER_RADIUS)
    cushion = rs.one("cushion", lambda r: on_bed(r)
                     and float(rs.asset(r).params.get("width", 1.0)) <= MAX_CUSHION_WIDTH)
    can = rs.one("trash_can", lambda r: r["support"] is None)
    if bed is None or paper is None or cushion is None or can is None:
        lack = [w for w, r in (("a bed", bed),
                               (f"crumpled paper under {MAX_PAPER_RADIUS * 2000:.0f} mm on the bed", paper),
                               (f"a cushion under {MAX_CUSHION_WIDTH * 1000:.0f} mm wide on the bed", cushion),
                               ("a trash can", can)) if r is None]
        raise ItemError(f"{scene_dir}: bedroom {rs.room} lacks {', '.join(lack)}")
    sides = {foot: _side(rs, bed, can, cushion, foot) for foot in (-1, 1)}
    ok = [s for s in sides.values() if not isinstance(s, str)]
    if not ok:
        raise ItemError(f"{scene_dir}: bedroom {rs.room}: no long side of the bed works (foot west: {sides[-1]}; "
                        f"foot east: {sides[1]})")
    rf, furniture, cp, rect, z, band, mattress_z, blanket, goal, spot, base_x = ok[0]
    foot = -1 if ok[0] is sides[-1] else 1
    bp = furniture[bed["name"]]
    furniture[can["name"]] = cp
    pl: dict[str, Placed] = {"bed": bp, "table": bp, "trash_can": cp, "paper": rf.placed(paper, rs.asset(paper)),
                             "cushion": rf.placed(cushion, rs.asset(cushion))}
    stand = rs.one("nightstand", lambda r: r["support"] is None)
    if stand is not None:
        pl["nightstand"] = furniture[stand["name"]]
    cut = rs.other_rooms_objects() + [n for n, r in rs.mine.items()
                                      if on_bed(r) and n not in (paper["name"], cushion["name"])]
    wardrobe = _wardrobe(rs, rf, furniture, pl, bp, foot)
    if wardrobe is not None:
        cut += [n for n, r in rs.mine.items() if r["category"] == "hanger" and n != pl["hanger"].name.removeprefix("Objects/")]
    hxy = rf.to_house(cp.position[:2])
    moved = (can["name"], (float(hxy[0]), float(hxy[1]), float(can["position"][2])))
    usd = out_dir / "scene.usda"
    write_task_scene(usd, rs.house, rf.frame, cut, moved)
    paper_spot = (rect[0] + PAPER_AT[0], rect[1] + PAPER_AT[1])
    w = HouseBedroom(
        usd=usd, scene_id=scene_id, placed=pl, furniture=furniture, cut=tuple(sorted(cut)), moved=moved,
        anchor=(float(goal[0]), float(goal[1] - COUNTER_STAGE)), head_band=band, mattress_z=mattress_z,
        blanket_x=blanket, foot=foot, pillow_spot=spot, pillow_base_x=base_x, multiccd=multiccd,
        **(wardrobe or {}),
        **room_fields(rs, rf, rect, z, paper_spot))
    spawn_in(w)
    log.info("house bedroom %s (%s, %s): %s; cut %d", scene_id, scene_dir.name, rs.room, w.asset_ids(), len(cut))
    return w
