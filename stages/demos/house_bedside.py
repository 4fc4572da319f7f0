"""A generated house's bedroom as the task world of the alarm clock (issue 16, set the alarm clock):
the nightstand the household rules put the clock on (``stages/scene/rules/household_tasks.toml``)
as the work surface, on the shared house-room machinery (:mod:`stages.demos.house_room`).

:func:`house_bedside` picks the bedroom's alarm clock standing on a nightstand. It turns the house
by the multiple of 90 deg about +Z that puts a side of the nightstand with free floor before it to
world -Y (the experts work at a surface from its south side, facing +Y): the nightstand's front
first, then its other sides (the bed usually stands 4-15 cm beside it). The base's pose before the
nightstand (:func:`~stages.demos.counter.facing_north_goal`, :data:`BASE_GAP` before it) is the nearest
free one (its staging pose, and the chassis's straight way in from it) along the nightstand's south side, up to :data:`CLOCK_REACH` from the top's middle (the base's 0.4 m disc
does not fit between the bed's side and the clock); the clock is parked on the top at that x
(clamped :data:`CLOCK_EDGE` inside the top's ends), :data:`~stages.demos.kitchen.CLOCK_FRONT` behind
its front edge, facing north (its back, with the switch, to the robot: as the task kitchen parks it).
The task scene deactivates the other rooms' objects, the nightstand's other objects and the room's
trash can (:data:`MOVABLE`: the make-the-bed rules put it beside the bed, often before the nightstand).

Facts (task frame, Z up, metres, radians): ``placed`` roles "clock", "nightstand" (also "counter"
and "table": the surface the press and slide experts approach, :func:`stages.demos.counter.approach_counter`);
``counter_rect`` / ``counter_z``: the nightstand's top and its height; ``base_x``: the x of the
base's pose before the nightstand (facing +Y); ``anchor``: the staging point of that pose (starts
are drawn only where the planner reaches it).

::

    world = house_bedside(Path("out/scenes_household/scenes/flat_000_p0"), Path("out/task"),
                          Path("out/scenes_household/catalog/default/generated.json"), scene_id="flat_000_p0")
    inst = sample_task("set_alarm_clock", world, seed=1)
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.demos.house_room import (HouseRoom, base_free, obstacles, overlaps, read_room, room_fields, room_frame,
                                     spawn_in, top_surface, write_task_scene)
from stages.demos.packages import Placed

log = logging.getLogger(__name__)

CLOCK_REACH = 0.30  # the base's x at most this far [m] from the nightstand top's middle
CLOCK_EDGE = 0.02   # the parked clock's footprint stays this far [m] inside the top's ends
MOVABLE = ("trash_can",)  # floor things the task scene cuts (the make_bed rule puts a can beside the bed:
                          # before the nightstand it stopped the base, drive_timeout)
CHASSIS = (0.60, 0.50)  # the mobile base's chassis (length along its heading, width) [m] (mobile_panda.toml)
BASE_GAP = 0.20     # the chassis's front stops this far [m] before the nightstand (the counter's 0.08
                    # left the hand too near the arm's shoulder for the 0.6 m high knob: ik_unreachable)


@dataclass(frozen=True, kw_only=True, eq=False)
class HouseBedside(HouseRoom):
    """A :class:`~stages.demos.house_room.HouseRoom` whose work surface is a bedroom's nightstand
    with the alarm clock (see the module doc); base_x: the base pose's x before it [m]; base_gap:
    its chassis's front this far [m] before the nightstand."""

    base_x: float
    base_gap: float = BASE_GAP


def _turn(rs, stand: dict, clock: dict, k: int):
    """The house turned so that the nightstand's side ``k`` (0: its front, its local +X; then a
    quarter turn each) faces -Y: (frame, furniture, nightstand, top, top z, clock, base goal), or a
    one-line reason why not."""
    from stages.demos.counter import COUNTER_STAGE, facing_north_goal
    from stages.demos.kitchen import CLOCK_FRONT

    rf = room_frame(rs.house, rs.room, -math.pi / 2 - stand["yaw"] + k * math.pi / 2)
    furniture = {n: rf.placed(r, rs.asset(r)) for n, r in rs.mine.items()
                 if r["support"] is None and r["category"] not in MOVABLE}
    sp = furniture[stand["name"]]
    top, z = top_surface(sp)
    ca = rs.asset(clock)
    # the clock faces north (yaw pi/2): its depth (local X) along Y, its width (local Y) along X
    half_w = 0.5 * (ca.hi[1] - ca.lo[1])
    lo_x, hi_x = top[0] + CLOCK_EDGE + half_w, top[2] - CLOCK_EDGE - half_w
    if hi_x < lo_x or ca.hi[0] - ca.lo[0] > top[3] - top[1] - CLOCK_FRONT:
        return "the clock does not fit on the top"
    front = sp.footprint()[1]
    mid = 0.5 * (top[0] + top[2])
    x0, y0, x1, y1 = rf.area
    boxes = obstacles(p for n, p in furniture.items())
    others = list(rf.walls) + obstacles(p for n, p in furniture.items() if n != stand["name"])
    for d in sorted(np.arange(-CLOCK_REACH, CLOCK_REACH + 1e-9, 0.05), key=abs):
        goal = facing_north_goal(front, float(mid + d), BASE_GAP)
        # the chassis's way in from the staging pose, COUNTER_STAGE back (a trash can before the
        # nightstand stopped the base: drive_timeout)
        way = (goal[0] - CHASSIS[1] / 2, goal[1] - COUNTER_STAGE - CHASSIS[0] / 2, goal[0] + CHASSIS[1] / 2,
               goal[1] + CHASSIS[0] / 2)
        if (x0 < goal[0] < x1 and y0 < goal[1] < y1 and base_free(goal, rf.walls, boxes)
                and not any(overlaps(way, b, 0.03) for b in others)):
            break
    else:
        return f"no free floor for the base within {CLOCK_REACH} m of the top's middle"
    cx = float(min(max(goal[0], lo_x), hi_x))
    cp = Placed(f"Objects/{clock['name']}", ca, (cx, float(top[1] + CLOCK_FRONT), float(z + 0.002)), math.pi / 2)
    return rf, furniture, sp, top, z, cp, goal


def house_bedside(scene_dir: Path, out_dir: Path, generated_json: Path, *, scene_id: str,
                  room: str | None = None) -> HouseBedside:
    """The alarm clock's task world in the bedroom ``room`` (default: the house's first populated
    bedroom) of the scene in ``scene_dir``, written to ``out_dir/scene.usda`` (see the module doc).
    ItemError names what the room lacks or why no side of the nightstand works."""
    from stages.demos.experts import COUNTER_STAGE

    scene_dir, out_dir = Path(scene_dir), Path(out_dir)
    rs = read_room(scene_dir, generated_json, "bedroom", room)
    stands = {n for n, r in rs.mine.items() if r["category"] == "nightstand" and r["support"] is None}
    clock = rs.one("alarm_clock", lambda r: r["support"] in stands)
    if clock is None:
        raise ItemError(f"{scene_dir}: bedroom {rs.room} lacks an alarm clock on a nightstand")
    stand = rs.mine[clock["support"]]
    tried = {}
    for k in range(4):
        got = _turn(rs, stand, clock, k)
        if not isinstance(got, str):
            break
        tried[k] = got
    else:
        raise ItemError(f"{scene_dir}: bedroom {rs.room}: no side of the nightstand works ("
                        + "; ".join(f"{90 * k} deg from its front: {why}" for k, why in tried.items()) + ")")
    rf, furniture, sp, top, z, cp, goal = got
    pl: dict[str, Placed] = {"clock": cp, "nightstand": sp, "counter": sp, "table": sp}
    cut = rs.other_rooms_objects() + [n for n, r in rs.mine.items() if (r["support"] == stand["name"] and n != clock["name"])
                                      or (r["support"] is None and r["category"] in MOVABLE)]
    usd = out_dir / "scene.usda"
    write_task_scene(usd, rs.house, rf.frame, cut, None)
    w = HouseBedside(
        usd=usd, scene_id=scene_id, placed=pl, furniture=furniture, cut=tuple(sorted(cut)),
        anchor=(float(goal[0]), float(goal[1] - COUNTER_STAGE)), base_x=float(goal[0]),
        **room_fields(rs, rf, top, z, (float(cp.position[0]), float(cp.position[1]))))
    spawn_in(w)
    log.info("house bedside %s (%s, %s): %s, turned %d deg from the nightstand's front; cut %d", scene_id,
             scene_dir.name, rs.room, w.asset_ids(), 90 * k, len(cut))
    return w
