"""Asset package writing speed: a package of about 5,000 prims.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_usd_write.py -s``.
Prints the figures and writes ``bench_results/usd_write.json`` (medians over REPEATS runs):

- ``package``: the whole ``write_asset_package`` (plan, Sdf authoring in a ChangeBlock, export of
  the usdc payload and usda root layer);
- ``sdf_authoring``: the authoring of the payload layer alone (Sdf API inside one ChangeBlock);
- ``usd_api_baseline``: the same meshes authored prim by prim with the Usd API (UsdGeom.Mesh.Define
  and attribute Set calls), the way the style guide says not to.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

REPO = Path(__file__).resolve().parents[2]
for _p in (str(REPO / "tests" / "usd_schemas"), str(REPO)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import usd_schemas  # noqa: E402
import usd_test_models as M  # noqa: E402
from asset_catalog.asset_model import AssetModel, Link  # noqa: E402

N_MESHES = 2496  # visual meshes; as many collider pieces; + link, groups, materials: ~5,000 prims
REPEATS = 5


def _model() -> AssetModel:
    box = trimesh.creation.box((0.01, 0.01, 0.01))
    visuals, colliders = [], []
    for i in range(N_MESHES):
        moved = box.copy()
        moved.apply_translation((0.02 * (i % 50), 0.02 * (i // 50), 0.0))
        visuals.append(M.part(f"v{i}", moved))
        colliders.append(M.part(f"c{i}", moved))
    link = Link(name="body", visuals=tuple(visuals), colliders=tuple(colliders),
                mass=M.mass_properties([box], 700.0))
    return AssetModel(name="bench_01", annotation=M.annotation("bench_01", "bench"), links=(link,),
                      physics_material=M.WOOD)


def _median(fn, repeats: int = REPEATS) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _usd_api_baseline(plan) -> None:
    from pxr import Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateInMemory()
    for body in plan.bodies:
        UsdGeom.Xform.Define(stage, body.path)
        for m in (*body.meshes, *body.colliders):
            mesh = UsdGeom.Mesh.Define(stage, m.path)
            mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(m.points))
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(m.indices) // 3, 3, dtype=np.int32)))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(m.indices))
            mesh.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(m.extent))
            mesh.CreateSubdivisionSchemeAttr("none")


@pytest.mark.benchmark
def test_bench_usd_write(tmp_path):
    from pxr import Sdf

    from usd_schemas._author import author_payload_layer
    from usd_schemas._plan import plan_package

    model = _model()
    pkg = usd_schemas.write_asset_package(model, tmp_path / "warm", pipeline_version="bench")
    prims = pkg.prim_count
    assert prims >= 5000
    k = iter(range(10**6))
    t_pkg = _median(lambda: usd_schemas.write_asset_package(model, tmp_path / f"p{next(k)}", pipeline_version="bench"))
    plan = plan_package(model, "bench")
    t_plan = _median(lambda: plan_package(model, "bench"))
    t_sdf = _median(lambda: author_payload_layer(Sdf.Layer.CreateAnonymous("b.usdc"), plan))
    t_usd = _median(lambda: _usd_api_baseline(plan), repeats=3)
    t_val = _median(lambda: usd_schemas.validate_package(pkg.root_path), repeats=3)
    result = {
        "prims": prims,
        "meshes": pkg.mesh_count + pkg.collider_count,
        "package_s": t_pkg, "package_prims_per_s": prims / t_pkg,
        "plan_s": t_plan,
        "sdf_authoring_s": t_sdf, "sdf_authoring_prims_per_s": prims / t_sdf,
        "usd_api_baseline_s": t_usd, "usd_api_baseline_prims_per_s": prims / t_usd,
        "validate_s": t_val,
        "repeats": REPEATS,
    }
    out = REPO / "bench_results"
    out.mkdir(exist_ok=True)
    (out / "usd_write.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nusd_write: {prims} prims; package {t_pkg:.3f} s ({prims / t_pkg:,.0f} prims/s); "
          f"plan {t_plan:.3f} s; Sdf authoring in ChangeBlock {t_sdf:.3f} s ({prims / t_sdf:,.0f} prims/s); "
          f"Usd API baseline {t_usd:.3f} s ({prims / t_usd:,.0f} prims/s); validate {t_val:.2f} s")
    assert t_sdf < t_usd
