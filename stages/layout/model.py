"""The floor-plan model (integer centimeters): rooms, outline edges, walls, openings, stairs,
floors and the house plan, with the room rules (``room_problems``, ``room_score``) and the sampling
constants shared by the planner (``stages.layout.plan``), the walls and openings
(``stages.layout.openings``) and the checks (``stages.layout.checks``).

Conventions: x to the right, y to the back, z up; the footprint is [0, W] x [0, D]; exterior walls
lie inside the footprint (their outer face is the footprint boundary); interior walls are centered on
the boundary line between two rooms. Room outlines are the partition of the footprint (wall
centerlines inside, outer faces outside), counter-clockwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
import math

import numpy as np

from asset_catalog.annotations import RoomType
from stages.layout.geom2d import Point, Rect
from stages.layout.spec import ROOM_RULES, LayoutSpec


STEP = 5            # [cm] plan grid


DOOR_MARGIN = 5     # [cm] frame margin on each side of a door opening


DOOR_DEPTH = 60     # [cm] clear passage depth in front of a door, each side


DOOR_SPACING = 30   # [cm] between two openings on one wall


WINDOW_MARGIN = 20  # [cm] from a window to a perpendicular wall or an opening


STAIR_BOTTOM_CLEAR = 120  # [cm] free floor before the first step


STAIR_TOP_CLEAR = 110     # [cm] free floor after the last step


PASSAGE = (110, 140)      # [cm] free width beside a staircase


RUN = (26, 30)            # [cm] tread depth


RISE = (0.15, 0.19)       # [m] riser height limits (the checks enforce them)


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
