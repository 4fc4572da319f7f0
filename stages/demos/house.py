"""A generated house's kitchen as the task world (issue 16): the scene stage's output (``scene.usda``,
``scene.json``, the layout's ``floorplan.json``) turned into the room facts the experts and samplers
read (:class:`~stages.demos.kitchen.KitchenWorld`).

:func:`house_kitchen` picks the kitchen room, its counter, the microwave on it, the fridge, the oven
and a mug the hand can grasp (the household rules place them:
``stages/scene/rules/household_tasks.toml``), and writes a task scene (``scene.usda`` in
``out_dir``) that sublayers the house's scene and moves the whole house by one rigid motion about
+Z (a multiple of 90 deg, the walls stay axis-aligned) so that the counter faces world -Y, as the
experts assume (they work at the counter from its south side, facing +Y), with the kitchen room's
corner at the origin. Where the microwave stands too near the end of its counter top for the
mug's spot beside it (on the side of its door handle: the open door stands on the hinge side), the
task scene slides it along the top. The task scene deactivates the objects of the other rooms (their furniture
and the walls stay, static) and the objects on the counter that stand where the task works (the
mug's spot beside the microwave, on the side of its door handle). Floor-standing furniture of the
kitchen and every wall of its floor are the planner's obstacles; the robot plans and starts inside
the kitchen room. What is not kitchen-specific (reading a room's records, the turn into the task
frame, the task scene layer, obstacles and start area) is :mod:`stages.demos.house_room`, shared
with the living room (:mod:`stages.demos.house_living`).

Frame: the task frame, Z up, metres, radians: ``p_task = Rz(theta) p_house + t``
(:attr:`HouseKitchen.frame` = (tx, ty, theta)).

::

    world = house_kitchen(Path("out/scenes_household/scenes/flat_000_p0"), Path("out/task"),
                          Path("out/scenes_household/catalog/default/generated.json"), scene_id="flat_000_p0")
    inst = sample_task("heat_food", world, seed=1)
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.demos.house_room import (HouseRoom, floor_plan_of, obstacles, read_room,
                                     room_frame, rot2, spawn_in, wrap, write_task_scene)
from stages.demos.kitchen import GRASP_MAX_DIAMETER, SOUTH, _cavity, _mug_ok
from stages.demos.packages import CatalogAsset, Placed, link_bounds

__all__ = ["HouseKitchen", "floor_plan_of", "house_kitchen"]

log = logging.getLogger(__name__)

FURNITURE_ROLES = {"kitchen_counter": "counter", "fridge": "fridge", "oven": "oven"}
SPOT_BESIDE = 0.17      # mug spot: from the microwave's side to the spot [m] (as the task kitchen)
SPOT_BACK = 0.07        # mug spot: behind the counter's front edge [m]
CLEAR_HALF = 0.15       # counter objects from the microwave to this beyond the spot are cut away [m]


class HouseKitchen(HouseRoom):
    """A :class:`~stages.demos.house_room.HouseRoom` whose room is a kitchen (see the module doc):
    moved is the microwave the task scene slid along the counter top to make room for the mug's
    spot, else None."""

    VIEW_ROLES = ("fridge",)  # store_food's fridge in the third-person view


def _reachable_y(cnt: Placed, seg: dict, ma: CatalogAsset, side: float, span: tuple[float, float], y0: float,
                 walls, boxes) -> float | None:
    """The microwave's position along the counter top ``seg`` (counter frame y, within ``span``) nearest
    ``y0`` from which the experts' base poses before the counter are free (the staging pose, COUNTER_STAGE
    behind the pose at the counter, of the pick into the microwave and of the button press; the base
    inflated by its radius as the planner does), None if there is none."""
    from stages.demos.driver import ROBOT_RADIUS
    from stages.demos.experts import COUNTER_STAGE, facing_north_goal
    from stages.demos.planner import NavGrid

    xs = [b[0] for b in walls] + [b[2] for b in walls]
    ys = [b[1] for b in walls] + [b[3] for b in walls]
    grid = NavGrid.from_boxes((min(xs), min(ys), max(xs), max(ys)), np.asarray(list(walls) + list(boxes), float))
    blocked = grid.inflate(ROBOT_RADIUS)
    front = cnt.footprint()[1]
    cav = _cavity(ma)
    blo, bhi = link_bounds(ma.usd, "button")

    def free(ly: float) -> bool:
        x = float(cnt.to_world((seg["hi"][0], ly, 0.0))[0])
        gx, gy, _ = facing_north_goal(front, x)
        cells = [grid.cell_of(gx + dx, gy - COUNTER_STAGE) for dx in (-0.05, 0.0, 0.05)]
        return all(0 <= iy < blocked.shape[0] and 0 <= ix < blocked.shape[1] and not blocked[iy, ix]
                   for iy, ix in cells)

    for y in sorted(np.arange(span[0], span[1] + 1e-9, 0.02).tolist() + [y0], key=lambda v: abs(v - y0)):
        spot = y + (ma.hi[1] + SPOT_BESIDE if side > 0 else ma.lo[1] - SPOT_BESIDE)
        pick = 0.5 * (spot + y + 0.5 * (cav["lo"][1] + cav["hi"][1]))
        if free(pick) and free(y + 0.5 * (blo[1] + bhi[1])):
            return float(y)
    return None


def house_kitchen(scene_dir: Path, out_dir: Path, generated_json: Path, *, scene_id: str,
                  room: str | None = None, dishes: bool = False) -> HouseKitchen:
    """The task world of the kitchen ``room`` (default: the house's first populated kitchen) of the
    scene in ``scene_dir`` (``scene.usda`` + ``scene.json``), written to ``out_dir/scene.usda``
    (see the module doc). ``generated_json``: the default catalog's records (surfaces, handles,
    parameters). ``dishes``: the clean-dishes world (:mod:`stages.demos.house_dishes`: plate,
    sponge and dish rack in a row on the counter, its other objects cut). ItemError names what the
    kitchen lacks."""
    scene_dir, out_dir = Path(scene_dir), Path(out_dir)
    rs = read_room(scene_dir, generated_json, "kitchen", room)
    house, room, recs, mine, info, one = rs.house, rs.room, rs.recs, rs.mine, rs.info, rs.one

    def _asset(rec: dict, _info=None) -> CatalogAsset:
        return rs.asset(rec)

    counter = one("kitchen_counter")
    micro = one("microwave", lambda r: r["support"] == (counter or {}).get("name"))
    mug = one("mug", lambda r: _mug_ok(_asset(r, info)))
    if counter is None or micro is None or mug is None:
        lack = [w for w, r in (("a kitchen counter", counter), ("a microwave on the counter", micro),
                               (f"a mug narrower than {GRASP_MAX_DIAMETER * 1000:.0f} mm", mug)) if r is None]
        raise ItemError(f"{scene_dir}: kitchen {room} lacks {', '.join(lack)}")
    if abs(wrap(micro["yaw"] - counter["yaw"])) > 0.05:
        raise ItemError(f"{scene_dir}: the microwave does not face the counter's front")

    # the motion: the counter's front (asset +X) to world -Y, the room's corner to the origin
    rf = room_frame(house, room, SOUTH - counter["yaw"])
    frame, size, walls, t, theta = rf.frame, rf.size, rf.walls, rf.t, rf.frame[2]

    def placed(rec: dict) -> Placed:
        return rf.placed(rec, rs.asset(rec))

    furniture = {n: placed(r) for n, r in mine.items() if r["support"] is None}
    pl: dict[str, Placed] = {"counter": furniture[counter["name"]], "microwave": placed(micro),
                             "mug": placed(mug)}
    for cat, role in FURNITURE_ROLES.items():
        r = one(cat)
        if r is not None and role not in pl:
            pl[role] = furniture[r["name"]]
    cnt, mwp = pl["counter"], pl["microwave"]

    # the counter's top segment under the microwave (counter frame), else the widest one with room
    local = np.asarray(mwp.position) - np.asarray(cnt.position)
    mloc = rot2(-cnt.yaw) @ local[:2]
    ma = mwp.asset
    handle = [h for h in ma.info.get("handles", []) if h["link"] == "door"]
    side = 1.0 if not handle or handle[0]["center"][1] >= 0 else -1.0
    need = ma.hi[1] + SPOT_BESIDE + 0.05 if side > 0 else ma.lo[1] - SPOT_BESIDE - 0.05

    def span(s: dict) -> tuple[float, float]:
        """Where the microwave's origin may stand along the top segment ``s`` (y, counter frame) [m]."""
        lo, hi = s["lo"][1] - ma.lo[1] + 0.01, s["hi"][1] - ma.hi[1] - 0.01
        return (lo, min(hi, s["hi"][1] - need)) if side > 0 else (max(lo, s["lo"][1] - need), hi)

    tops = sorted((s for s in cnt.info.get("surfaces", []) if not s["inside"] and s["link"] == "base"),
                  key=lambda s: (not s["lo"][1] - 0.01 <= mloc[1] <= s["hi"][1] + 0.01,
                                 s["lo"][1] - s["hi"][1]))
    tops = [s for s in tops if span(s)[0] <= span(s)[1]]
    if not tops:
        raise ItemError(f"{scene_dir}: no counter top has room for the microwave and the mug beside it "
                        f"on its handle side")
    seg = tops[0]
    lo_y, hi_y = span(seg)
    my = _reachable_y(cnt, seg, ma, side, (lo_y, hi_y), float(np.clip(mloc[1], lo_y, hi_y)), walls,
                      obstacles(furniture.values()))
    if my is None:
        raise ItemError(f"{scene_dir}: the robot's base cannot stand before the counter where the microwave "
                        f"and the mug's spot are (furniture or a wall beside it)")
    moved = None
    if abs(my - mloc[1]) > 1e-9:
        mloc = np.array([mloc[0], my])
        xy = np.asarray(cnt.position[:2]) + rot2(cnt.yaw) @ mloc
        mwp = pl["microwave"] = Placed(mwp.name, ma, (float(xy[0]), float(xy[1]), mwp.position[2]), mwp.yaw)
        hxy = rot2(-theta) @ (xy - t)
        moved = (micro["name"], (float(hxy[0]), float(hxy[1]), float(micro["position"][2])))
    spot_y = mloc[1] + (ma.hi[1] + SPOT_BESIDE if side > 0 else ma.lo[1] - SPOT_BESIDE)
    counter_z = float(cnt.position[2] + seg["z"])
    spot = cnt.to_world((seg["hi"][0] - SPOT_BACK, spot_y, 0.0))[:2]

    # cut away: the other rooms' objects; the counter's objects where the mug is set down and carried
    cut = rs.other_rooms_objects()
    y_lo = spot_y - CLEAR_HALF if side < 0 else mloc[1] + ma.lo[1] - 0.02
    y_hi = spot_y + CLEAR_HALF if side > 0 else mloc[1] + ma.hi[1] + 0.02
    for n, r in mine.items():
        if r["support"] != counter["name"] or n in (micro["name"], mug["name"]):
            continue
        a = _asset(r, info)
        p = placed(r)
        fp = np.array([p.to_world((x, y, 0.0))[:2] for x in (a.lo[0], a.hi[0]) for y in (a.lo[1], a.hi[1])])
        cl = (fp - np.asarray(cnt.position[:2])) @ rot2(cnt.yaw)  # counter frame (row vectors: R^T)
        if cl[:, 1].max() > y_lo and cl[:, 1].min() < y_hi:
            cut.append(n)

    # the mug's support: the table of the table tasks' facts (its start pose for the non-pick tasks)
    sup = recs.get(mug["support"] or "")
    table = furniture.get(sup["name"]) if sup else None
    if table is None or table is cnt:
        table_z, table_rect = counter_z, cnt.rect(seg["lo"], seg["hi"])
    else:
        ttop = max((s for s in table.info.get("surfaces", []) if not s["inside"]), key=lambda s: s["z"])
        table_z, table_rect = float(table.position[2] + ttop["z"]), table.rect(ttop["lo"], ttop["hi"])
        pl["table"] = table
    # the mug's rest pose in the task frame, on its support (the non-pick tasks' start)
    m = pl["mug"]
    pl["mug"] = Placed(m.name, m.asset, (*m.position[:2], table_z + 0.002), m.yaw)

    if dishes:  # the plate, sponge and rack in a row on the counter (its other objects cut away)
        from stages.demos.house_dishes import dish_layout

        lay = dish_layout(rs, rf, cnt, counter, mug, walls, obstacles(furniture.values()), scene_dir)
        pl.update(lay.placed)
        keep = {p.name.rsplit("/", 1)[-1] for p in lay.placed.values()}
        cut = [n for n in dict.fromkeys(cut + lay.cut) if n not in keep]
        table_z, table_rect = lay.z, lay.top
        moved = None if moved and moved[0] in cut else moved  # (the microwave cut)
    cav = _cavity(ma)
    blo, bhi = link_bounds(ma.usd, "button")
    button = mwp.to_world(np.array([bhi[0], (blo[1] + bhi[1]) / 2, (blo[2] + bhi[2]) / 2]))
    usd = out_dir / "scene.usda"
    write_task_scene(usd, house, frame, cut, moved)
    area = (0.0, 0.0, *size)
    w = HouseKitchen(
        usd=usd, scene_id=scene_id, size=size, wall_thickness=0.0, placed=pl, spawn=(0.0, 0.0, 0.0),
        counter_z=counter_z, counter_rect=cnt.rect(seg["lo"], seg["hi"]),
        counter_spot=(float(spot[0]), float(spot[1])), table_z=table_z, table_rect=table_rect,
        cavity=mwp.rect(cav["lo"], cav["hi"]), cavity_z=float(mwp.position[2] + cav["z"]),
        cavity_height=float(cav["clear_height"]), button=tuple(float(v) for v in button),
        button_travel=float(ma.params.get("button_travel", 0.005)),
        button_push=tuple(float(v) for v in mwp.dir_to_world((-1.0, 0.0, 0.0))),
        mug_radius=float(m.asset.params["radius"]), mug_height=float(m.asset.params["height"]),
        bowl_radius=0.0, materials={}, look=None, house=house.resolve(), room=room, frame=frame, area=area,
        walls=walls, furniture=furniture, cut=tuple(sorted(cut)), moved=moved)
    spawn_in(w)
    log.info("house kitchen %s (%s, %s): %s; cut %d", scene_id, scene_dir.name, room, w.asset_ids(), len(cut))
    return w
