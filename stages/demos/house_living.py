"""A generated house's living room as the task world (issue 16): the scene stage's output turned into
the facts the living-room skills read, on the shared house-room machinery
(:mod:`stages.demos.house_room`).

:func:`house_living` picks the living room, its work surface (the coffee table, else a dining table)
with a piece of crumpled paper on it that the hand grasps, the trash can, and where the room has them
the bookshelf (the household rules place them:
``stages/scene/rules/household_tasks.toml``). It turns the house by the multiple of 90 deg about +Z
that leaves the table's side facing world -Y with free floor for the robot's base before its west
end (the experts work at a table from its south side, facing +Y; the coffee table's sofa side is
not that one), the table's long side first, and moves the trash can onto the floor off the table's
west end (as the task kitchen parks it: :data:`CAN_GAP` off the table's footprint, 0.15 m north of
the top's front), where it stands clear of the walls and the floor furniture. The
task scene deactivates the other rooms' objects, the table's objects other than the task's paper,
books, pitcher and cup and the bookshelf's own books (its boards
take organize books' books); the room's first two books 20-46 mm thick (the household rules put two
on the table) become roles "book_1", "book_2", which every living-room episode stands spine up on
the table's near band east of the paper (:func:`stages.demos.skill_books.book_setup`: a book left
lying at the table's west end lay where the paper is set and the grasp missed); the room's floor furniture (the moved
can with it) and the floor's walls are the planner's obstacles; the robot starts inside the room,
where the planner finds a path to the staging pose before the paper (``anchor``; a pocket behind
the sofa or the TV stand is no start: flat_000 seeds 4 and 6 started there, no_path). With
``drink=True`` (serve drinks: :func:`stages.demos.multistage.needs_drink`), where the
table holds a pitcher whose handle the hand grasps (:func:`stages.demos.drink.pitcher_ok`) and
a cup, they become roles "pitcher" and "cup" and the task scene adds the drink (serve drinks:
:data:`stages.demos.drink.DRINK_COUNT` spheres, ``/World/Drink/D<k>``, in the pitcher; a
sublayer ``drink.usda`` beside the task scene).

Facts (task frame, Z up, metres, radians): ``placed`` roles "table", "paper", "trash_can" and
where present "bookshelf" and (with it) "book_1", "book_2", "pitcher" and "cup" (with ``drink``: the
spheres' body paths); ``table_rect`` / ``table_z``: the table's top; ``shelves``: the
bookshelf's boards inside it as (xmin, ymin, xmax, ymax, z, clear height) [m]. The kitchen-only
facts (counter, microwave cavity, button) are the table's top or zero.

::

    world = house_living(Path("out/scenes_household/scenes/flat_000_p0"), Path("out/task"),
                         Path("out/scenes_household/catalog/default/generated.json"), scene_id="flat_000_p0")
    inst = sample_task("clean_table_living", world, seed=1)
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

from pipeline.types import ItemError
from stages.demos.house_room import (HouseRoom, base_free, obstacles, overlaps, read_room, room_fields, room_frame,
                                     spawn_in, top_surface, write_task_scene)
from stages.demos.packages import Placed
from stages.demos.skill_trash import MAX_PAPER_RADIUS, PAPER_AT

log = logging.getLogger(__name__)

TABLE_CATEGORIES = ("coffee_table", "dining_table")
CAN_CLEAR = 0.03      # the moved can keeps this far [m] from walls and floor furniture
CAN_GAP = 0.04        # the can's east side this far [m] off the table's west end (its legs and apron:
                      # a coffee table's top surface lies up to 0.2 m inside its footprint)
CAN_NORTH = 0.15      # the can's centre this far [m] north of the table's front (the task kitchen's park)


@dataclass(frozen=True, kw_only=True, eq=False)
class HouseLiving(HouseRoom):
    """A :class:`~stages.demos.house_room.HouseRoom` whose room is a living room (see the module
    doc): moved is the trash can the task scene moved off the table's west end; shelves: the
    bookshelf's boards (xmin, ymin, xmax, ymax, z, clear height) [m], empty without a bookshelf."""

    shelves: tuple[tuple[float, float, float, float, float, float], ...] = field(default=())
    VIEW_ROLES: ClassVar[tuple[str, ...]] = ("bookshelf", "trash_can")  # organize_books', clean_table's


def _shelves(shelf: Placed) -> tuple:
    """The bookshelf's inside boards (task frame)."""
    out = []
    for s in sorted((s for s in shelf.info.get("surfaces", []) if s["inside"]), key=lambda s: s["z"]):
        out.append((*shelf.rect(s["lo"], s["hi"]), float(shelf.position[2] + s["z"]),
                    float(s.get("clear_height", 0.0))))
    return tuple(out)


def _books(rs, table: str) -> list[dict]:
    """The room's first :data:`~stages.demos.skill_books.BOOKS` books a hand grasps across their
    thickness (:data:`~stages.demos.skill_books.THICKNESS`), those on the table first (organize
    books stands them on it; none when the room has fewer)."""
    from stages.demos.skill_books import BOOKS, THICKNESS

    def fits(r: dict) -> bool:
        a = rs.asset(r)
        return THICKNESS[0] - 1e-6 <= a.hi[2] - a.lo[2] <= THICKNESS[1] + 1e-6

    found = sorted((r for r in rs.mine.values() if r["category"] == "book" and r["support"] is not None and fits(r)),
                   key=lambda r: (r["support"] != table, r["name"]))
    return found[:BOOKS] if len(found) >= BOOKS else []


def _drink(rs, table: str) -> tuple[dict, dict] | None:
    """The table's pitcher whose handle the hand grasps (:func:`stages.demos.drink.pitcher_ok`)
    and its first cup, as scene records; None when it lacks either."""
    from stages.demos.drink import pitcher_ok

    pitcher = rs.one("pitcher", lambda r: r["support"] == table and pitcher_ok(rs.asset(r)))
    cup = rs.one("cup", lambda r: r["support"] == table)
    return (pitcher, cup) if pitcher is not None and cup is not None else None


def _write_drink(out_dir: Path, pitcher: dict, asset) -> tuple[Path, tuple[str, ...]]:
    """The drink's layer ``out_dir/drink.usda`` (:func:`stages.demos.drink.write_drink`): the
    spheres in the pitcher of scene record ``pitcher`` (house frame: the task scene moves ``/World``)
    and their body paths."""
    from stages.demos.drink import DRINK_COUNT, drink_world, write_drink
    from stages.simulate.demo_scene import _Writer

    bodies = tuple(f"/World/Drink/D{k:02d}" for k in range(DRINK_COUNT))
    pts = drink_world((*pitcher["position"], pitcher["yaw"]), asset.params, DRINK_COUNT)
    w = _Writer()
    write_drink(w, dict(zip(bodies, pts, strict=True)))
    path = out_dir / "drink.usda"
    out_dir.mkdir(parents=True, exist_ok=True)
    w.write(path, "World")
    return path, bodies


def house_living(scene_dir: Path, out_dir: Path, generated_json: Path, *, scene_id: str,
                 room: str | None = None, drink: bool = False) -> HouseLiving:
    """The task world of the living room ``room`` (default: the house's first populated living room)
    of the scene in ``scene_dir``, written to ``out_dir/scene.usda`` (see the module doc).
    ItemError names what the room lacks or why no side of its table works."""
    from stages.demos.counter import facing_north_goal
    from stages.demos.experts import COUNTER_STAGE

    scene_dir, out_dir = Path(scene_dir), Path(out_dir)
    rs = read_room(scene_dir, generated_json, "living_room", room)

    def paper_on(t: dict) -> dict | None:
        return rs.one("crumpled_paper", lambda r: r["support"] == t["name"]
                      and float(rs.asset(r).params.get("radius", 1.0)) <= MAX_PAPER_RADIUS)

    tables = [t for c in TABLE_CATEGORIES for t in rs.mine.values() if t["category"] == c and t["support"] is None]
    table = next((t for t in tables if paper_on(t)), tables[0] if tables else None)
    paper = paper_on(table) if table else None
    can = rs.one("trash_can", lambda r: r["support"] is None)
    if table is None or paper is None or can is None:
        lack = [w for w, r in (("a coffee or dining table", table),
                               (f"crumpled paper under {MAX_PAPER_RADIUS * 2000:.0f} mm on the table", paper),
                               ("a trash can", can)) if r is None]
        raise ItemError(f"{scene_dir}: living room {rs.room} lacks {', '.join(lack)}")
    shelf = rs.one("bookshelf", lambda r: r["support"] is None)
    books = _books(rs, table["name"])
    drink = _drink(rs, table["name"]) if drink else None
    can_asset = rs.asset(can)

    # the turn: the table's long side along X first; the first whose south side has room
    ta = rs.asset(table)
    long_x = (ta.hi[0] - ta.lo[0]) >= (ta.hi[1] - ta.lo[1])
    turns = sorted(range(4), key=lambda k: (k % 2 == 0) != long_x)
    tried = []
    for k in turns:
        rf = room_frame(rs.house, rs.room, -table["yaw"] + k * math.pi / 2)
        furniture = {n: rf.placed(r, rs.asset(r)) for n, r in rs.mine.items() if r["support"] is None}
        tp = furniture[table["name"]]
        rect, z = top_surface(tp)
        cx = tp.footprint()[0] - CAN_GAP - can_asset.hi[0]
        cp = Placed(f"Objects/{can['name']}", can_asset, (float(cx), float(rect[1] + CAN_NORTH),
                                                          float(can["position"][2])), 0.0)
        fp = cp.footprint()
        x0, y0, x1, y1 = rf.area
        others = [p for n, p in furniture.items() if n != can["name"]]
        inside = (x0 + CAN_CLEAR <= fp[0] and fp[2] <= x1 - CAN_CLEAR
                  and y0 + CAN_CLEAR <= fp[1] and fp[3] <= y1 - CAN_CLEAR)
        clash = [b for b in list(rf.walls) + obstacles(others) if overlaps(fp, b, CAN_CLEAR)]
        goal = facing_north_goal(rect[1], rect[0] + PAPER_AT[0])
        ok_base = x0 < goal[0] < x1 and y0 < goal[1] < y1 and base_free(goal, rf.walls, obstacles(others + [cp]))
        if inside and not clash and ok_base:
            break
        tried.append(f"{math.degrees(rf.frame[2]):.0f} deg: " + ("the can's place is off the floor" if not inside else
                                                                 "the can's place is taken" if clash else
                                                                 "no room for the base before the table"))
    else:
        raise ItemError(f"{scene_dir}: living room {rs.room}: no side of the table works ({'; '.join(tried)})")

    furniture[can["name"]] = cp
    pl: dict[str, Placed] = {"table": tp, "trash_can": cp, "paper": rf.placed(paper, rs.asset(paper))}
    if shelf is not None:
        pl["bookshelf"] = furniture[shelf["name"]]
        pl.update({f"book_{k + 1}": rf.placed(b, rs.asset(b)) for k, b in enumerate(books)})
    keep = {paper["name"]} | ({b["name"] for b in books} if shelf is not None else set())
    layers, bodies = [], ()
    if drink is not None:
        pl.update(pitcher=rf.placed(drink[0], rs.asset(drink[0])), cup=rf.placed(drink[1], rs.asset(drink[1])))
        keep |= {drink[0]["name"], drink[1]["name"]}
        layer, bodies = _write_drink(out_dir, drink[0], rs.asset(drink[0]))
        layers.append(layer)
    cut = rs.other_rooms_objects() + [n for n, r in rs.mine.items() if n not in keep and r["support"] is not None
                                      and r["support"] in (table["name"], shelf["name"] if shelf else None)]
    hxy = rf.to_house(cp.position[:2])
    moved = (can["name"], (float(hxy[0]), float(hxy[1]), float(can["position"][2])))
    usd = out_dir / "scene.usda"
    write_task_scene(usd, rs.house, rf.frame, cut, moved, layers=layers)
    spot = (rect[0] + PAPER_AT[0], rect[1] + PAPER_AT[1])
    w = HouseLiving(
        usd=usd, scene_id=scene_id, placed=pl, furniture=furniture, cut=tuple(sorted(cut)), moved=moved,
        anchor=(float(goal[0]), float(goal[1] - COUNTER_STAGE)),
        shelves=_shelves(pl["bookshelf"]) if shelf is not None else (), drink=bodies,
        **room_fields(rs, rf, rect, z, spot))
    spawn_in(w)
    log.info("house living room %s (%s, %s): %s; cut %d", scene_id, scene_dir.name, rs.room, w.asset_ids(), len(cut))
    return w
