"""The catalog's annotation file: the one human-edited input of a catalog.

A catalog is a folder of source files plus ``annotations.toml``::

    [defaults]                 # optional; any AssetAnnotation field except id/source
    room_types = ["kitchen"]

    [[asset]]
    id = "mug_01"              # unique, [a-z0-9_]+; becomes the USD package name
    source = "mugs/mug.obj"    # relative to the catalog folder; never escapes it
    category = "mug"
    room_types = ["kitchen", "living_room"]
    placement = "on_surface"
    material = "ceramic"
    interactable = true
    co_occurrence = ["table", "counter"]
    # optional overrides
    mass = 0.35                # [kg]; default: material density x mesh volume
    up_axis = "Y"              # default: detected per format (glTF: Y, else Z)
    meters_per_unit = 0.001    # default: detected/1.0
    collider = "auto"          # auto | hull | coacd | none
    fixed_base = false         # articulated sources: fix the root to the world
    plausible_size = [0.05, 0.3]   # [m] largest dimension; default: asset_catalog.plausibility
    plausible_mass = [0.1, 1.0]    # [kg] total mass; default: asset_catalog.plausibility
    mjcf_body = "mug"          # MJCF with several top-level bodies: ingest only this one (and its children)

Everything else (bounding box, volume, mass, friction, colliders) is computed by the stages.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path, PurePosixPath
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from asset_catalog.materials import MaterialClass

ANNOTATION_FILENAME = "annotations.toml"
SOURCE_SUFFIXES = (".obj", ".glb", ".gltf", ".stl", ".ply", ".urdf", ".xml", ".mjcf")
_ID_RE = re.compile(r"^[a-z0-9][a-z0-9_]{0,63}$")


class PlacementKind(StrEnum):
    ON_FLOOR = "on_floor"
    AGAINST_WALL = "against_wall"
    ON_SURFACE = "on_surface"
    WALL_MOUNTED = "wall_mounted"
    CEILING = "ceiling"


class RoomType(StrEnum):
    LIVING_ROOM = "living_room"
    KITCHEN = "kitchen"
    BEDROOM = "bedroom"
    BATHROOM = "bathroom"
    HALLWAY = "hallway"


class ColliderKind(StrEnum):
    AUTO = "auto"      # convex hull if near-convex, else CoACD decomposition
    HULL = "hull"
    COACD = "coacd"
    NONE = "none"      # visual only


class CatalogError(ValueError):
    """A catalog or annotation file is invalid; the message names the file and every problem."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, use_enum_values=False)


class AssetAnnotation(_Strict):
    id: str
    source: str
    category: str
    room_types: tuple[RoomType, ...] = ()
    placement: PlacementKind = PlacementKind.ON_FLOOR
    material: MaterialClass = MaterialClass.WOOD
    interactable: bool = False
    co_occurrence: tuple[str, ...] = ()
    mass: float | None = Field(default=None, gt=0.0, description="[kg]")
    up_axis: Literal["Y", "Z"] | None = None
    meters_per_unit: float | None = Field(default=None, gt=0.0)
    collider: ColliderKind = ColliderKind.AUTO
    fixed_base: bool | None = None
    plausible_size: tuple[float, float] | None = Field(default=None, description="[m] largest dimension")
    plausible_mass: tuple[float, float] | None = Field(default=None, description="[kg] total mass")
    mjcf_body: str | None = None

    @field_validator("plausible_size", "plausible_mass")
    @classmethod
    def _range_ok(cls, v: tuple[float, float] | None) -> tuple[float, float] | None:
        if v is not None and not 0.0 < v[0] <= v[1] < float("inf"):
            raise ValueError(f"range {list(v)} must be [low, high] with 0 < low <= high")
        return v

    @field_validator("id")
    @classmethod
    def _id_ok(cls, v: str) -> str:
        if not _ID_RE.match(v):
            raise ValueError(f"asset id {v!r} must match [a-z0-9][a-z0-9_]* (at most 64 characters)")
        return v

    @field_validator("source")
    @classmethod
    def _source_ok(cls, v: str) -> str:
        p = PurePosixPath(v.replace("\\", "/"))
        if p.is_absolute() or re.match(r"^[A-Za-z]:", v):
            raise ValueError(f"source {v!r} is absolute; it must be relative to the catalog folder")
        if ".." in p.parts:
            raise ValueError(f"source {v!r} escapes the catalog folder ('..')")
        if p.suffix.lower() not in SOURCE_SUFFIXES:
            raise ValueError(f"source {v!r} has unsupported type; expected one of {', '.join(SOURCE_SUFFIXES)}")
        return str(p)


class CatalogFile(_Strict):
    defaults: dict = Field(default_factory=dict)
    asset: tuple[AssetAnnotation, ...] = ()


def resolve_source(catalog_dir: Path, source: str) -> Path:
    """The absolute path of ``source`` inside ``catalog_dir``; raises CatalogError if it escapes
    the folder (also through symbolic links)."""
    root = catalog_dir.resolve()
    path = (root / source).resolve()
    if not path.is_relative_to(root):
        raise CatalogError(f"{catalog_dir / ANNOTATION_FILENAME}: source {source!r} escapes the catalog folder")
    return path


@dataclass(frozen=True)
class InvalidEntry:
    """An ``[[asset]]`` entry that failed validation: it fails alone, the rest of the catalog goes on."""

    index: int
    id: str
    reason: str


@dataclass(frozen=True)
class LoadedCatalog:
    path: Path
    assets: tuple[AssetAnnotation, ...]
    invalid: tuple[InvalidEntry, ...]


def load_annotations(catalog_dir: Path, annotations_file: Path | None = None) -> LoadedCatalog:
    """Read and validate ``<catalog_dir>/annotations.toml`` (or ``annotations_file``, an explicit
    annotation file kept elsewhere; sources still resolve against ``catalog_dir``).

    A file-level problem (missing, not TOML, unknown top-level key, bad [defaults]) raises one
    CatalogError naming the file. A bad ``[[asset]]`` entry is returned in ``invalid`` with a one-line
    reason naming the file and every problem of that entry; the other entries load.
    """
    path = Path(annotations_file) if annotations_file is not None else Path(catalog_dir) / ANNOTATION_FILENAME
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CatalogError(f"{path}: annotation file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise CatalogError(f"{path}: not valid TOML: {e}") from None
    unknown = set(raw) - {"defaults", "asset"}
    if unknown:
        raise CatalogError(f"{path}: unknown top-level key(s): {', '.join(sorted(unknown))}")
    defaults = raw.get("defaults", {})
    if not isinstance(defaults, dict) or {"id", "source"} & set(defaults):
        raise CatalogError(f"{path}: [defaults] must be a table without 'id' or 'source'")
    entries = raw.get("asset", [])
    if not isinstance(entries, list):
        raise CatalogError(f"{path}: 'asset' must be an array of tables ([[asset]])")
    assets: list[AssetAnnotation] = []
    invalid: list[InvalidEntry] = []
    seen: set[str] = set()
    for i, entry in enumerate(entries):
        ident = str(entry.get("id", f"#{i}")) if isinstance(entry, dict) else f"#{i}"
        try:
            a = AssetAnnotation.model_validate({**defaults, **entry})
        except ValidationError as e:
            msgs = [f"{'.'.join(str(x) for x in err['loc']) or 'entry'}: {err['msg']}" for err in e.errors()]
            invalid.append(InvalidEntry(i, ident, f"{path}: asset {ident!r}: " + "; ".join(msgs)))
            continue
        if a.id in seen:
            invalid.append(InvalidEntry(i, ident, f"{path}: asset {ident!r}: duplicate id"))
            continue
        seen.add(a.id)
        assets.append(a)
    return LoadedCatalog(path=path, assets=tuple(assets), invalid=tuple(invalid))
