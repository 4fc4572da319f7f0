"""The catalog index: one SQLite file (``<work_dir>/catalog.sqlite``) listing every asset of a catalog,
ingested or failed, with its annotations and computed physical properties.

Written once per ingest run by the ingest job kind's ``finalize`` (``write_index``: a new file under a
temporary name, renamed over the old one, so readers never see a half-written index) and queried by
later stages and by ``agentworld catalog list`` (``query_index``).

Tables: ``assets`` (one row per asset; list and vector fields as JSON text), ``asset_rooms``
(asset id, room type) for room queries, ``meta`` (schema version, write time).
"""

from __future__ import annotations

import json
import os
import sqlite3
import time
from collections import Counter
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

INDEX_FILENAME = "catalog.sqlite"
SCHEMA_VERSION = 1

Vec3 = tuple[float, float, float]


class CatalogRecord(BaseModel):
    """One asset of the catalog index.

    id, category, room_types, placement, material, interactable, co_occurrence: from the annotation file
    (enum values as strings); status: "ok" or "failed" (then ``error`` is the one-line reason and the
    computed fields may be None); usd_path: the asset package's root layer, relative to the work dir
    (POSIX separators); bbox_min / bbox_max: axis-aligned bounds [m] in the asset frame (Z up);
    dimensions: bbox extent (x, y, z) [m]; volume [m^3]; mass [kg]; static_friction, dynamic_friction,
    restitution [-]; collider: "convexHull" | "convexDecomposition" | "none"; n_colliders: number of
    convex collider prims; is_articulated / n_joints: joints of the source; source: source file,
    relative to the catalog folder; source_sha256: its content hash.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str = Field(min_length=1)
    category: str = ""
    room_types: tuple[str, ...] = ()
    placement: str = ""
    material: str = ""
    interactable: bool = False
    co_occurrence: tuple[str, ...] = ()
    status: Literal["ok", "failed"] = "ok"
    error: str = ""
    usd_path: str | None = None
    bbox_min: Vec3 | None = None
    bbox_max: Vec3 | None = None
    dimensions: Vec3 | None = None
    volume: float | None = Field(default=None, ge=0.0)
    mass: float | None = Field(default=None, ge=0.0)
    static_friction: float | None = Field(default=None, ge=0.0)
    dynamic_friction: float | None = Field(default=None, ge=0.0)
    restitution: float | None = Field(default=None, ge=0.0, le=1.0)
    collider: Literal["convexHull", "convexDecomposition", "none"] | None = None
    n_colliders: int = Field(default=0, ge=0)
    is_articulated: bool = False
    n_joints: int = Field(default=0, ge=0)
    source: str = ""
    source_sha256: str = ""

    @model_validator(mode="after")
    def _consistent(self) -> "CatalogRecord":
        if self.status == "failed" and not self.error:
            raise ValueError(f"asset {self.id!r}: a failed record needs an error reason")
        if self.status == "ok" and self.error:
            raise ValueError(f"asset {self.id!r}: an ok record has an error ({self.error!r})")
        if self.usd_path is not None and (self.usd_path.startswith("/") or "\\" in self.usd_path):
            raise ValueError(f"asset {self.id!r}: usd_path must be relative to the work dir, POSIX style")
        return self


_SCALAR = ("id", "category", "placement", "material", "interactable", "status", "error", "usd_path", "volume",
           "mass", "static_friction", "dynamic_friction", "restitution", "collider", "n_colliders",
           "is_articulated", "n_joints", "source", "source_sha256")
_JSON = ("room_types", "co_occurrence", "bbox_min", "bbox_max", "dimensions")
_COLUMNS = _SCALAR + _JSON

_SCHEMA = f"""
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE assets (
    id TEXT PRIMARY KEY, category TEXT NOT NULL, placement TEXT NOT NULL, material TEXT NOT NULL,
    interactable INTEGER NOT NULL, status TEXT NOT NULL, error TEXT NOT NULL, usd_path TEXT,
    volume REAL, mass REAL, static_friction REAL, dynamic_friction REAL, restitution REAL, collider TEXT,
    n_colliders INTEGER NOT NULL, is_articulated INTEGER NOT NULL, n_joints INTEGER NOT NULL,
    source TEXT NOT NULL, source_sha256 TEXT NOT NULL,
    {", ".join(f"{c} TEXT" for c in _JSON)}
);
CREATE TABLE asset_rooms (id TEXT NOT NULL REFERENCES assets(id), room TEXT NOT NULL, PRIMARY KEY (id, room));
CREATE INDEX assets_category ON assets (category);
CREATE INDEX asset_rooms_room ON asset_rooms (room);
"""


def index_path(work_dir: str | Path) -> Path:
    """The default index file of a work directory: ``<work_dir>/catalog.sqlite``."""
    return Path(work_dir) / INDEX_FILENAME


def write_index(db_path: str | Path, records: Iterable[CatalogRecord]) -> Path:
    """Write the index (replacing any old one) atomically: build a temporary file, then rename it.

    Raises ValueError naming the id if two records share an id. Returns the index path.
    """
    db_path = Path(db_path)
    recs = sorted(records, key=lambda r: r.id)
    dup = sorted(i for i, n in Counter(r.id for r in recs).items() if n > 1)
    if dup:
        raise ValueError(f"{db_path}: duplicate asset id(s) in the catalog index: {', '.join(dup)}")
    db_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = db_path.with_name(f".{db_path.name}.{os.getpid()}.tmp")
    tmp.unlink(missing_ok=True)
    con = sqlite3.connect(tmp)
    try:
        con.executescript(_SCHEMA)
        with con:
            con.executemany("INSERT INTO meta VALUES (?, ?)",
                            [("schema_version", str(SCHEMA_VERSION)), ("written_at", f"{time.time():.3f}")])
            cols, marks = ", ".join(_COLUMNS), ", ".join("?" * len(_COLUMNS))
            con.executemany(f"INSERT INTO assets ({cols}) VALUES ({marks})", [_row(r) for r in recs])
            con.executemany("INSERT INTO asset_rooms VALUES (?, ?)",
                            [(r.id, room) for r in recs for room in sorted(set(r.room_types))])
    except BaseException:
        con.close()
        tmp.unlink(missing_ok=True)
        raise
    con.close()
    os.replace(tmp, db_path)
    return db_path


def query_index(db_path: str | Path, category: str | None = None, room: str | None = None,
                placement: str | None = None, interactable: bool | None = None,
                status: Literal["ok", "failed"] | None = "ok") -> list[CatalogRecord]:
    """Records matching every given filter (None = any), ordered by id.

    room: the asset lists this room type; status: "ok" (default), "failed", or None for both.
    """
    db_path = Path(db_path)
    if not db_path.is_file():
        raise FileNotFoundError(f"{db_path}: catalog index not found")
    where, args = [], []
    for col, val in (("category", category), ("placement", placement), ("status", status)):
        if val is not None:
            where.append(f"a.{col} = ?")
            args.append(str(val))
    if interactable is not None:
        where.append("a.interactable = ?")
        args.append(int(interactable))
    if room is not None:
        where.append("EXISTS (SELECT 1 FROM asset_rooms r WHERE r.id = a.id AND r.room = ?)")
        args.append(str(room))
    sql = f"SELECT {', '.join('a.' + c for c in _COLUMNS)} FROM assets a"
    if where:
        sql += " WHERE " + " AND ".join(where)
    con = sqlite3.connect(f"file:{db_path}?mode=ro", uri=True)
    try:
        rows = con.execute(sql + " ORDER BY a.id", args).fetchall()
    finally:
        con.close()
    return [_record(r) for r in rows]


def get_record(db_path: str | Path, asset_id: str) -> CatalogRecord | None:
    """The record of one asset (any status), or None."""
    con = sqlite3.connect(f"file:{Path(db_path)}?mode=ro", uri=True)
    try:
        row = con.execute(f"SELECT {', '.join(_COLUMNS)} FROM assets WHERE id = ?", (asset_id,)).fetchone()
    finally:
        con.close()
    return _record(row) if row else None


def _row(r: CatalogRecord) -> tuple:
    d = r.model_dump(mode="json")
    return tuple(d[c] for c in _SCALAR) + tuple(json.dumps(d[c]) for c in _JSON)


def _record(row: Sequence) -> CatalogRecord:
    d = dict(zip(_COLUMNS, row, strict=True))
    for c in _JSON:
        d[c] = json.loads(d[c]) if d[c] is not None else None
    for c in ("room_types", "co_occurrence"):
        d[c] = tuple(d[c] or ())
    d["interactable"] = bool(d["interactable"])
    d["is_articulated"] = bool(d["is_articulated"])
    return CatalogRecord.model_validate(d)
