"""The layout spec (what a user asks for) and the per-room-type rules (data a user can read and edit).

All lengths are meters, areas square meters. The spec says *what* rooms a house has; the planner
(``stages.layout.plan``) decides where they go, using a ``numpy.random.Generator`` seeded from the
spec's ``seed`` (or the work item's seed when the spec has none).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from asset_catalog.annotations import RoomType

PUBLIC_ROOMS = (RoomType.LIVING_ROOM, RoomType.KITCHEN)
PRIVATE_ROOMS = (RoomType.BEDROOM, RoomType.BATHROOM)


@dataclass(frozen=True, kw_only=True)
class RoomRule:
    """Size rules of one room type.

    area: (min, max) target floor area [m^2] (wall centerlines), sampled uniformly;
    min_side: shortest allowed side of the room's bounding box [m];
    max_aspect: largest allowed long/short side ratio of the bounding box [-];
    min_fill: smallest allowed floor area / bounding-box area [-] (1 for rectangles);
    min_arm: narrowest allowed arm of an L-shaped room [m];
    can_be_l: whether the room may become L-shaped;
    windows: whether the room gets windows on its exterior walls.
    """

    area: tuple[float, float]
    min_side: float
    max_aspect: float
    min_fill: float = 0.55
    min_arm: float = 1.6
    can_be_l: bool = False
    windows: bool = True


ROOM_RULES: dict[RoomType, RoomRule] = {
    RoomType.LIVING_ROOM: RoomRule(area=(16.0, 28.0), min_side=3.0, max_aspect=2.2, can_be_l=True),
    RoomType.KITCHEN: RoomRule(area=(8.0, 14.0), min_side=2.2, max_aspect=2.4, can_be_l=True),
    RoomType.BEDROOM: RoomRule(area=(9.0, 15.0), min_side=2.5, max_aspect=2.0, can_be_l=True),
    RoomType.BATHROOM: RoomRule(area=(4.0, 7.0), min_side=1.6, max_aspect=2.4),
    RoomType.HALLWAY: RoomRule(area=(0.0, 0.0), min_side=1.0, max_aspect=100.0, windows=False),
}

# Connection preference between room types for the door graph: lower is preferred [-].
DOOR_PREFERENCE: dict[frozenset[RoomType], float] = {
    frozenset({RoomType.LIVING_ROOM, RoomType.KITCHEN}): 1.0,
    frozenset({RoomType.BEDROOM, RoomType.BATHROOM}): 2.5,
    frozenset({RoomType.BEDROOM}): 6.0,
    frozenset({RoomType.KITCHEN, RoomType.BEDROOM}): 5.0,
    frozenset({RoomType.KITCHEN, RoomType.BATHROOM}): 6.0,
}


def door_preference(a: RoomType, b: RoomType) -> float:
    """Cost of a door between rooms of types a and b (hallways are hubs, then living rooms)."""
    key = frozenset({a, b})
    if key in DOOR_PREFERENCE:
        return DOOR_PREFERENCE[key]
    if RoomType.HALLWAY in key:
        return 0.5
    if RoomType.LIVING_ROOM in key:
        return 2.0
    return 4.0


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class LayoutSpec(_Strict):
    """What house to build.

    rooms: room type -> count for the whole house; a hallway count > 0 asks for a hallway on a single
      floor (at most one hallway per floor; multi-floor houses always get one, it holds the stairs);
    floor_rooms: optional explicit room counts per floor (overrides the automatic distribution:
      living room and kitchen on the ground floor, bedrooms and bathrooms above);
    floors: number of floors (1-3); floors are joined by one staircase each;
    seed: the plan's seed; None uses the work item's seed;
    hallway: "auto" adds a hallway per floor for multi-floor houses (it holds the stairs) and for
      single floors with at least ``hallway_min_rooms`` rooms; "always" / "never";
    bathroom: "auto" adds one bathroom when the house has 2 or more bedrooms and no bathroom;
    stair_shape: "straight", "l_shaped" or "any" (sampled);
    ceiling_height: clear height of every floor [m];
    slab_thickness: floor slab thickness [m]; ceiling_thickness: ceiling finish below it [m];
    exterior_wall / interior_wall: (min, max) wall thickness [m], within [0.1, 0.25];
    door_width: (min, max) clear width of doors [m], at least 0.8;
    robot_radius: radius of the navigating base for the occupancy grid inflation [m];
    cell_size: occupancy grid cell [m];
    l_shape_probability: chance that a plan tries to make one room L-shaped [-];
    min_score: plans whose shape score (mean over rooms of aspect-ratio and floor/bbox-area terms,
      see ``stages.layout.plan.room_score``) is lower are rejected and resampled;
    candidates: valid plans sampled per house; the best-scoring one is kept;
    max_attempts: sampled plans before giving up.
    """

    rooms: dict[RoomType, int] = Field(min_length=1)
    floor_rooms: tuple[dict[RoomType, int], ...] | None = None
    floors: int = Field(default=1, ge=1, le=3)
    seed: int | None = None
    hallway: Literal["auto", "always", "never"] = "auto"
    hallway_min_rooms: int = Field(default=5, ge=2)
    bathroom: Literal["auto", "never"] = "auto"
    stair_shape: Literal["straight", "l_shaped", "any"] = "any"
    ceiling_height: float = Field(default=2.6, ge=2.3, le=3.5)
    slab_thickness: float = Field(default=0.2, ge=0.1, le=0.4)
    ceiling_thickness: float = Field(default=0.02, ge=0.0, le=0.1)
    exterior_wall: tuple[float, float] = (0.2, 0.25)
    interior_wall: tuple[float, float] = (0.1, 0.15)
    door_width: tuple[float, float] = (0.9, 1.0)
    door_height: float = Field(default=2.1, ge=1.9, le=2.4)
    robot_radius: float = Field(default=0.25, ge=0.05, le=0.5)
    cell_size: float = Field(default=0.05, ge=0.01, le=0.25)
    l_shape_probability: float = Field(default=0.35, ge=0.0, le=1.0)
    min_score: float = Field(default=0.65, ge=0.0, le=1.0)
    candidates: int = Field(default=1, ge=1, le=16)
    max_attempts: int = Field(default=400, ge=1)

    @field_validator("rooms")
    @classmethod
    def _counts_ok(cls, v: dict[RoomType, int]) -> dict[RoomType, int]:
        bad = [f"{k}={n}" for k, n in v.items() if n < 0 or n > 8]
        if bad:
            raise ValueError(f"room counts must be in 0..8, got {', '.join(bad)}")
        if sum(n for t, n in v.items() if t != RoomType.HALLWAY) == 0:
            raise ValueError("the house needs at least one room besides hallways")
        return v

    @field_validator("exterior_wall", "interior_wall")
    @classmethod
    def _wall_ok(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not 0.1 <= v[0] <= v[1] <= 0.25:
            raise ValueError(f"wall thickness range must satisfy 0.1 <= min <= max <= 0.25 m, got {v}")
        return v

    @field_validator("door_width")
    @classmethod
    def _door_ok(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not 0.8 <= v[0] <= v[1] <= 1.6:
            raise ValueError(f"door width range must satisfy 0.8 <= min <= max <= 1.6 m, got {v}")
        return v

    @model_validator(mode="after")
    def _floors_ok(self) -> "LayoutSpec":
        if self.floor_rooms is not None and len(self.floor_rooms) != self.floors:
            raise ValueError(f"floor_rooms lists {len(self.floor_rooms)} floors but floors={self.floors}")
        if self.floor_rooms is None and self.floors > 1:
            n = sum(n for t, n in self.rooms.items() if t != RoomType.HALLWAY)
            if n < self.floors:
                raise ValueError(f"{n} room(s) cannot fill {self.floors} floors (one room per floor at least)")
        return self

    @property
    def floor_height(self) -> float:
        """Floor-to-floor height [m]: clear height + ceiling finish + slab."""
        return self.ceiling_height + self.ceiling_thickness + self.slab_thickness


def rooms_per_floor(spec: LayoutSpec) -> list[list[RoomType]]:
    """The room types of each floor (hallways excluded; see ``needs_hallway``), in a fixed order.

    Automatic distribution: living rooms and kitchens on the ground floor, bedrooms and bathrooms
    round-robin over the upper floors; a floor left empty takes a room from the fullest floor.
    """
    order = list(RoomType)
    if spec.floor_rooms is not None:
        floors = [[t for t in order for _ in range(fr.get(t, 0)) if t != RoomType.HALLWAY]
                  for fr in spec.floor_rooms]
        for i, f in enumerate(floors):
            if not f:
                raise ValueError(f"floor_rooms[{i}] has no room besides hallways")
        return floors
    counts = dict(spec.rooms)
    if (spec.bathroom == "auto" and counts.get(RoomType.BEDROOM, 0) >= 2
            and counts.get(RoomType.BATHROOM, 0) == 0):
        counts[RoomType.BATHROOM] = 1
    public = [t for t in order if t in PUBLIC_ROOMS for _ in range(counts.get(t, 0))]
    private = [t for t in order if t in PRIVATE_ROOMS for _ in range(counts.get(t, 0))]
    floors: list[list[RoomType]] = [[] for _ in range(spec.floors)]
    floors[0].extend(public)
    if spec.floors == 1:
        floors[0].extend(private)
    else:
        # bedrooms first, then bathrooms, round-robin over upper floors
        for i, t in enumerate(private):
            floors[1 + i % (spec.floors - 1)].append(t)
    for i in range(spec.floors):
        while not floors[i]:
            donor = max(range(spec.floors), key=lambda j: (len(floors[j]), -j))
            if len(floors[donor]) < 2:
                raise ValueError("not enough rooms to give every floor one")
            floors[i].append(floors[donor].pop())
    return floors


def needs_hallway(spec: LayoutSpec, n_rooms_on_floor: int) -> bool:
    """Whether a floor gets a hallway strip (multi-floor houses always: it holds the stairs)."""
    if spec.floors > 1:
        return True
    if spec.hallway == "always" or (spec.hallway == "auto" and spec.rooms.get(RoomType.HALLWAY, 0) > 0):
        return True
    if spec.hallway == "never":
        return False
    return n_rooms_on_floor >= spec.hallway_min_rooms
