"""The package-shape cache (``stages.scene.shapecache``): a package's AssetGeometry is read from its
USD once per package content and then from disk in other processes, identical to reading the USD;
a changed package is read again."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

_PROBE = """
import json, sys
from pathlib import Path
from stages.scene import shapecache
g = shapecache.geometry(Path(sys.argv[1]), Path(sys.argv[2]))
print(json.dumps({"stats": shapecache.stats, "n": len(g.pieces), "lo": g.lo.tolist(), "hi": g.hi.tolist(),
                  "surfaces": len(g.surfaces), "flat": bool(g.rests_flat), "mass": g.mass}))
"""


def _probe(usd: Path, root: Path) -> dict:
    out = subprocess.run([sys.executable, "-c", _PROBE, str(usd), str(root)], cwd=ROOT, capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> Path:
    from asset_catalog.index import query_index
    from stages.scene.standin import build_library

    out = tmp_path_factory.mktemp("lib")
    idx = build_library(out, categories=["nightstand"], variants=1)
    return out / query_index(idx)[0].usd_path


def test_shape_cache_across_processes_and_invalidated_on_change(package: Path, tmp_path: Path) -> None:
    root = tmp_path / "cache"
    first = _probe(package, root)
    assert first["stats"] == {"hits": 0, "misses": 1}
    assert len(list((root / "shape_v1").glob("*.npz"))) == 1
    second = _probe(package, root)  # another process: from disk, the USD not read
    assert second["stats"] == {"hits": 1, "misses": 0}
    assert {k: v for k, v in second.items() if k != "stats"} == {k: v for k, v in first.items() if k != "stats"}
    with package.open("a", encoding="utf-8") as f:  # the package changes: a new entry
        f.write("\n")
    third = _probe(package, root)
    assert third["stats"] == {"hits": 0, "misses": 1}
    assert len(list((root / "shape_v1").glob("*.npz"))) == 2


def test_cached_geometry_equals_the_usd_reading(package: Path, tmp_path: Path) -> None:
    from stages.scene import shapecache
    from stages.scene.assets import load_asset_geometry

    shapecache.geometry(package, tmp_path)  # writes the entry
    shapecache._MEM.clear()
    got, want = shapecache.geometry(package, tmp_path), load_asset_geometry(package)
    assert got is not want
    assert got.moving == want.moving and (got.dynamic, got.n_bodies, got.neutral_joints) == (
        want.dynamic, want.n_bodies, want.neutral_joints)
    for a, b in zip(got.pieces, want.pieces, strict=True):
        for f in ("vertices", "normals", "edges", "lo", "hi"):
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    for a, b in zip(got.surfaces, want.surfaces, strict=True):
        assert a.z == b.z
        np.testing.assert_array_equal(a.polygon, b.polygon)
    for a, b in zip(got.swings, want.swings, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(got.footprint, want.footprint)
    assert got.rests_flat == want.rests_flat and got.mass == want.mass
    np.testing.assert_array_equal(got.com, want.com)
