"""The SQLite catalog index: write, query by category / room / placement / interactable / status."""

from __future__ import annotations

import sqlite3

import pytest
from pydantic import ValidationError

from asset_catalog.index import CatalogRecord, get_record, index_path, query_index, write_index


def _ok(i: str, category: str, rooms: tuple[str, ...], placement: str = "on_floor", **kw) -> CatalogRecord:
    return CatalogRecord(id=i, category=category, room_types=rooms, placement=placement, material="wood",
                         usd_path=f"assets/{i}/{i}.usda", bbox_min=(-0.5, -0.25, 0.0), bbox_max=(0.5, 0.25, 0.8),
                         dimensions=(1.0, 0.5, 0.8), volume=0.05, mass=35.0, static_friction=0.44,
                         dynamic_friction=0.4, restitution=0.3, collider="convexHull", n_colliders=1,
                         source=f"{i}.obj", source_sha256="ab" * 32, **kw)


RECORDS = [
    _ok("table_01", "table", ("kitchen", "living_room")),
    _ok("mug_01", "mug", ("kitchen",), "on_surface", interactable=True, co_occurrence=("table",)),
    _ok("mug_02", "mug", ("kitchen", "living_room"), "on_surface", interactable=True),
    _ok("cabinet_01", "cabinet", ("kitchen",), "against_wall", is_articulated=True, n_joints=2),
    CatalogRecord(id="mug_bad", category="mug", room_types=("kitchen",), status="failed",
                  error="mugs/bad.obj: mesh has NaN vertices", source="mugs/bad.obj"),
]


@pytest.fixture
def db(tmp_path):
    return write_index(index_path(tmp_path), RECORDS)


def _ids(recs):
    return [r.id for r in recs]


def test_roundtrip_preserves_every_field(db):
    assert db.name == "catalog.sqlite"
    back = {r.id: r for r in query_index(db, status=None)}
    assert back == {r.id: r for r in RECORDS}
    assert get_record(db, "cabinet_01") == RECORDS[3] and get_record(db, "nope") is None


def test_filters(db):
    assert _ids(query_index(db)) == ["cabinet_01", "mug_01", "mug_02", "table_01"]        # ok only, by id
    assert _ids(query_index(db, category="mug")) == ["mug_01", "mug_02"]
    assert _ids(query_index(db, category="mug", room="living_room")) == ["mug_02"]
    assert _ids(query_index(db, room="kitchen", placement="against_wall")) == ["cabinet_01"]
    assert _ids(query_index(db, interactable=True)) == ["mug_01", "mug_02"]
    assert _ids(query_index(db, interactable=False)) == ["cabinet_01", "table_01"]
    assert _ids(query_index(db, status="failed")) == ["mug_bad"]
    assert query_index(db, status="failed")[0].error == "mugs/bad.obj: mesh has NaN vertices"
    assert query_index(db, category="sofa") == []


def test_rewrite_replaces_atomically_and_leaves_no_temp(tmp_path, db):
    write_index(db, RECORDS[:2])
    assert _ids(query_index(db, status=None)) == ["mug_01", "table_01"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["catalog.sqlite"]
    con = sqlite3.connect(db)
    assert con.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone() == ("1",)
    con.close()


def test_duplicate_ids_rejected_and_old_index_kept(tmp_path, db):
    with pytest.raises(ValueError, match="duplicate asset id.*mug_01"):
        write_index(db, [RECORDS[1], RECORDS[1]])
    assert len(query_index(db, status=None)) == 5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["catalog.sqlite"]


def test_record_validation():
    with pytest.raises(ValidationError, match="needs an error reason"):
        CatalogRecord(id="x", status="failed")
    with pytest.raises(ValidationError, match="relative to the work dir"):
        CatalogRecord(id="x", usd_path="/abs/x.usda")
    with pytest.raises(ValidationError):
        CatalogRecord(id="x", collider="sphere")
    with pytest.raises(ValidationError):
        CatalogRecord(id="x", restitution=1.5)


def test_missing_index(tmp_path):
    with pytest.raises(FileNotFoundError, match="catalog index not found"):
        query_index(tmp_path / "catalog.sqlite")
