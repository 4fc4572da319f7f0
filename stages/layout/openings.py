"""Walls, doors, windows and staircases of a sampled floor (integer centimeters): walls from the
room outlines, doors that join the rooms (and one to the outside), windows on exterior walls, the
staircase geometry. Used by the planner (``stages.layout.plan``); randomness only from the
attempt's generator (``_Draft.rng``).
"""

from __future__ import annotations

import math

import numpy as np

from asset_catalog.annotations import RoomType
from stages.layout.geom2d import Point, Rect, make_rect, snap
from stages.layout.model import (
    DOOR_DEPTH, DOOR_MARGIN, DOOR_SPACING, Edge, LayoutError, Opening, PlanRejected, RAIL_T, RISE, Room, STEP, Stair,
    WINDOW_MARGIN, Wall, _Draft, _merge_intervals, _on_boundary, _uniform_int,
)
from stages.layout.spec import ROOM_RULES, LayoutSpec, door_preference


def _risers(spec: LayoutSpec) -> tuple[int, float]:
    """(number of risers, rise [m]) for the floor height: rise within [0.15, 0.19] m."""
    h = spec.floor_height
    n = math.ceil(h / RISE[1] - 1e-9)
    rise = h / n
    if not RISE[0] <= rise <= RISE[1]:
        raise LayoutError(f"floor height {h:.3f} m gives rise {rise:.3f} m outside [{RISE[0]}, {RISE[1]}]")
    return n, rise


def _stair_run_length(d: _Draft, n_risers: int) -> tuple[int, int, int]:
    """(flight-1 length, flight-2 length, landing) [cm] of the staircase shape."""
    treads = n_risers - 1
    if d.stair_shape == "straight":
        return treads * d.run, 0, 0
    k2 = max(3, (treads - 1) // 3)
    k1 = treads - 1 - k2
    return k1 * d.run, k2 * d.run, d.stair_width


def build_walls(f: int, rooms: list[Room], fp: Rect, t_ext: int, t_int: int) -> list[Wall]:
    """Exterior walls (one per footprint side) and maximal interior walls along shared edges."""
    walls = [
        Wall(f"f{f}_wall_ext_s", f, True, fp.y0, Rect(fp.x0, fp.y0, fp.x1, fp.y0 + t_ext), t_ext, True),
        Wall(f"f{f}_wall_ext_n", f, True, fp.y1, Rect(fp.x0, fp.y1 - t_ext, fp.x1, fp.y1), t_ext, True),
        Wall(f"f{f}_wall_ext_w", f, False, fp.x0, Rect(fp.x0, fp.y0 + t_ext, fp.x0 + t_ext, fp.y1 - t_ext),
             t_ext, True),
        Wall(f"f{f}_wall_ext_e", f, False, fp.x1, Rect(fp.x1 - t_ext, fp.y0 + t_ext, fp.x1, fp.y1 - t_ext),
             t_ext, True),
    ]
    lines: dict[tuple[bool, int], list[tuple[int, int]]] = {}
    for r in rooms:
        for e in r.edges:
            if not _on_boundary(e, fp):
                lines.setdefault((e.horizontal, e.line), []).append((e.a, e.b))
    h = t_int // 2
    k = 0
    for (horiz, line), ivs in sorted(lines.items()):
        for a, b in _merge_intervals(ivs):
            lo_lim, hi_lim = (fp.x0 + t_ext, fp.x1 - t_ext) if horiz else (fp.y0 + t_ext, fp.y1 - t_ext)
            a2, b2 = max(a - h, lo_lim), min(b + h, hi_lim)
            box = Rect(a2, line - h, b2, line + h) if horiz else Rect(line - h, a2, line + h, b2)
            walls.append(Wall(f"f{f}_wall_{k:02d}", f, horiz, line, box, t_int, False))
            k += 1
    return walls


def shared_segments(a: Room, b: Room) -> list[tuple[bool, int, int, int]]:
    """(horizontal, line, s0, s1) segments where the outlines of a and b touch (opposite sides)."""
    out = []
    ba, bb = a.bbox, b.bbox
    if ba.x0 > bb.x1 or bb.x0 > ba.x1 or ba.y0 > bb.y1 or bb.y0 > ba.y1:
        return out
    for ea in a.edges:
        for eb in b.edges:
            if ea.horizontal == eb.horizontal and ea.line == eb.line and ea.inside != eb.inside:
                s0, s1 = max(ea.a, eb.a), min(ea.b, eb.b)
                if s1 > s0:
                    out.append((ea.horizontal, ea.line, s0, s1))
    return out


def wall_at(walls: list[Wall] | tuple[Wall, ...], horizontal: bool, line: int, s0: int, s1: int) -> Wall:
    """The wall that carries the segment [s0, s1] on a line (interior: centerline; exterior: face)."""
    for w in walls:
        a0, a1 = w.along
        if w.horizontal == horizontal and w.line == line and min(s1, a1) > max(s0, a0):
            return w
    raise PlanRejected(f"no wall on line {line}")


def _zone(w: Wall, c: int, width: int, depth_neg: int, depth_pos: int) -> Rect:
    """Clearance zone of an opening: width + margins along, wall + depths across [cm]."""
    lo, hi = c - width // 2 - DOOR_MARGIN, c + width // 2 + DOOR_MARGIN
    c0, c1 = w.across
    return Rect(lo, c0 - depth_neg, hi, c1 + depth_pos) if w.horizontal else \
        Rect(c0 - depth_neg, lo, c1 + depth_pos, hi)


def feasible_centers(w: Wall, s0: int, s1: int, width: int, obstacles: list[Rect],
                     depth_neg: int, depth_pos: int, placed: list[Opening], spacing: int) -> np.ndarray:
    """Opening centers [cm] (multiples of STEP) on wall ``w`` within [s0, s1] whose clearance zone
    meets no obstacle and that keep ``spacing`` from openings already on the wall."""
    a0, a1 = w.along
    lo = max(s0, a0) + width // 2 + DOOR_MARGIN
    hi = min(s1, a1) - width // 2 - DOOR_MARGIN
    if hi < lo:
        return np.zeros(0, dtype=np.int64)
    cs = np.arange(math.ceil(lo / STEP) * STEP, hi + 1, STEP, dtype=np.int64)
    if cs.size == 0:
        return cs
    ok = np.ones(cs.size, dtype=bool)
    z = _zone(w, 0, width, depth_neg, depth_pos)
    if obstacles:
        ob = np.array([(o.x0, o.y0, o.x1, o.y1) for o in obstacles], dtype=np.int64)
        if not w.horizontal:
            ob = ob[:, [1, 0, 3, 2]]
            zc0, zc1 = z.x0, z.x1
        else:
            zc0, zc1 = z.y0, z.y1
        ob = ob[(ob[:, 3] > zc0) & (ob[:, 1] < zc1)]
        if ob.size:
            half = width // 2 + DOOR_MARGIN
            hit = (cs[:, None] + half > ob[None, :, 0]) & (cs[:, None] - half < ob[None, :, 2])
            ok &= ~hit.any(axis=1)
    for p in placed:
        if p.wall == w.id:
            ok &= np.abs(cs - p.center) >= (width + p.width) // 2 + spacing
    return cs[ok]


def _pick(rng: np.random.Generator, cs: np.ndarray) -> int:
    return int(cs[int(rng.integers(cs.size))])


def _door_candidates(d: _Draft, f: int, a: Room, b: Room, walls: list[Wall], obstacles: list[Rect],
                     placed: list[Opening], width: int) -> list[tuple[Wall, np.ndarray]]:
    out = []
    for horiz, line, s0, s1 in shared_segments(a, b):
        try:
            w = wall_at(walls, horiz, line, s0, s1)
        except PlanRejected:
            continue
        others = [x.box for x in walls if x.id != w.id] + obstacles
        cs = feasible_centers(w, s0, s1, width, others, DOOR_DEPTH, DOOR_DEPTH, placed, DOOR_SPACING)
        if cs.size:
            out.append((w, cs))
    return out


def _spanning_doors(d: _Draft, f: int, rooms: list[Room], walls: list[Wall],
                    obstacles: list[Rect]) -> list[Opening]:
    """Doors along a preference-weighted spanning tree (bathrooms as leaves), plus optional extras."""
    rng, spec = d.rng, d.spec
    widths = list(range(snap(spec.door_width[0] * 100, 10), snap(spec.door_width[1] * 100, 10) + 1, 10))
    edges = []
    for i in range(len(rooms)):
        for j in range(i + 1, len(rooms)):
            if _door_candidates(d, f, rooms[i], rooms[j], walls, obstacles, [], min(widths)):
                cost = door_preference(rooms[i].type, rooms[j].type) + rng.uniform(0.0, 0.5)
                edges.append((cost, i, j))
    edges.sort()
    parent = list(range(len(rooms)))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    chosen: list[tuple[int, int]] = []
    is_bath = [r.type == RoomType.BATHROOM for r in rooms]
    core = [e for e in edges if not is_bath[e[1]] and not is_bath[e[2]]]
    for _, i, j in core:
        if find(i) != find(j):
            parent[find(i)] = find(j)
            chosen.append((i, j))
    for _, i, j in edges:
        if (is_bath[i] or is_bath[j]) and not (is_bath[i] and is_bath[j]) and find(i) != find(j):
            parent[find(i)] = find(j)
            chosen.append((i, j))
    if len({find(i) for i in range(len(rooms))}) != 1:
        raise PlanRejected(f"floor {f}: rooms cannot all be joined by doors")
    for _, i, j in edges:
        pair = {rooms[i].type, rooms[j].type}
        if (i, j) not in chosen and pair == {RoomType.LIVING_ROOM, RoomType.KITCHEN} and rng.random() < 0.5:
            chosen.append((i, j))
    doors: list[Opening] = []
    for k, (i, j) in enumerate(chosen):
        width = widths[int(rng.integers(len(widths)))]
        cands = _door_candidates(d, f, rooms[i], rooms[j], walls, obstacles, doors, width)
        if not cands:
            width = min(widths)
            cands = _door_candidates(d, f, rooms[i], rooms[j], walls, obstacles, doors, width)
        if not cands:
            raise PlanRejected(f"floor {f}: no room for door {rooms[i].id}-{rooms[j].id}")
        w, cs = cands[int(rng.integers(len(cands)))]
        doors.append(Opening(f"f{f}_door_{k:02d}", f, "door", w.id, _pick(rng, cs), width, 0.0,
                             spec.door_height, (rooms[i].id, rooms[j].id)))
    return doors


PRIVATE_ACCESS = (RoomType.HALLWAY, RoomType.LIVING_ROOM)


def private_access_misses(rooms: tuple[Room, ...] | list[Room], openings) -> int:
    """Bedrooms entered only through a kitchen, bathroom or another bedroom on a floor that has a
    hallway or living room (counted against the plan's score)."""
    ids = {r.id: r for r in rooms}
    hubs = {r.id for r in rooms if r.type in PRIVATE_ACCESS}
    if not hubs:
        return 0
    misses = 0
    for r in rooms:
        if r.type != RoomType.BEDROOM:
            continue
        nbrs = {b if a == r.id else a for o in openings if o.kind == "door" and r.id in o.rooms
                for a, b in [o.rooms]}
        if not nbrs & hubs and all(n in ids for n in nbrs):
            misses += 1
    return misses


def _exterior_edges(room: Room, fp: Rect) -> list[Edge]:
    return [e for e in room.edges if _on_boundary(e, fp)]


def _exterior_door(d: _Draft, rooms: list[Room], walls: list[Wall], obstacles: list[Rect],
                   placed: list[Opening], fp: Rect) -> Opening:
    """The entrance: on an exterior wall of the hallway, else living room, else kitchen, else any room."""
    rank = {RoomType.HALLWAY: 0, RoomType.LIVING_ROOM: 1, RoomType.KITCHEN: 2}
    width = snap(max(d.spec.door_width[1], 1.0) * 100, 10)
    for room in sorted(rooms, key=lambda r: (rank.get(r.type, 9), r.id)):
        cands = []
        for e in _exterior_edges(room, fp):
            w = wall_at(walls, e.horizontal, e.line, e.a, e.b)
            others = [x.box for x in walls if x.id != w.id] + obstacles
            inward_pos = e.inside > 0
            cs = feasible_centers(w, e.a, e.b, width, others, 0 if inward_pos else DOOR_DEPTH,
                                  DOOR_DEPTH if inward_pos else 0, placed, DOOR_SPACING)
            if cs.size:
                cands.append((w, cs))
        if cands:
            w, cs = cands[int(d.rng.integers(len(cands)))]
            return Opening("f0_door_ext", 0, "exterior_door", w.id, _pick(d.rng, cs), width, 0.0,
                           d.spec.door_height, (room.id, None))
    raise PlanRejected("no place for the exterior door")


def _windows(d: _Draft, f: int, rooms: list[Room], walls: list[Wall], placed: list[Opening],
             fp: Rect) -> list[Opening]:
    """One window per exterior edge of rooms that have windows (wide enough edges only)."""
    rng, spec = d.rng, d.spec
    out: list[Opening] = []
    k = 0
    for room in rooms:
        if not ROOM_RULES[room.type].windows:
            continue
        bath = room.type == RoomType.BATHROOM
        sill = 1.4 if bath else 0.9
        top = min(sill + (0.6 if bath else 1.3), spec.ceiling_height - 0.25)
        for e in _exterior_edges(room, fp):
            w = wall_at(walls, e.horizontal, e.line, e.a, e.b)
            others = [x.box for x in walls if x.id != w.id]
            max_w = min(60 if bath else 180, (e.b - e.a) - 2 * (d.t_int + WINDOW_MARGIN))
            if max_w < 60:
                continue
            width = _uniform_int(rng, 60, max_w, 10)
            inward_pos = e.inside > 0
            cs = feasible_centers(w, e.a, e.b, width, others, 0 if inward_pos else WINDOW_MARGIN,
                                  WINDOW_MARGIN if inward_pos else 0, placed + out, WINDOW_MARGIN + 10)
            if cs.size == 0:
                continue
            out.append(Opening(f"f{f}_window_{k:02d}", f, "window", w.id, _pick(rng, cs), width, sill, top,
                               (room.id, None)))
            k += 1
    return out


def _stair(d: _Draft, k: int, rise: float, n_risers: int) -> Stair:
    """Staircase k (floor k -> k+1) in the hallway strip, against one side wall of the strip (the
    exterior one when the strip is at the footprint's edge) for even k and against the other for odd
    k (switchback for 3 floors)."""
    strip = d.strip
    assert strip is not None
    sw, run = d.stair_width, d.run
    left_face = strip.x0 + (d.t_ext if strip.x0 == 0 else d.t_int // 2)
    right_face = strip.x1 - (d.t_ext if strip.x1 == d.W else d.t_int // 2)
    sgn = d.stair_side if k % 2 == 0 else -d.stair_side
    face = left_face if sgn > 0 else right_face
    up = 1 if k % 2 == 0 else -1  # direction of ascent along y
    l1, l2, land = _stair_run_length(d, n_risers)
    y_start = d.stair_y0 if up > 0 else d.stair_y0 + l1

    def R(v0: int, u0: int, v1: int, u1: int) -> Rect:
        """Local (v across from the wall, u along the ascent) to plan coordinates."""
        return make_rect(face + sgn * v0, y_start + up * u0, face + sgn * v1, y_start + up * u1)

    def P(v: int, u: int) -> Point:
        return (face + sgn * v, y_start + up * u)

    treads: list[tuple[Rect, int]] = []
    bal: list[tuple[Rect, int]] = []
    if d.stair_shape == "straight":
        n_t = n_risers - 1
        for i in range(n_t):
            treads.append((R(0, i * run, sw, (i + 1) * run), i + 1))
            bal.append((R(sw - RAIL_T, i * run, sw, (i + 1) * run), i + 1))
        opening = (R(0, 0, sw, l1),)
        rails = (R(sw, -RAIL_T, sw + RAIL_T, l1), R(0, -RAIL_T, sw, 0))
        top = P(sw // 2, l1 + 40)
        footprint = (R(0, 0, sw, l1),)
    else:
        k1 = l1 // run
        k2 = l2 // run
        for i in range(k1):
            treads.append((R(0, i * run, sw, (i + 1) * run), i + 1))
            bal.append((R(sw - RAIL_T, i * run, sw, (i + 1) * run), i + 1))
        treads.append((R(0, l1, sw, l1 + land), k1 + 1))
        bal.append((R(0, l1 + land - RAIL_T, sw, l1 + land), k1 + 1))
        for j in range(k2):
            v0 = sw + j * run
            treads.append((R(v0, l1, v0 + run, l1 + land), k1 + 2 + j))
            bal.append((R(v0, l1, v0 + run, l1 + RAIL_T), k1 + 2 + j))
            bal.append((R(v0, l1 + land - RAIL_T, v0 + run, l1 + land), k1 + 2 + j))
        opening = (R(0, 0, sw, l1 + land), R(sw, l1, sw + l2, l1 + land))
        rails = (R(0, -RAIL_T, sw, 0), R(sw, -RAIL_T, sw + RAIL_T, l1 - RAIL_T),
                 R(sw, l1 - RAIL_T, sw + l2, l1), R(0, l1 + land, sw + l2, l1 + land + RAIL_T))
        top = P(sw + l2 + 40, l1 + land // 2)
        footprint = opening
    bottom = P(sw // 2, -40)
    return Stair(f"stair_{k}", k, d.stair_shape, n_risers, rise, run, sw, tuple(treads), opening, rails,
                 tuple(bal), bottom, top, footprint)
