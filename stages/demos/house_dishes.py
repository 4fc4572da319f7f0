"""Clean dishes in a generated house's kitchen (issue 16): where the plate, the sponge and the dish
rack the household rules put on the counter (``stages/scene/rules/household_tasks.toml``) stand in
the kitchen task world (:func:`stages.demos.house.house_kitchen` with ``dishes=True``).

:func:`dish_layout` lays them out in a row along the front of the longest counter top (the gaps are
:mod:`stages.demos.skill_rack`'s): the rack (tine rows along world Y, its front ``RACK_FRONT`` behind
the counter's front edge), ``RACK_GAP`` beside it the plate (its near rim ``PLATE_BACK`` behind the
edge: the place stage reaches behind its far rim), ``SPONGE_GAP`` beyond the plate's rim the sponge;
the row faces either way, at the first place along the top (from its middle out) where the base's
poses before the plate and sponge (the wipe) and before the plate and rack (the place) are free
(:func:`~stages.demos.house_room.base_free`). The task scene cuts every other object on the counter,
the microwave included (clean dishes does not use it); the mug is parked at the back of the top
behind the sponge.

Frame: the task frame, Z up, metres, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.types import ItemError
from stages.demos.packages import Placed
from stages.demos.skill_rack import PLATE_BACK, RACK_GAP, SPONGE_GAP

SPONGE_BACK = 0.12  # the sponge's centre behind the counter's front edge [m]
MUG_BACK = 0.07     # the parked mug's centre before the counter top's back edge [m]
END_MARGIN = 0.03   # the row stays this far [m] inside the top's ends


@dataclass(frozen=True)
class DishLayout:
    """placed: the plate, sponge, rack and mug in the task frame (role -> Placed); cut: the counter's
    other instances; top: the counter top's rectangle (xmin, ymin, xmax, ymax) [m] and z: its height
    [m] (the world's table facts for the wipe)."""

    placed: dict
    cut: list
    top: tuple[float, float, float, float]
    z: float


def dish_layout(rs, rf, cnt: Placed, counter_rec: dict, mug_rec: dict, walls, boxes, source) -> DishLayout:
    """The clean-dishes layout of the kitchen of ``rs`` (:class:`~stages.demos.house_room.RoomScene`,
    turned by ``rf``) on counter ``cnt`` (record ``counter_rec``), see the module doc; ``walls`` /
    ``boxes``: the planner's obstacles (task frame). ItemError (naming ``source``) when the kitchen
    lacks a plate, a sponge the hand grasps across or a dish rack, or no top has room for the row."""
    from stages.demos.counter import facing_north_goal
    from stages.demos.house_room import base_free
    from stages.demos.skill_rack import RACK_FRONT, rack_box
    from stages.demos.skill_wipe import MAX_SPONGE_WIDTH

    plate = rs.one("plate")
    sponge = rs.one("sponge", lambda r: float(rs.asset(r).params.get("width", 1.0)) <= MAX_SPONGE_WIDTH)
    rack = rs.one("dish_rack")
    lack = [w for w, r in (("a plate", plate), (f"a sponge narrower than {MAX_SPONGE_WIDTH * 1000:.0f} mm", sponge),
                           ("a dish rack", rack)) if r is None]
    if lack:
        raise ItemError(f"{source}: kitchen {rs.room} lacks {', '.join(lack)} for clean dishes")
    pa, sa, ra = rs.asset(plate), rs.asset(sponge), rs.asset(rack)
    r = float(pa.params["radius"])
    hx, hy, _ = rack_box(ra.params)
    s_half = 0.5 * float(sa.params["length"])
    tops = sorted((s for s in cnt.info.get("surfaces", []) if not s["inside"] and s["link"] == "base"),
                  key=lambda s: -(cnt.rect(s["lo"], s["hi"])[2] - cnt.rect(s["lo"], s["hi"])[0]))
    left, right = hx + RACK_GAP + r, r + SPONGE_GAP + s_half  # the row's reach from the plate's centre
    for seg in tops:
        x0, y0, x1, y1 = cnt.rect(seg["lo"], seg["hi"])
        z = float(cnt.position[2] + seg["z"])
        if y1 - y0 < PLATE_BACK + 2 * r + 0.02:
            continue
        mid = 0.5 * (x0 + x1)
        cands = []
        for side in (1.0, -1.0):  # +1: the rack west of the plate, the sponge east
            lo, hi = x0 + END_MARGIN + (left if side > 0 else right), x1 - END_MARGIN - (right if side > 0 else left)
            cands += [(float(px), side) for px in np.arange(lo, hi + 1e-9, 0.02)]
        for px, side in sorted(cands, key=lambda c: abs(c[0] - mid)):
            rx, sx = px - side * (hx + RACK_GAP + r), px + side * (r + SPONGE_GAP)
            if all(base_free(facing_north_goal(y0, x), walls, boxes) for x in (0.5 * (px + sx), 0.5 * (px + rx))):
                break
        else:
            continue
        def at(rec, a, xy, yaw=0.0) -> Placed:
            p = rf.placed(rec, a)
            return Placed(p.name, a, (float(xy[0]), float(xy[1]), z + 0.002), yaw)

        placed = {"plate": at(plate, pa, (px, y0 + PLATE_BACK + r)),
                  "sponge": at(sponge, sa, (sx, y0 + SPONGE_BACK)),
                  "dish_rack": at(rack, ra, (rx, y0 + RACK_FRONT + hy)),
                  "mug": at(mug_rec, rs.asset(mug_rec), (sx, y1 - MUG_BACK))}
        keep = {plate["name"], sponge["name"], rack["name"], mug_rec["name"]}
        cut = [n for n, q in rs.mine.items() if q["support"] == counter_rec["name"] and n not in keep]
        return DishLayout(placed=placed, cut=cut, top=(x0, y0, x1, y1), z=z)
    raise ItemError(f"{source}: no counter top has room for the dish rack, the plate and the sponge "
                    f"in a row with the base free before them")
