"""Placement rules as data: ``stages/scene/rules/*.toml`` read into typed, validated models.

The rule file documents its own fields (see ``rules/default.toml``); the solver
(``stages.scene.solver``) reads only these models. ``load_rules(path)`` raises ``RulesError``
naming the file and every problem, so a user can fix all of them in one pass.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from asset_catalog.annotations import RoomType

DEFAULT_RULES = Path(__file__).parent / "rules" / "default.toml"


class RulesError(ValueError):
    """A rule file is invalid; the message names the file and every problem."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class _Entry(_Strict):
    category: str = Field(min_length=1)
    count: tuple[int, int] = (1, 1)
    probability: float = Field(default=1.0, ge=0.0, le=1.0)
    requires: tuple[str, ...] = ()

    def problems(self) -> list[str]:
        lo, hi = self.count
        return [f"count {list(self.count)} must be [min, max] with 0 <= min <= max"] if lo < 0 or hi < lo else []

    @model_validator(mode="after")
    def _check(self):
        errs = self.problems()
        if errs:
            raise ValueError("; ".join(errs))
        return self


class FurnitureRule(_Entry):
    """A floor-standing entry (see the rule file's header for the meaning of each field)."""

    mode: Literal["wall", "facing", "front", "beside", "around", "floor"] = "wall"
    target: str | None = None
    distance: tuple[float, float] = (0.3, 0.6)
    clearance: float = Field(default=0.0, ge=0.0, le=3.0)
    yaw_jitter: float = Field(default=0.0, ge=0.0, le=180.0)
    tall_ok_at_window: bool = False
    snap: float = Field(default=0.0, ge=0.0, le=1.0)

    def problems(self) -> list[str]:
        errs = super().problems()
        if self.mode in ("facing", "front", "beside", "around") and not self.target:
            errs.append(f"mode {self.mode!r} needs a target category")
        if self.distance[0] < 0 or self.distance[1] < self.distance[0]:
            errs.append(f"distance {list(self.distance)} must be [min, max] with 0 <= min <= max")
        return errs


class ObjectRule(_Entry):
    """An entry placed on support surfaces of furniture (see the rule file's header)."""

    on: tuple[str, ...] = ()
    align: bool = False


class RoomRules(_Strict):
    furniture: tuple[FurnitureRule, ...] = ()
    objects: tuple[ObjectRule, ...] = ()
    path_width: float | None = Field(default=None, gt=0.0)
    reach: float | None = Field(default=None, gt=0.0)
    door_clearance: float | None = Field(default=None, ge=0.0)
    wall_gap: float | None = Field(default=None, ge=0.0)
    min_gap: float | None = Field(default=None, ge=0.0)


class Defaults(_Strict):
    """path_width, reach, door_clearance, wall_gap, min_gap [m]; max_tries: samples per instance;
    room_attempts: arrangements tried per room (a room whose required entry fails is emptied and
    arranged again) before the populate attempt fails."""

    path_width: float = Field(default=0.6, gt=0.0)
    reach: float = Field(default=0.9, gt=0.0)
    door_clearance: float = Field(default=1.0, ge=0.0)
    wall_gap: float = Field(default=0.02, ge=0.0)
    min_gap: float = Field(default=0.03, ge=0.0)
    max_tries: int = Field(default=40, ge=1, le=10000)
    room_attempts: int = Field(default=8, ge=1, le=100)


class PlacementRules(_Strict):
    defaults: Defaults = Defaults()
    room: dict[RoomType, RoomRules] = Field(default_factory=dict)

    def for_room(self, room_type: RoomType | str) -> RoomRules:
        """The rules of a room type (empty rules when the file has none for it)."""
        return self.room.get(RoomType(room_type), RoomRules())

    def setting(self, room_type: RoomType | str, name: str) -> float:
        """A room setting (path_width, reach, door_clearance, wall_gap, min_gap), falling back to defaults."""
        v = getattr(self.for_room(room_type), name)
        return float(getattr(self.defaults, name) if v is None else v)

    def categories(self) -> set[str]:
        return {e.category for r in self.room.values() for e in (*r.furniture, *r.objects)}


def load_rules(path: str | Path = DEFAULT_RULES) -> PlacementRules:
    """Read and validate a rule file (TOML); raises RulesError naming the file and every problem."""
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RulesError(f"{path}: rule file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise RulesError(f"{path}: not valid TOML: {e}") from None
    try:
        return PlacementRules.model_validate(raw)
    except ValidationError as e:
        msgs = [f"{'.'.join(str(x) for x in err['loc'])}: {err['msg']}" for err in e.errors()]
        raise RulesError(f"{path}: " + "; ".join(msgs)) from None
