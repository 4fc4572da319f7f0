"""Independent checks of a sampled plan. The planner rejects any plan with a problem; the property
tests run the same checks over thousands of seeds.

Checks: rooms inside the footprint, not overlapping, covering it; room size rules; every door at
least 0.8 m wide, inside its wall, leading into the rooms it names (or outside for the entrance) with
its clearance zones free of walls, stairs and rails; windows inside exterior walls, apart from
doors; every room joined to every other by doors (and floors by stairs); on the occupancy grid every
room, door and stair end lies in one traversable component; stairs within rise/run limits.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from stages.layout.geom2d import Rect
from stages.layout.model import (DOOR_DEPTH, DOOR_MARGIN, RISE, FloorLayout, HousePlan, Opening, Wall,
                                 room_problems)
from stages.layout.spec import LayoutSpec

PROBE = 30  # [cm] beyond the wall face where a door's sides are probed


def _room_at(fl: FloorLayout, x: float, y: float) -> str | None:
    for r in fl.rooms:
        if r.contains(x, y):
            return r.id
    return None


def room_layout_problems(plan: HousePlan) -> list[str]:
    """Rooms outside the footprint, overlapping, leaving gaps, or breaking size rules."""
    probs = []
    fp = plan.footprint
    for fl in plan.floors:
        pieces = [(r.id, p) for r in fl.rooms for p in r.rects]
        for rid, p in pieces:
            if not p.inside(fp):
                probs.append(f"floor {fl.index}: {rid} leaves the footprint")
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                if pieces[i][1].intersects(pieces[j][1]):
                    probs.append(f"floor {fl.index}: {pieces[i][0]} overlaps {pieces[j][0]}")
        if sum(p.area for _, p in pieces) != fp.area:
            probs.append(f"floor {fl.index}: rooms do not cover the footprint")
        for r in fl.rooms:
            if r.type.value != "hallway":
                probs.extend(room_problems(r))
    return probs


def _probe_points(w: Wall, o: Opening) -> tuple[tuple[float, float], tuple[float, float]]:
    """Points PROBE cm beyond each face of the wall at the opening's center: (minus side, plus side)."""
    c0, c1 = w.across
    if w.horizontal:
        return (o.center, c0 - PROBE), (o.center, c1 + PROBE)
    return (c0 - PROBE, o.center), (c1 + PROBE, o.center)


def opening_problems(plan: HousePlan) -> list[str]:
    """Doors and windows that are too narrow, off their wall, lead into a wall or the wrong place."""
    probs = []
    fp = plan.footprint
    for fl in plan.floors:
        walls = {w.id: w for w in fl.walls}
        obstacles = plan.obstacles(fl.index)
        for o in fl.openings:
            w = walls.get(o.wall)
            if w is None:
                probs.append(f"{o.id}: unknown wall {o.wall}")
                continue
            a0, a1 = w.along
            lo, hi = o.center - o.width // 2, o.center + o.width // 2
            if lo - DOOR_MARGIN < a0 or hi + DOOR_MARGIN > a1:
                probs.append(f"{o.id}: opening leaves its wall {w.id}")
            for p in fl.openings:
                if p.id < o.id and p.wall == o.wall and abs(p.center - o.center) < (p.width + o.width) // 2:
                    probs.append(f"{o.id}: overlaps {p.id}")
            if o.kind == "window":
                if not w.exterior:
                    probs.append(f"{o.id}: window in an interior wall")
                if o.z1 > plan.ceiling_height - 0.1 or o.z0 < 0.3:
                    probs.append(f"{o.id}: window height out of range")
                continue
            if o.width < 80:
                probs.append(f"{o.id}: clear width {o.width / 100:.2f} m < 0.8 m")
            if o.z1 - o.z0 < 1.9:
                probs.append(f"{o.id}: clear height {o.z1 - o.z0:.2f} m < 1.9 m")
            pm, pp = _probe_points(w, o)
            sides = (_room_at(fl, *pm), _room_at(fl, *pp))
            if o.kind == "door":
                if set(sides) != set(o.rooms) or None in sides:
                    probs.append(f"{o.id}: leads {sides} instead of {o.rooms}")
                depth = (DOOR_DEPTH, DOOR_DEPTH)
            else:
                inside = [s for s in sides if s is not None]
                outside = [p for p, s in zip((pm, pp), sides, strict=True) if s is None]
                if inside != [o.rooms[0]] or len(outside) != 1 or fp.contains(*outside[0]):
                    probs.append(f"{o.id}: entrance leads {sides}, expected ({o.rooms[0]}, outside)")
                depth = (DOOR_DEPTH, 0) if sides[0] is not None else (0, DOOR_DEPTH)
            zone_lo, zone_hi = lo - DOOR_MARGIN, hi + DOOR_MARGIN
            c0, c1 = w.across
            z = (zone_lo, c0 - depth[0], zone_hi, c1 + depth[1])
            zone = Rect(*z) if w.horizontal else Rect(z[1], z[0], z[3], z[2])
            for other in [x.box for x in fl.walls if x.id != w.id] + obstacles:
                if zone.intersects(other):
                    probs.append(f"{o.id}: clearance zone blocked by {other}")
                    break
    return probs


def connectivity_problems(plan: HousePlan) -> list[str]:
    """Rooms not reachable through doors (per floor), stairs whose ends are not in rooms."""
    probs = []
    for fl in plan.floors:
        ids = [r.id for r in fl.rooms]
        adj: dict[str, set[str]] = {i: set() for i in ids}
        for o in fl.openings:
            if o.kind == "door" and o.rooms[1] is not None:
                adj[o.rooms[0]].add(o.rooms[1])
                adj[o.rooms[1]].add(o.rooms[0])
        seen = {ids[0]}
        q = deque([ids[0]])
        while q:
            for n in adj[q.popleft()]:
                if n not in seen:
                    seen.add(n)
                    q.append(n)
        for i in ids:
            if i not in seen:
                probs.append(f"floor {fl.index}: {i} is isolated from {ids[0]}")
    if not any(o.kind == "exterior_door" for o in plan.floors[0].openings):
        probs.append("no exterior door on the ground floor")
    for f in range(1, len(plan.floors)):
        if len(plan.stairs_to(f)) != 1:
            probs.append(f"floor {f}: {len(plan.stairs_to(f))} staircases reach it, expected 1")
    for s in plan.stairs:
        if _room_at(plan.floors[s.floor], *s.bottom) is None:
            probs.append(f"{s.id}: bottom is in no room of floor {s.floor}")
        if _room_at(plan.floors[s.floor + 1], *s.top) is None:
            probs.append(f"{s.id}: top is in no room of floor {s.floor + 1}")
        if not RISE[0] <= s.rise <= RISE[1] or s.run < 25:
            probs.append(f"{s.id}: rise {s.rise:.3f} m / run {s.run / 100:.2f} m out of limits")
        if abs(s.n_risers * s.rise - plan.floor_height) > 1e-6:
            probs.append(f"{s.id}: risers do not reach the next floor")
    return probs


def grid_problems(plan: HousePlan, grids: list) -> list[str]:
    """Every room, door and stair end of a floor in one traversable component of its grid."""
    from scipy import ndimage

    probs = []
    for fl, g in zip(plan.floors, grids, strict=True):
        labels, _ = ndimage.label(g.traversable)
        comps: dict[str, set[int]] = {}
        for k, room in enumerate(fl.rooms):
            ls = np.unique(labels[(g.room_index == k) & g.traversable])
            ls = ls[ls > 0]
            if ls.size == 0:
                probs.append(f"floor {fl.index}: {room.id} has no traversable cell")
            comps[room.id] = set(int(v) for v in ls)
        points = []
        walls = {w.id: w for w in fl.walls}
        for o in fl.openings:
            if o.kind != "window":
                w = walls[o.wall]
                c0, c1 = w.across
                mid = (c0 + c1) / 2
                points.append((o.id, (o.center, mid) if w.horizontal else (mid, o.center)))
        points += [(s.id + ".bottom", s.bottom) for s in plan.stairs_from(fl.index)]
        points += [(s.id + ".top", s.top) for s in plan.stairs_to(fl.index)]
        main: set[int] = set()
        for name, (x, y) in points:
            iy, ix = g.cell_of(x / 100, y / 100)
            if not g.is_traversable(x / 100, y / 100):
                probs.append(f"floor {fl.index}: {name} at ({x / 100:.2f}, {y / 100:.2f}) not traversable")
            else:
                main.add(int(labels[iy, ix]))
        for ls in comps.values():
            main |= ls
        if len(main) > 1:
            probs.append(f"floor {fl.index}: traversable space split into {len(main)} parts")
    return probs


def plan_problems(plan: HousePlan, spec: LayoutSpec, grids: list | None = None) -> list[str]:
    """All problems of a plan (empty list: the plan is valid). Computes the grids unless given."""
    probs = room_layout_problems(plan) + opening_problems(plan) + connectivity_problems(plan)
    if probs:
        return probs
    if grids is None:
        from stages.layout.occupancy import occupancy_grid

        grids = [occupancy_grid(plan, f, spec.cell_size, spec.robot_radius) for f in range(len(plan.floors))]
    return grid_problems(plan, grids)
