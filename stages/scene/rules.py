"""Placement rules as data: ``stages/scene/rules/*.toml`` read into typed, validated models.

The rule file documents its own fields (see ``rules/default.toml``); a file may extend another
(``rules/household_tasks.toml`` extends the default one, see ``load_rules``). The solver
(``stages.scene.solver``) reads only these models. ``load_rules(path)`` raises ``RulesError``
naming the file and every problem, so a user can fix all of them in one pass.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from asset_catalog.annotations import RoomType

DEFAULT_RULES = Path(__file__).parent / "rules" / "default.toml"
HOUSEHOLD_TASK_RULES = Path(__file__).parent / "rules" / "household_tasks.toml"
_SECTIONS = ("furniture", "objects")


class RulesError(ValueError):
    """A rule file is invalid; the message names the file and every problem."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class _Entry(_Strict):
    category: str = Field(min_length=1)
    count: tuple[int, int] = (1, 1)
    probability: float = Field(default=1.0, ge=0.0, le=1.0)
    requires: tuple[str, ...] = ()

    def fits(self, record, geo) -> bool:
        """Whether a catalog record (its package geometry ``geo``) may serve this entry (any, here)."""
        return True

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
    min_top: float | None = Field(default=None, gt=0.0)
    stand: tuple[float, float] = (0.0, 0.0)
    clear_of_swings: bool = False
    side: tuple[float, float] = (0.0, 0.0)
    leaf: float = 0.0
    leaf_door: Literal["each", "one"] = "each"

    def fits(self, record, geo) -> bool:
        """Whether the longest top surface of the package (within 2 cm of its highest surface), along
        its back (asset y), is at least ``min_top`` [m]."""
        if self.min_top is None:
            return True
        if not geo.surfaces:
            return False
        z = max(s.z for s in geo.surfaces)
        return max(float(np.ptp(s.polygon[:, 1])) for s in geo.surfaces if s.z >= z - 0.02) >= self.min_top

    def problems(self) -> list[str]:
        errs = super().problems()
        if self.mode in ("facing", "front", "beside", "around") and not self.target:
            errs.append(f"mode {self.mode!r} needs a target category")
        if not all(0.0 <= w <= 3.0 for w in self.stand):
            errs.append(f"stand {list(self.stand)} must be [free edge, hinge] widths in [0, 3] m")
        if not 0.0 <= self.leaf <= 3.0:
            errs.append(f"leaf {self.leaf} must be a radius in [0, 3] m")
        if not all(0.0 <= w <= 3.0 for w in self.side):
            errs.append(f"side {list(self.side)} must be [depth, beyond] in [0, 3] m")
        if self.distance[0] < 0 or self.distance[1] < self.distance[0]:
            errs.append(f"distance {list(self.distance)} must be [min, max] with 0 <= min <= max")
        return errs


class ObjectRule(_Entry):
    """An entry placed on support surfaces of furniture (see the rule file's header)."""

    on: tuple[str, ...] = ()
    align: bool = False
    inside: bool = False
    max_width: float | None = Field(default=None, gt=0.0)
    thickness: tuple[float, float] | None = None

    def fits(self, record, geo=None) -> bool:
        """Whether a catalog record's narrower horizontal extent [m] is at most ``max_width`` (a
        hand grasps it across) and its smallest extent [m] within ``thickness`` (a book's covers)."""
        if self.thickness is not None and not self.thickness[0] <= min(record.dimensions) <= self.thickness[1]:
            return False
        return self.max_width is None or min(record.dimensions[:2]) <= self.max_width

    def problems(self) -> list[str]:
        errs = super().problems()
        if self.thickness is not None and not 0.0 < self.thickness[0] <= self.thickness[1]:
            errs.append(f"thickness {list(self.thickness)} must be [min, max] with 0 < min <= max")
        return errs


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
    """Read and validate a rule file (TOML); raises RulesError naming the file and every problem.

    A file may start with ``extends = "other.toml"`` (relative to the file): it is then read over that
    base (see ``rules/household_tasks.toml``): its ``[defaults]`` and room settings override the base's
    field by field; in each room's furniture and objects lists, an entry of a category the base lists
    replaces the base's entries of that category (at the first one's position), and an entry of a new
    category is appended; ``replace = ["furniture"]`` (or "objects") in a room makes the file's list
    replace the base's whole list (to change the order)."""
    path = Path(path)
    raw = _merged_raw(path, ())
    try:
        return PlacementRules.model_validate(raw)
    except ValidationError as e:
        msgs = [f"{'.'.join(str(x) for x in err['loc'])}: {err['msg']}" for err in e.errors()]
        raise RulesError(f"{path}: " + "; ".join(msgs)) from None


def rule_files(path: str | Path = DEFAULT_RULES) -> tuple[Path, ...]:
    """The rule file and the files it extends, in order (inputs of a cached scene item). A file that
    cannot be read, or a cycle, ends the list: ``load_rules`` reports it."""
    out = [Path(path)]
    while True:
        try:
            base = _read(out[-1]).get("extends")
        except RulesError:
            break
        if not isinstance(base, str):
            break
        nxt = out[-1].parent / base
        if nxt.resolve() in {p.resolve() for p in out}:
            break
        out.append(nxt)
    return tuple(out)


def _read(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RulesError(f"{path}: rule file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise RulesError(f"{path}: not valid TOML: {e}") from None


def _merged_raw(path: Path, seen: tuple[Path, ...]) -> dict:
    raw = _read(path)
    base_name = raw.pop("extends", None)
    if base_name is None:
        return raw
    if not isinstance(base_name, str):
        raise RulesError(f"{path}: extends must be a file name, got {base_name!r}")
    base_path = (path.parent / base_name).resolve()
    if base_path in seen or base_path == path.resolve():
        raise RulesError(f"{path}: extends {base_name!r} makes a cycle")
    base = _merged_raw(base_path, (*seen, path.resolve()))
    out = dict(base)
    for key, val in raw.items():
        if key == "defaults" and isinstance(val, dict):
            out["defaults"] = {**base.get("defaults", {}), **val}
        elif key == "room" and isinstance(val, dict):
            rooms = dict(base.get("room", {}))
            for rt, rr in val.items():
                rooms[rt] = _merge_room(rooms.get(rt, {}), rr) if isinstance(rr, dict) else rr
            out["room"] = rooms
        else:
            out[key] = val
    return out


def _merge_room(base: dict, over: dict) -> dict:
    whole = over.get("replace", [])
    whole = [whole] if isinstance(whole, str) else whole
    out = {**base, **{k: v for k, v in over.items() if k not in (*_SECTIONS, "replace")}}
    if not isinstance(whole, list) or not {str(w) for w in whole} <= set(_SECTIONS):
        out["replace"] = whole   # left for validation to name
        whole = []
    for sec in _SECTIONS:
        if sec in whole:
            out[sec] = over.get(sec, [])
            continue
        new = [e for e in over.get(sec, []) if isinstance(e, dict)]
        by_cat: dict[object, list[dict]] = {}
        for e in new:
            by_cat.setdefault(e.get("category"), []).append(e)
        entries, done = [], set()
        for b in base.get(sec, []):
            cat = b.get("category") if isinstance(b, dict) else None
            if cat not in by_cat:
                entries.append(b)
            elif cat not in done:       # the override's entries of a category take the base's first place
                entries += by_cat[cat]
                done.add(cat)
        entries += [e for e in new if e.get("category") not in done]
        entries += [e for e in over.get(sec, []) if not isinstance(e, dict)]   # left for validation to name
        if entries:
            out[sec] = entries
    return out
