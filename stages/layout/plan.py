"""Floor-plan sampling: footprint, rooms (rectangular and L-shaped), walls, doors, windows, stairs.

A plan is sampled in integer centimeters (exact adjacency), scored, checked (``stages.layout.checks``)
and resampled until it passes; a plan that fails a check is never returned.

Conventions: x to the right, y to the back, z up; the footprint is [0, W] x [0, D]; exterior walls
lie inside the footprint (their outer face is the footprint boundary); interior walls are centered on
the boundary line between two rooms. Room outlines are the partition of the footprint (wall
centerlines inside, outer faces outside), counter-clockwise.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from asset_catalog.annotations import RoomType
from stages.layout.geom2d import Point, Rect, make_rect, snap
from stages.layout.spec import ROOM_RULES, LayoutSpec, door_preference, needs_hallway, rooms_per_floor

log = logging.getLogger(__name__)

STEP = 5            # [cm] plan grid
DOOR_MARGIN = 5     # [cm] frame margin on each side of a door opening
DOOR_DEPTH = 60     # [cm] clear passage depth in front of a door, each side
DOOR_SPACING = 30   # [cm] between two openings on one wall
WINDOW_MARGIN = 20  # [cm] from a window to a perpendicular wall or an opening
STAIR_BOTTOM_CLEAR = 120  # [cm] free floor before the first step
STAIR_TOP_CLEAR = 110     # [cm] free floor after the last step
PASSAGE = (110, 140)      # [cm] free width beside a staircase
RUN = (26, 30)            # [cm] tread depth
STAIR_WIDTH = (90, 110)   # [cm]
RAIL_T = 4                # [cm] railing panel thickness
RAIL_HEIGHT = 0.95        # [m]
COLUMN_PROBABILITY = 0.9  # rooms of a region beside the hallway stacked so each touches it
STACK_DEPTH = 260         # [cm] depth per stacked room the footprint allows for


class PlanRejected(Exception):
    """A sampled plan failed a rule; the planner resamples."""


class LayoutError(ValueError):
    """No valid plan could be sampled for a spec."""


@dataclass(frozen=True)
class Room:
    """A room. rects: disjoint pieces (1 for a rectangle, 2 for an L); outline: CCW polygon [cm]."""

    id: str
    type: RoomType
    floor: int
    rects: tuple[Rect, ...]
    outline: tuple[Point, ...]

    @property
    def area(self) -> int:
        return sum(r.area for r in self.rects)

    @property
    def bbox(self) -> Rect:
        return Rect(min(r.x0 for r in self.rects), min(r.y0 for r in self.rects),
                    max(r.x1 for r in self.rects), max(r.y1 for r in self.rects))

    @property
    def is_l(self) -> bool:
        return len(self.rects) == 2

    @cached_property
    def edges(self) -> tuple["Edge", ...]:
        """Outline edges (see ``outline_edges``), computed once."""
        return tuple(outline_edges(self))

    def contains(self, x: float, y: float) -> bool:
        """Point strictly inside the outline (the seam between the pieces of an L counts as inside)."""
        if any(r.contains(x, y) for r in self.rects):
            return True
        if not any(r.x0 <= x <= r.x1 and r.y0 <= y <= r.y1 for r in self.rects):
            return False
        pts = self.outline
        for i, (x0, y0) in enumerate(pts):
            x1, y1 = pts[(i + 1) % len(pts)]
            if min(x0, x1) <= x <= max(x0, x1) and min(y0, y1) <= y <= max(y0, y1):
                return False
        return True


@dataclass(frozen=True)
class Edge:
    """An outline edge: horizontal (along x at y=line) or vertical (along y at x=line), [a, b] along,
    inside: +1 when the room is on the + side of the line, else -1."""

    horizontal: bool
    line: int
    a: int
    b: int
    inside: int


@dataclass(frozen=True)
class Wall:
    """A straight wall. box: its 2-D footprint [cm]; horizontal: runs along x; line: centerline (interior)
    or outer face (exterior) coordinate; thickness [cm]."""

    id: str
    floor: int
    horizontal: bool
    line: int
    box: Rect
    thickness: int
    exterior: bool

    @property
    def along(self) -> tuple[int, int]:
        return (self.box.x0, self.box.x1) if self.horizontal else (self.box.y0, self.box.y1)

    @property
    def across(self) -> tuple[int, int]:
        return (self.box.y0, self.box.y1) if self.horizontal else (self.box.x0, self.box.x1)


@dataclass(frozen=True)
class Opening:
    """A door or window cut through a wall. center/width along the wall [cm]; z0, z1 above the floor [m];
    rooms: (room, other room or None for outside)."""

    id: str
    floor: int
    kind: str  # "door" | "exterior_door" | "window"
    wall: str
    center: int
    width: int
    z0: float
    z1: float
    rooms: tuple[str, str | None]

    def rect(self, wall: Wall) -> Rect:
        """2-D footprint of the cut through the wall [cm]."""
        lo, hi = self.center - self.width // 2, self.center + self.width // 2
        c0, c1 = wall.across
        return Rect(lo, c0, hi, c1) if wall.horizontal else Rect(c0, lo, c1, hi)


@dataclass(frozen=True)
class Stair:
    """A staircase from floor ``floor`` to ``floor + 1``.

    treads: (footprint [cm], number of risers below its top) per step, landing included; the step
    box is solid from the lower floor up to ``n * rise``; opening: the cut in the upper slab [cm];
    rails: railing panels on the upper floor around the opening; balustrades: (footprint, risers) of
    panels standing on treads along open sides; bottom/top: approach points on the lower floor and
    arrival points on the upper floor [cm]; rise [m]; run, width [cm].
    """

    id: str
    floor: int
    shape: str
    n_risers: int
    rise: float
    run: int
    width: int
    treads: tuple[tuple[Rect, int], ...]
    opening: tuple[Rect, ...]
    rails: tuple[Rect, ...]
    balustrades: tuple[tuple[Rect, int], ...]
    bottom: Point
    top: Point
    footprint: tuple[Rect, ...]


@dataclass(frozen=True)
class FloorLayout:
    index: int
    rooms: tuple[Room, ...]
    walls: tuple[Wall, ...]
    openings: tuple[Opening, ...]

    def room(self, rid: str) -> Room:
        for r in self.rooms:
            if r.id == rid:
                return r
        raise KeyError(rid)

    def wall(self, wid: str) -> Wall:
        for w in self.walls:
            if w.id == wid:
                return w
        raise KeyError(wid)


@dataclass(frozen=True)
class HousePlan:
    """A complete plan in cm (heights in m). score in [0, 1], higher is better."""

    footprint: Rect
    t_ext: int
    t_int: int
    floor_height: float
    ceiling_height: float
    slab_thickness: float
    ceiling_thickness: float
    door_height: float
    floors: tuple[FloorLayout, ...]
    stairs: tuple[Stair, ...]
    score: float = 0.0
    attempts: int = 0

    def stairs_from(self, floor: int) -> tuple[Stair, ...]:
        return tuple(s for s in self.stairs if s.floor == floor)

    def stairs_to(self, floor: int) -> tuple[Stair, ...]:
        return tuple(s for s in self.stairs if s.floor + 1 == floor)

    def obstacles(self, floor: int) -> list[Rect]:
        """Non-wall 2-D obstacles of a floor [cm]: stairs going up, stairwell openings and rails."""
        out: list[Rect] = []
        for s in self.stairs_from(floor):
            out.extend(s.footprint)
        for s in self.stairs_to(floor):
            out.extend(s.opening)
            out.extend(s.rails)
        return out


# ----------------------------------------------------------------------------------------------
# sampling helpers


@dataclass
class _Draft:
    """Mutable state of one sampling attempt."""

    spec: LayoutSpec
    rng: np.random.Generator
    t_ext: int = 20
    t_int: int = 10
    W: int = 0
    D: int = 0
    strip: Rect | None = None
    stair_shape: str = "straight"
    stair_width: int = 100
    run: int = 27
    passage: int = 120
    stair_y0: int = 0
    stair_side: int = 1  # +1: first staircase against the strip's left wall, -1: its right wall


def _uniform_int(rng: np.random.Generator, lo: int, hi: int, step: int = 1) -> int:
    """A multiple of ``step`` uniformly in [lo, hi] (both rounded to the step grid)."""
    a, b = math.ceil(lo / step), math.floor(hi / step)
    if b < a:
        raise PlanRejected(f"empty range [{lo}, {hi}]")
    return int(rng.integers(a, b + 1)) * step


def _risers(spec: LayoutSpec) -> tuple[int, float]:
    """(number of risers, rise [m]) for the floor height: rise within [0.15, 0.19] m."""
    h = spec.floor_height
    n = math.ceil(h / 0.19 - 1e-9)
    rise = h / n
    if not 0.15 <= rise <= 0.19:
        raise LayoutError(f"floor height {h:.3f} m gives rise {rise:.3f} m outside [0.15, 0.19]")
    return n, rise


def _stair_run_length(d: _Draft, n_risers: int) -> tuple[int, int, int]:
    """(flight-1 length, flight-2 length, landing) [cm] of the staircase shape."""
    treads = n_risers - 1
    if d.stair_shape == "straight":
        return treads * d.run, 0, 0
    k2 = max(3, (treads - 1) // 3)
    k1 = treads - 1 - k2
    return k1 * d.run, k2 * d.run, d.stair_width


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


# ----------------------------------------------------------------------------------------------
# one attempt


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


def room_problems(room: Room) -> list[str]:
    """Size-rule violations of a room (aspect ratio, floor/bbox area ratio, shortest side, L arms)."""
    rule = ROOM_RULES[room.type]
    bb = room.bbox
    probs = []
    short, long_ = min(bb.w, bb.h) / 100, max(bb.w, bb.h) / 100
    if short < rule.min_side:
        probs.append(f"{room.id}: side {short:.2f} m < {rule.min_side} m")
    if long_ / short > rule.max_aspect:
        probs.append(f"{room.id}: aspect {long_ / short:.2f} > {rule.max_aspect}")
    fill = room.area / bb.area
    if fill < rule.min_fill:
        probs.append(f"{room.id}: floor/bbox area {fill:.2f} < {rule.min_fill}")
    if room.is_l and min(min(r.w, r.h) for r in room.rects) < rule.min_arm * 100:
        probs.append(f"{room.id}: L arm narrower than {rule.min_arm} m")
    return probs


def room_score(room: Room) -> float:
    """Shape quality in [0, 1]: 1 for a square, falling with aspect ratio and unfilled bbox area."""
    rule = ROOM_RULES[room.type]
    bb = room.bbox
    aspect = max(bb.w, bb.h) / min(bb.w, bb.h)
    a_term = 1.0 - min(1.0, (aspect - 1.0) / max(rule.max_aspect - 1.0, 1e-6)) if room.type != RoomType.HALLWAY \
        else 1.0
    fill = room.area / bb.area
    return 0.6 * a_term + 0.4 * fill


# ----------------------------------------------------------------------------------------------
# edges, walls


def outline_edges(room: Room) -> list[Edge]:
    """The room's outline edges with the side its interior lies on."""
    out = []
    pts = room.outline
    for i, (x0, y0) in enumerate(pts):
        x1, y1 = pts[(i + 1) % len(pts)]
        if y0 == y1:
            out.append(Edge(True, y0, min(x0, x1), max(x0, x1), 1 if x1 > x0 else -1))
        else:
            out.append(Edge(False, x0, min(y0, y1), max(y0, y1), -1 if y1 > y0 else 1))
    return out


def _on_boundary(e: Edge, fp: Rect) -> bool:
    return (e.horizontal and e.line in (fp.y0, fp.y1)) or (not e.horizontal and e.line in (fp.x0, fp.x1))


def _merge_intervals(iv: list[tuple[int, int]]) -> list[tuple[int, int]]:
    out: list[tuple[int, int]] = []
    for a, b in sorted(iv):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


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


# ----------------------------------------------------------------------------------------------
# openings


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


# ----------------------------------------------------------------------------------------------
# stairs


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


# ----------------------------------------------------------------------------------------------
# public


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
