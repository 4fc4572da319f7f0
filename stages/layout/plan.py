"""Floor-plan sampling: footprint, rooms (rectangular and L-shaped), walls, doors, windows, stairs.

A plan is sampled in integer centimeters (exact adjacency), scored, checked (``stages.layout.checks``)
and resampled until it passes; a plan that fails a check is never returned.

Conventions: x to the right, y to the back, z up; the footprint is [0, W] x [0, D]; exterior walls
lie inside the footprint (their outer face is the footprint boundary); interior walls are centered on
the boundary line between two rooms. Room outlines are the partition of the footprint (wall
centerlines inside, outer faces outside), counter-clockwise.

The model lives in ``stages.layout.model`` (re-exported here), walls and openings in
``stages.layout.openings``.
"""

from __future__ import annotations

import logging
from collections import Counter
from dataclasses import replace
import math

import numpy as np

from asset_catalog.annotations import RoomType
from stages.layout.geom2d import Point, Rect, make_rect, snap
from stages.layout.model import (
    COLUMN_PROBABILITY, FloorLayout, HousePlan, LayoutError, PASSAGE, PlanRejected, RUN, Room, STACK_DEPTH,
    STAIR_BOTTOM_CLEAR, STAIR_TOP_CLEAR, STAIR_WIDTH, STEP, _Draft, _uniform_int, room_problems, room_score,
)
from stages.layout.openings import (
    _exterior_door, _risers, _spanning_doors, _stair, _stair_run_length, _windows, build_walls,
    private_access_misses,
)
from stages.layout.spec import ROOM_RULES, LayoutSpec, needs_hallway, rooms_per_floor

log = logging.getLogger(__name__)


def _treemap(rect: Rect, items: list[tuple[int, float]], rng: np.random.Generator,
             out: dict[int, Rect], pairs: list[tuple[int, int]], columns: bool = False) -> None:
    """Split ``rect`` among ``items`` ((key, weight)) by recursive area-balanced slicing.

    Records sibling leaf pairs (two leaves whose union is a rectangle) in ``pairs``. With
    ``columns`` every cut is horizontal (rooms stacked along y, each spanning the full width, so
    each touches both long sides of the region).
    """
    if len(items) == 1:
        out[items[0][0]] = rect
        return
    order = [items[i] for i in rng.permutation(len(items))]
    total = sum(w for _, w in order)
    acc, best_k, best_gap = 0.0, 1, math.inf
    for k in range(1, len(order)):
        acc += order[k - 1][1]
        gap = abs(acc - total / 2) + (rng.uniform(0, 0.15 * total) if len(order) > 2 else 0.0)
        if gap < best_gap:
            best_gap, best_k = gap, k
    g1, g2 = order[:best_k], order[best_k:]
    frac = sum(w for _, w in g1) / total
    if rect.w >= rect.h and not columns:
        x = rect.x0 + snap(frac * rect.w, STEP)
        if not rect.x0 < x < rect.x1:
            raise PlanRejected("degenerate split")
        r1, r2 = Rect(rect.x0, rect.y0, x, rect.y1), Rect(x, rect.y0, rect.x1, rect.y1)
    else:
        y = rect.y0 + snap(frac * rect.h, STEP)
        if not rect.y0 < y < rect.y1:
            raise PlanRejected("degenerate split")
        r1, r2 = Rect(rect.x0, rect.y0, rect.x1, y), Rect(rect.x0, y, rect.x1, rect.y1)
    if len(g1) == 1 and len(g2) == 1:
        pairs.append((g1[0][0], g2[0][0]))
    _treemap(r1, g1, rng, out, pairs, columns)
    _treemap(r2, g2, rng, out, pairs, columns)


def _l_outline(u: Rect, corner: int, wn: int, hn: int) -> tuple[tuple[Rect, Rect], tuple[Point, ...], Rect]:
    """U minus a wn x hn notch at corner (0 BL, 1 BR, 2 TR, 3 TL): (two rects, CCW outline, notch)."""
    corners = [(u.x0, u.y0), (u.x1, u.y0), (u.x1, u.y1), (u.x0, u.y1)]
    cx, cy = corners[corner]
    sx = -1 if cx == u.x1 else 1
    sy = -1 if cy == u.y1 else 1
    inner = (cx + sx * wn, cy + sy * hn)
    if corner % 2 == 1:
        pts = [(cx + sx * wn, cy), inner, (cx, cy + sy * hn)]
    else:
        pts = [(cx, cy + sy * hn), inner, (cx + sx * wn, cy)]
    outline = tuple(p for i, c in enumerate(corners) for p in (pts if i == corner else [c]))
    notch = make_rect(cx, cy, cx + sx * wn, cy + sy * hn)
    col = (notch.x0, notch.x1)
    rest_x = (u.x0, notch.x0) if notch.x0 > u.x0 else (notch.x1, u.x1)
    ra = Rect(rest_x[0], u.y0, rest_x[1], u.y1)
    rb = Rect(col[0], u.y0, col[1], notch.y0) if notch.y0 > u.y0 else Rect(col[0], notch.y1, col[1], u.y1)
    return (ra, rb), outline, notch


def _rect_outline(r: Rect) -> tuple[Point, ...]:
    return ((r.x0, r.y0), (r.x1, r.y0), (r.x1, r.y1), (r.x0, r.y1))


def _notch(u: Rect, area_n: float, t_r: RoomType, t_n: RoomType, corners: tuple[int, ...],
           rng: np.random.Generator) -> tuple[tuple[Rect, Rect], tuple[Point, ...], Rect] | None:
    """Place a room of area ``area_n`` [cm^2] in one of ``corners`` of ``u``; the rest of ``u`` is an
    L-shaped room of type t_r. None when the sizes cannot satisfy both rooms' rules."""
    rule_r, rule_n = ROOM_RULES[t_r], ROOM_RULES[t_n]
    arm, nmin = int(rule_r.min_arm * 100), int(rule_n.min_side * 100)
    try:
        wn = _uniform_int(rng, max(nmin, math.ceil(area_n / max(u.h - arm, 1))), u.w - arm, STEP)
    except PlanRejected:
        return None
    hn = snap(area_n / wn, STEP)
    if not (nmin <= hn <= u.h - arm) or max(wn, hn) / min(wn, hn) > rule_n.max_aspect:
        return None
    return _l_outline(u, corners[int(rng.integers(len(corners)))], wn, hn)


def _try_l_shape(types: list[RoomType], rects: dict[int, Rect], pairs: list[tuple[int, int]],
                 rng: np.random.Generator) -> dict[int, tuple[tuple[Rect, ...], tuple[Point, ...]]]:
    """Turn one sibling pair (R, N) into an L-shaped R with N in a corner of their union."""
    shapes = {k: ((r,), _rect_outline(r)) for k, r in rects.items()}
    cands = []
    for a, b in pairs:
        for r, n in ((a, b), (b, a)):
            if ROOM_RULES[types[r]].can_be_l and types[n] != RoomType.HALLWAY:
                cands.append((r, n))
    if not cands:
        return shapes
    r, n = cands[int(rng.integers(len(cands)))]
    ra, rn = rects[r], rects[n]
    u = Rect(min(ra.x0, rn.x0), min(ra.y0, rn.y0), max(ra.x1, rn.x1), max(ra.y1, rn.y1))
    placed = _notch(u, rn.area, types[r], types[n], (0, 1, 2, 3), rng)
    if placed is not None:
        pieces, outline, notch = placed
        shapes[r] = (pieces, outline)
        shapes[n] = ((notch,), _rect_outline(notch))
    return shapes


def _columns_with_ensuite(d: _Draft, reg: Rect, idx: list[int], types: list[RoomType], areas: list[float],
                          pairs: list[tuple[int, int]]) -> dict[int, tuple[tuple[Rect, ...], tuple[Point, ...]]]:
    """Rooms of a region beside the hallway stacked along y (each touches the hallway); a bathroom
    becomes an en-suite notch in the far corner of one bedroom (or other room)."""
    rng = d.rng
    baths = [i for i in idx if types[i] == RoomType.BATHROOM]
    host = None
    if baths and len(idx) >= 3:
        others = [i for i in idx if types[i] != RoomType.BATHROOM]
        beds = [i for i in others if types[i] == RoomType.BEDROOM] or others
        host, bath = beds[int(rng.integers(len(beds)))], baths[0]
    items = [(i, areas[i] + (areas[bath] if i == host else 0.0)) for i in idx if host is None or i != bath]
    out: dict[int, Rect] = {}
    _treemap(reg, items, rng, out, pairs, columns=True)
    shapes = {k: ((r,), _rect_outline(r)) for k, r in out.items()}
    if host is not None:
        assert d.strip is not None
        far = (0, 3) if reg.x1 <= d.strip.x0 else (1, 2)
        placed = _notch(out[host], areas[bath], types[host], RoomType.BATHROOM, far, rng)
        if placed is None:
            raise PlanRejected("no room for the en-suite bathroom")
        pieces, outline, notch = placed
        shapes[host] = (pieces, outline)
        shapes[bath] = ((notch,), _rect_outline(notch))
    return shapes


def _sample_footprint(d: _Draft, floor_types: list[list[RoomType]], areas: list[list[float]],
                      hall: bool) -> tuple[list[Rect], list[Rect]]:
    """Footprint and, per floor, the side regions (left, right) around the hallway strip [cm]."""
    spec, rng = d.spec, d.rng
    a_max = max(sum(a) for a in areas)
    if not hall:
        aspect = rng.uniform(1.0, 1.6)
        w = snap(math.sqrt(a_max * aspect), STEP)
        h = snap(a_max / max(w, 1), STEP)
        if rng.random() < 0.5:
            w, h = h, w
        d.W, d.D = w, h
        return [Rect(0, 0, w, h)], []
    n_risers, _ = _risers(spec)
    if spec.floors == 1:
        hw = _uniform_int(rng, 120, 160, STEP)
        d_min = 300
    else:
        d.stair_width = _uniform_int(rng, *STAIR_WIDTH, STEP)
        d.run = _uniform_int(rng, *RUN)
        d.passage = _uniform_int(rng, *PASSAGE, STEP)
        l1, l2, land = _stair_run_length(d, n_risers)
        n_stairs = spec.floors - 1
        if d.stair_shape == "straight":
            hw = d.t_ext + n_stairs * d.stair_width + d.passage + d.t_ext
            d_min = d.t_ext + STAIR_BOTTOM_CLEAR + l1 + STAIR_TOP_CLEAR + d.t_ext
        else:
            hw = d.t_ext + d.stair_width + l2 + d.passage + d.t_ext
            d_min = d.t_ext + STAIR_BOTTOM_CLEAR + l1 + land + 100 + d.t_ext
        hw = snap(hw + 2, STEP)
        d_min = snap(d_min + 2, STEP)
    side_n = max(len(t) for t in floor_types)
    stacked = [len(t) - (RoomType.BATHROOM in t and len(t) >= 3) for t in floor_types]
    lo = max(d_min, math.sqrt(a_max) * 0.8, STACK_DEPTH * min(max(stacked), 3))
    hi = max(d_min + 50, math.sqrt(a_max + hw * 500) * (1.25 if side_n > 2 else 1.05))
    d.D = _uniform_int(rng, int(lo), int(hi), STEP)
    side = snap(a_max / d.D, STEP)
    both = min(len(t) for t in floor_types) >= 3 and rng.random() < 0.5
    if both:
        left = snap(side * rng.uniform(0.35, 0.65), STEP)
        right = side - left
    elif rng.random() < 0.5:
        left, right = side, 0
    else:
        left, right = 0, side
    if (left and left < 200) or (right and right < 200):
        raise PlanRejected("side region too narrow")
    d.W = left + hw + right
    d.strip = Rect(left, 0, left + hw, d.D)
    if spec.floors > 1:
        d.stair_side = 1 if left == 0 else -1 if right == 0 else (1 if rng.random() < 0.5 else -1)
        l1 = _stair_run_length(d, n_risers)[0]
        top_space = STAIR_TOP_CLEAR if d.stair_shape == "straight" else 100 + d.stair_width
        d.stair_y0 = _uniform_int(rng, d.t_ext + STAIR_BOTTOM_CLEAR, d.D - d.t_ext - top_space - l1, STEP)
    regions = []
    if left:
        regions.append(Rect(0, 0, left, d.D))
    if right:
        regions.append(Rect(left + hw, 0, d.W, d.D))
    return [Rect(0, 0, d.W, d.D)], regions


def _split_rooms(types: list[RoomType], areas: list[float], n_regions: int, rng: np.random.Generator,
                 region_areas: list[int]) -> list[list[int]]:
    """Assign room indices to regions, balancing area shares."""
    if n_regions == 1:
        return [list(range(len(types)))]
    order = [int(i) for i in rng.permutation(len(types))]
    groups: list[list[int]] = [[] for _ in range(n_regions)]
    load = [0.0] * n_regions
    total = sum(areas)
    for i in order:
        share = [load[g] / max(region_areas[g], 1) for g in range(n_regions)]
        g = min(range(n_regions), key=lambda k: (share[k], k))
        groups[g].append(i)
        load[g] += areas[i] / total * sum(region_areas)
    if any(not g for g in groups):
        raise PlanRejected("a side region got no room")
    return groups


def _floor_rooms(d: _Draft, f: int, types: list[RoomType], areas: list[float],
                 regions: list[Rect], footprint: Rect) -> list[Room]:
    """Partition one floor into rooms (hallway strip first when present)."""
    rng = d.rng
    rooms: list[Room] = []
    regs = regions if d.strip is not None else [footprint]
    groups = _split_rooms(types, areas, len(regs), rng, [r.area for r in regs])
    counters: Counter[RoomType] = Counter()

    def rid(t: RoomType) -> str:
        counters[t] += 1
        return f"f{f}_{t.value}_{counters[t]}"

    if d.strip is not None:
        rooms.append(Room(rid(RoomType.HALLWAY), RoomType.HALLWAY, f, (d.strip,), _rect_outline(d.strip)))
    for reg, idx in zip(regs, groups, strict=True):
        out: dict[int, Rect] = {}
        pairs: list[tuple[int, int]] = []
        n_stacked = len(idx) - (1 if any(types[i] == RoomType.BATHROOM for i in idx) and len(idx) >= 3 else 0)
        if d.strip is not None and n_stacked <= 3 and rng.random() < COLUMN_PROBABILITY:
            shapes = _columns_with_ensuite(d, reg, idx, types, areas, pairs)
        else:
            _treemap(reg, [(i, areas[i]) for i in idx], rng, out, pairs)
            shapes = {k: ((r,), _rect_outline(r)) for k, r in out.items()}
            if pairs and rng.random() < d.spec.l_shape_probability:
                shapes = _try_l_shape(types, out, pairs, rng)
        for i in sorted(idx):
            pieces, outline = shapes[i]
            rooms.append(Room(rid(types[i]), types[i], f, tuple(pieces), outline))
    return rooms


def _sample_once(spec: LayoutSpec, floor_types: list[list[RoomType]], rng: np.random.Generator) -> HousePlan:
    d = _Draft(spec=spec, rng=rng)
    d.t_ext = _uniform_int(rng, round(spec.exterior_wall[0] * 100), round(spec.exterior_wall[1] * 100))
    d.t_int = _uniform_int(rng, round(spec.interior_wall[0] * 100), round(spec.interior_wall[1] * 100), 2)
    if spec.floors > 1:
        shape = spec.stair_shape
        if shape == "any":
            shape = "l_shaped" if (spec.floors == 2 and rng.random() < 0.5) else "straight"
        if shape == "l_shaped" and spec.floors > 2:
            shape = "straight"
        d.stair_shape = shape
    areas = [[float(rng.uniform(*ROOM_RULES[t].area)) * 1e4 for t in ts] for ts in floor_types]
    hall = any(needs_hallway(spec, len(ts)) for ts in floor_types)
    (fp,), regions = _sample_footprint(d, floor_types, areas, hall)
    n_risers, rise = _risers(spec)
    stairs = tuple(_stair(d, k, rise, n_risers) for k in range(spec.floors - 1))
    plan_floors = []
    for f, ts in enumerate(floor_types):
        rooms = _floor_rooms(d, f, ts, areas[f], regions, fp)
        probs = [p for r in rooms if r.type != RoomType.HALLWAY for p in room_problems(r)]
        if probs:
            raise PlanRejected(probs[0])
        walls = build_walls(f, rooms, fp, d.t_ext, d.t_int)
        obstacles = [r for s in stairs if s.floor == f for r in s.footprint] + \
                    [r for s in stairs if s.floor + 1 == f for r in (*s.opening, *s.rails)]
        doors = _spanning_doors(d, f, rooms, walls, obstacles)
        if f == 0:
            doors.append(_exterior_door(d, rooms, walls, obstacles, doors, fp))
        windows = _windows(d, f, rooms, walls, doors, fp)
        plan_floors.append(FloorLayout(f, tuple(rooms), tuple(walls), tuple(doors + windows)))
    score = float(np.mean([room_score(r) for fl in plan_floors for r in fl.rooms]))
    score -= 0.1 * sum(private_access_misses(fl.rooms, fl.openings) for fl in plan_floors)
    return HousePlan(fp, d.t_ext, d.t_int, spec.floor_height, spec.ceiling_height, spec.slab_thickness,
                     spec.ceiling_thickness, spec.door_height, tuple(plan_floors), stairs, score)


def sample_plan(spec: LayoutSpec, rng: np.random.Generator) -> HousePlan:
    """Sample plans until ``spec.candidates`` pass every check; return the best-scoring one.

    Raises LayoutError (naming the most common rejections) when ``spec.max_attempts`` are used up.
    """
    return sample_plan_and_grids(spec, rng)[0]


def sample_plan_and_grids(spec: LayoutSpec, rng: np.random.Generator) -> tuple[HousePlan, list]:
    """``sample_plan`` plus the plan's occupancy grids (one ``OccupancyGrid`` per floor)."""
    from stages.layout.checks import plan_problems
    from stages.layout.occupancy import occupancy_grid

    floor_types = rooms_per_floor(spec)
    reasons: Counter[str] = Counter()
    best: tuple[HousePlan, list] | None = None
    found = 0
    for attempt in range(1, spec.max_attempts + 1):
        try:
            cand = _sample_once(spec, floor_types, rng)
        except PlanRejected as e:
            reasons[str(e).split(":")[-1].strip()[:60]] += 1
            continue
        if cand.score < spec.min_score:
            reasons["score below min_score"] += 1
            continue
        grids = [occupancy_grid(cand, f, spec.cell_size, spec.robot_radius) for f in range(len(cand.floors))]
        probs = plan_problems(cand, spec, grids)
        if probs:
            reasons["check: " + probs[0][:60]] += 1
            log.debug("plan rejected by checks: %s", probs)
            continue
        found += 1
        if best is None or cand.score > best[0].score:
            best = (cand, grids)
        if found >= spec.candidates:
            break
    if best is None:
        common = ", ".join(f"{r} ({n})" for r, n in reasons.most_common(3))
        raise LayoutError(f"no valid plan in {spec.max_attempts} attempts; most common rejections: {common}")
    log.debug("plan found after %d attempts (score %.3f)", attempt, best[0].score)
    return replace(best[0], attempts=attempt), best[1]
