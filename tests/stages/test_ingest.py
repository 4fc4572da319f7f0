"""Ingest: mesh loaders on real shared assets, bad inputs failing alone, planning, and the job end to end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from asset_catalog.annotations import AssetAnnotation, load_annotations
from ingest_testutil import (SHARED_RIGID_ANNOTATIONS, box_arrays, write_obj, write_stl, write_textured_box)
from pipeline.types import ItemError, PlanContext, PlannedFailure, WorkItem
from stages.loaders import LoadLimits
from stages.loaders.mesh import load_mesh_asset


def _shared(shared_assets: Path, asset_id: str) -> AssetAnnotation:
    anns = {a.id: a for a in load_annotations(shared_assets, SHARED_RIGID_ANNOTATIONS).assets}
    return anns[asset_id]


def _check_normalised(model, dims_expected=None, tol=2e-3):
    pts = np.concatenate([p.vertices for p in model.links[0].visuals])
    lo, hi = pts.min(0), pts.max(0)
    assert lo[2] == pytest.approx(0.0, abs=1e-9)  # bottom at z = 0
    assert (lo[:2] + hi[:2]) / 2 == pytest.approx((0.0, 0.0), abs=1e-9)  # XY centred
    for p in model.links[0].visuals:
        assert p.normals is not None and p.normals.shape == p.vertices.shape
        assert np.linalg.norm(p.normals, axis=1) == pytest.approx(1.0, abs=1e-6)
        assert p.faces.min() >= 0 and p.faces.max() < len(p.vertices)
        assert p.material in model.materials
    if dims_expected is not None:
        assert hi - lo == pytest.approx(dims_expected, abs=tol)


# ------------------------------------------------------------------------------- loaders, real assets


def test_obj_with_mtl_and_texture_ycb(shared_assets):
    a = _shared(shared_assets, "ycb_apple")
    m = load_mesh_asset(shared_assets / a.source, a, catalog_root=shared_assets)
    _check_normalised(m, (0.075, 0.075, 0.072))
    (part,) = m.links[0].visuals
    assert part.uvs is not None and part.uvs.shape == (len(part.vertices), 2)
    (mat,) = m.materials.values()
    assert mat.base_color_texture == ((shared_assets / a.source).parent / "texture_map.png").resolve()
    assert len(m.source_sha256) == 64


def test_obj_texture_outside_the_mesh_folder_but_inside_the_catalog(shared_assets):
    a = _shared(shared_assets, "rs_can")  # map_Kd ../../textures/soda.png
    m = load_mesh_asset(shared_assets / a.source, a, catalog_root=shared_assets)
    _check_normalised(m, (0.05, 0.05, 0.08))
    (mat,) = m.materials.values()
    assert mat.base_color_texture == (shared_assets / "objects_rigid/household__robosuite/textures/soda.png").resolve()


def test_stl_without_normals_gets_computed_normals_and_material_defaults(shared_assets):
    a = _shared(shared_assets, "os_mug")
    m = load_mesh_asset(shared_assets / a.source, a, catalog_root=shared_assets)
    _check_normalised(m, (0.116, 0.082, 0.105))
    (mat,) = m.materials.values()
    assert mat.base_color == pytest.approx((0.92, 0.92, 0.9))  # ceramic default (no material in STL)


def test_gltf_y_up_rotated_and_orm_channels_split(shared_assets):
    from PIL import Image

    a = _shared(shared_assets, "tea_set")
    m = load_mesh_asset(shared_assets / a.source, a, catalog_root=shared_assets)
    _check_normalised(m, (0.452, 0.384, 0.165))  # glTF height (Y) becomes Z
    assert len(m.links[0].visuals) == 8
    (mat,) = m.materials.values()
    assert mat.base_color_texture.name == "tea_set_01_diff_1k.jpg"
    assert mat.normal_texture.name == "tea_set_01_nor_gl_1k.jpg"
    arm = (shared_assets / "objects_rigid/tea_set__polyhaven_via_robotlocomotion/assets/textures"
           / "tea_set_01_arm_1k.jpg")
    with Image.open(mat.roughness_texture) as r, Image.open(arm) as src:
        assert r.mode == "L" and r.size == src.size
        g = np.asarray(src.convert("RGB"))[..., 1]
        assert np.abs(np.asarray(r).astype(int) - g).max() == 0  # roughness = G channel


def test_gltf_ktx2_image_falls_back_to_png(shared_assets):
    a = _shared(shared_assets, "ms_bin")
    m = load_mesh_asset(shared_assets / a.source, a, catalog_root=shared_assets)
    _check_normalised(m, (0.558, 0.418, 0.21))
    (mat,) = m.materials.values()
    assert mat.base_color_texture.name == "bin.png"


def test_ply_and_glb_with_embedded_texture(tmp_path):
    import trimesh
    from PIL import Image

    box = trimesh.creation.box(extents=(0.2, 0.1, 0.3))
    write_stl(tmp_path / "box.ply", box)
    a = AssetAnnotation(id="box", source="box.ply", category="box", material="plastic")
    _check_normalised(load_mesh_asset(tmp_path / "box.ply", a), (0.2, 0.1, 0.3))
    # GLB (Y-up) with its texture embedded in the binary chunk
    uv = np.random.default_rng(0).uniform(size=(len(box.vertices), 2))
    img = Image.new("RGB", (4, 4), (10, 200, 30))
    tex = trimesh.Trimesh(box.vertices, box.faces, visual=trimesh.visual.TextureVisuals(
        uv=uv, material=trimesh.visual.material.PBRMaterial(name="paint", baseColorTexture=img)),
        process=False)
    tex.export(tmp_path / "box.glb")
    g = AssetAnnotation(id="boxg", source="box.glb", category="box")
    m = load_mesh_asset(tmp_path / "box.glb", g, texture_cache=tmp_path / "cache")
    _check_normalised(m, (0.2, 0.3, 0.1))  # glTF Y-up: y (0.1) becomes the height, z (0.3) the depth
    (mat,) = m.materials.values()
    assert mat.base_color_texture.parent == tmp_path / "cache" and mat.base_color_texture.is_file()


def test_annotated_units_and_up_axis(tmp_path):
    v, f = box_arrays((100.0, 200.0, 50.0))  # millimetres
    write_obj(tmp_path / "mm.obj", v, f)
    a = AssetAnnotation(id="mm", source="mm.obj", category="box", meters_per_unit=0.001, up_axis="Y")
    _check_normalised(load_mesh_asset(tmp_path / "mm.obj", a), (0.1, 0.05, 0.2), tol=1e-9)


# ------------------------------------------------------------------------------------- bad inputs


def _write_bad(kind: str, folder: Path) -> tuple[str, str]:
    """Write one bad source into ``folder``; returns (source relative to folder, expected message part)."""
    v, f = box_arrays((0.1, 0.1, 0.1))
    if kind == "nan":
        v = v.copy()
        v[3, 1] = np.nan
        write_obj(folder / "nan.obj", v, f)
        return "nan.obj", "NaN or infinite"
    if kind == "empty":
        (folder / "empty.obj").write_text("")
        return "empty.obj", "empty file"
    if kind == "no_faces":
        (folder / "nofaces.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
        return "nofaces.obj", "no triangles"
    if kind == "flat":
        quad = [[0, 0, 0], [0.3, 0, 0], [0.3, 0.2, 0], [0, 0.2, 0]]
        write_obj(folder / "flat.obj", quad, [[0, 1, 2], [0, 2, 3]])
        return "flat.obj", "zero volume"
    if kind == "degenerate":
        line = [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.3, 0, 0]]
        write_obj(folder / "degenerate.obj", line, [[0, 1, 2], [1, 2, 3]])
        return "degenerate.obj", "zero area"
    if kind == "missing_texture":
        write_textured_box(folder / "mt", "missing", texture=False)
        return "mt/missing.obj", "'missing.png' not found"
    if kind == "unreadable_texture":
        write_textured_box(folder / "ut", "corrupt", texture=False)
        (folder / "ut" / "corrupt.png").write_bytes(b"not a png at all")
        return "ut/corrupt.obj", "unreadable"
    if kind == "texture_escapes":
        write_textured_box(folder / "te", "esc", texture=False)
        (folder / "te" / "esc.mtl").write_text("newmtl mat0\nmap_Kd ../../outside.png\n")
        return "te/esc.obj", "escapes the catalog folder"
    if kind == "millimetres":
        write_obj(folder / "mm.obj", v * 1000, f)
        return "mm.obj", "set meters_per_unit"
    if kind == "microscopic":
        write_obj(folder / "tiny.obj", v * 0.005, f)
        return "tiny.obj", "absurd scale"
    if kind == "corrupt":
        (folder / "corrupt.stl").write_bytes(b"\x00\x01garbage" * 3)
        return "corrupt.stl", "no triangles"  # trimesh reads no triangle out of it
    if kind == "bad_index":
        (folder / "badidx.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 9\n")
        return "badidx.obj", "mesh"
    raise AssertionError(kind)


BAD_KINDS = ["nan", "empty", "no_faces", "flat", "degenerate", "missing_texture", "unreadable_texture",
             "texture_escapes", "millimetres", "microscopic", "corrupt", "bad_index"]


@pytest.mark.parametrize("kind", BAD_KINDS)
def test_bad_mesh_input_is_a_one_line_item_error_naming_the_file(tmp_path, kind):
    cat = tmp_path / "catalog"
    cat.mkdir()
    rel, expected = _write_bad(kind, cat)
    a = AssetAnnotation(id="bad", source=rel, category="thing")
    with pytest.raises(ItemError) as e:
        load_mesh_asset(cat / rel, a, catalog_root=cat)
    msg = str(e.value)
    assert "\n" not in msg and expected in msg
    assert str(cat / rel) in msg or Path(rel).name in msg or Path(rel).with_suffix(".mtl").name in msg


def test_oversized_file_rejected_with_configured_limit(tmp_path):
    v, f = box_arrays()
    write_obj(tmp_path / "box.obj", v, f)
    a = AssetAnnotation(id="box", source="box.obj", category="box")
    with pytest.raises(ItemError, match=r"box\.obj: file is .* MiB, over the 0.0001 MiB limit"):
        load_mesh_asset(tmp_path / "box.obj", a, limits=LoadLimits(max_file_mb=0.0001))


# --------------------------------------------------------------------------------- plan + end to end


def _bad_catalog(root: Path) -> tuple[Path, dict[str, str], list[str]]:
    """A catalog with good sources, every kind of bad source and bad entries; returns (folder,
    {bad id: expected reason part}, good ids)."""
    import trimesh

    cat = root / "catalog"
    cat.mkdir(parents=True)
    write_textured_box(cat / "good", "box")
    write_stl(cat / "good" / "ball.stl", trimesh.creation.icosphere(subdivisions=2, radius=0.04))
    v, f = box_arrays((0.3, 0.2, 0.1))
    write_obj(cat / "good" / "plain.obj", v, f)
    entries = [("good_box", "good/box.obj"), ("good_ball", "good/ball.stl"), ("good_plain", "good/plain.obj")]
    expected: dict[str, str] = {}
    for kind in BAD_KINDS:
        rel, exp = _write_bad(kind, cat)
        entries.append((f"bad_{kind}", rel))
        expected[f"bad_{kind}"] = exp
    big = write_stl(cat / "big.stl", trimesh.creation.icosphere(subdivisions=5, radius=0.1))  # > 0.5 MiB
    assert big.stat().st_size > 600_000
    entries.append(("bad_oversized", "big.stl"))
    expected["bad_oversized"] = "limit"
    lines = [f'[[asset]]\nid = "{i}"\nsource = "{s}"\ncategory = "thing"\nmaterial = "plastic"\n'
             for i, s in entries]
    lines.append('[[asset]]\nid = "bad_escape"\nsource = "../outside.obj"\ncategory = "thing"\n')
    absolute = cat / "good" / "box.obj"
    lines.append(f'[[asset]]\nid = "bad_absolute"\nsource = "{absolute}"\ncategory = "thing"\n')
    lines.append('[[asset]]\nid = "bad_missing"\nsource = "nowhere/ghost.obj"\ncategory = "thing"\n')
    expected.update(bad_escape="escapes the catalog folder", bad_absolute="is absolute",
                    bad_missing="not found")
    (cat / "annotations.toml").write_text("\n".join(lines), encoding="utf-8")
    return cat, expected, ["good_ball", "good_box", "good_plain"]


def test_plan_items_reference_files_and_planned_failures(tmp_path):
    from stages.ingest import IngestConfig, plan_ingest

    cat, _, _ = _bad_catalog(tmp_path)
    pctx = PlanContext(job_file=tmp_path / "job.toml", job_dir=tmp_path, work_dir=tmp_path / "out", seed=0)
    planned = plan_ingest(IngestConfig(catalog=cat), pctx)
    items = {p.item_id: p for p in planned if isinstance(p, WorkItem)}
    fails = {p.item_id: p.reason for p in planned if isinstance(p, PlannedFailure)}
    assert set(fails) == {"bad_escape", "bad_absolute", "bad_missing"}
    assert "escapes the catalog folder" in fails["bad_escape"] and "absolute" in fails["bad_absolute"]
    assert "ghost.obj" in fails["bad_missing"]
    box = items["good_box"]
    names = {Path(p).name for p in box.input_files}
    assert names == {"box.obj", "box.mtl", "box.png"}  # edits to the MTL or texture invalidate the cache
    assert box.params.annotation.id == "good_box" and box.params.source == (cat / "good/box.obj").resolve()
    only = plan_ingest(IngestConfig(catalog=cat, only=("good_ball",)), pctx)
    assert [p.item_id for p in only] == ["good_ball"]


def _run_ingest(cat: Path, out: Path, *, annotations: Path | None = None, only=(),
                max_file_mb: float | None = None, executor: str = "inline", workers: int = 1):
    from pipeline import build_job, run_job

    config: dict = {"catalog": str(cat)}
    if annotations is not None:
        config["annotations"] = str(annotations)
    if only:
        config["only"] = list(only)
    if max_file_mb is not None:
        config["limits"] = {"max_file_mb": max_file_mb}
    data = {"job": {"name": "ingest", "seed": 0, "out": str(out), "executor": executor, "workers": workers},
            "step": [{"name": "assets", "kind": "ingest", "config": config}]}
    return run_job(build_job(data, source="<test>", base_dir=out.parent), progress=False)


def test_ingest_job_bad_assets_fail_alone_and_the_rest_ingest(tmp_path):
    from asset_catalog.index import index_path, query_index

    cat, expected, good = _bad_catalog(tmp_path)
    out = tmp_path / "out"
    summary = _run_ingest(cat, out, max_file_mb=0.5)
    (step,) = summary.steps
    reasons = {f.item_id: f.reason for f in step.failures}
    assert step.done == len(good) and set(reasons) == set(expected), reasons
    for iid, part in expected.items():
        r = reasons[iid]
        assert part in r and "\n" not in r, (iid, r)
        assert not (out / "assets" / iid).exists()  # no half-written output of a failed asset
    for iid in good:
        assert (out / "assets" / iid / f"{iid}.usda").is_file()
    assert not any((out / "assets" / ".tmp").glob("*")) if (out / "assets" / ".tmp").exists() else True
    ok = query_index(index_path(out), status="ok")
    failed = query_index(index_path(out), status="failed")
    assert [r.id for r in ok] == good and {r.id for r in failed} == set(expected)
    box = next(r for r in ok if r.id == "good_box")
    assert box.usd_path == "assets/good_box/good_box.usda" and box.collider == "convexHull"
    assert box.mass == pytest.approx(1100 * 1e-3, rel=1e-3) and box.dimensions == pytest.approx((0.1,) * 3)
    assert (out / "assets/good_box/textures").is_dir()  # texture copied beside the asset
    # a second run does no work
    again = _run_ingest(cat, out, max_file_mb=0.5)
    assert again.steps[0].done == 0 and again.steps[0].cached == len(good)
    # editing a texture re-ingests just that asset
    from PIL import Image

    Image.new("RGB", (8, 8), (0, 0, 255)).save(cat / "good" / "box.png")
    third = _run_ingest(cat, out, max_file_mb=0.5)
    assert third.steps[0].done == 1 and third.steps[0].cached == len(good) - 1


SUBSET = ("ycb_apple", "rs_can", "os_flashlight", "ms_table_wide")


def test_ingest_shared_subset_then_rest_check(shared_assets, tmp_path):
    """A few real shared assets through the runner; each output validates, and (where Newton's USD
    importer is installed) comes to rest on a plane."""
    import usd_schemas
    from asset_catalog.index import index_path, query_index

    out = tmp_path / "out"
    summary = _run_ingest(shared_assets, out, annotations=SHARED_RIGID_ANNOTATIONS, only=SUBSET)
    (step,) = summary.steps
    assert step.failed == 0 and step.done == len(SUBSET), step.failures
    recs = {r.id: r for r in query_index(index_path(out))}
    assert set(recs) == set(SUBSET)
    assert recs["ycb_apple"].collider == "convexHull" and 0.1 < recs["ycb_apple"].mass < 0.4
    assert recs["ms_table_wide"].dimensions == pytest.approx((1.5, 2.182, 1.0), abs=2e-3)
    for r in recs.values():
        report = usd_schemas.validate_package(out / r.usd_path)
        assert report.ok, report.summary()
    pytest.importorskip("newton_usd_schemas", reason="Newton's add_usd needs newton-usd-schemas")
    from stages.physics_checks import rest_check

    for r in recs.values():
        rep = rest_check(out / r.usd_path)
        assert rep.passed, (r.id, rep.reasons)


@pytest.mark.slow
def test_ingest_every_shared_rigid_asset(shared_assets, tmp_path):
    """Every rigid object and furniture entry of the shared assets ingests, validates and rests."""
    import usd_schemas
    from asset_catalog.index import index_path, query_index

    n = len(load_annotations(shared_assets, SHARED_RIGID_ANNOTATIONS).assets)
    out = tmp_path / "out"
    summary = _run_ingest(shared_assets, out, annotations=SHARED_RIGID_ANNOTATIONS, executor="local",
                          workers=2)
    (step,) = summary.steps
    assert step.failed == 0 and step.done == n, step.failures
    recs = query_index(index_path(out))
    assert len(recs) == n
    for r in recs:
        assert usd_schemas.validate_package(out / r.usd_path).ok
    if _has_newton_usd():
        from stages.physics_checks import rest_check

        reports = {r.id: rest_check(out / r.usd_path) for r in recs}
        failures = {k: rep.reasons for k, rep in reports.items() if not rep.passed}
        assert set(failures) <= set(KNOWN_REST_ISSUES), failures
        for k, rep in reports.items():  # the stiff contacts: resting depth well under the 3 mm bound
            assert k in KNOWN_REST_ISSUES or rep.settled_min_height > -0.001, (k, rep.settled_min_height)


# Assets that ingest and validate but whose rest check (stages.physics_checks) flags them, with why
# (seen on CPU, MuJoCo solver); open items, not accepted behaviour. Empty since the check's contacts
# are stiff (solref 0.01 s, solimp 0.99): os_mouse / ycb_dice no longer micro-rock on MuJoCo's 3
# switching plane-mesh contacts, os_toothpaste's topple sinks 3.9 mm (was 12.6 mm, tolerance 10 mm).
KNOWN_REST_ISSUES: dict[str, str] = {}


def _has_newton_usd() -> bool:
    try:
        import newton_usd_schemas  # noqa: F401
    except ImportError:
        return False
    return True


def test_plan_reads_the_catalog_of_an_earlier_step(tmp_path):
    from stages.catalog import DefaultCatalogResult
    from stages.ingest import IngestConfig, plan_ingest

    cat = tmp_path / "cat"
    write_textured_box(cat, "box")
    (cat / "annotations.toml").write_text('[[asset]]\nid = "box"\nsource = "box.obj"\ncategory = "box"\n')
    prev = DefaultCatalogResult(catalog_dir=str(cat), asset_ids=("box",), categories=("box",), n_files=3,
                                seconds=0.0)
    pctx = PlanContext(job_file=tmp_path / "j.toml", job_dir=tmp_path, work_dir=tmp_path / "out", seed=0,
                       previous={"catalog": {"default": prev}})
    (item,) = plan_ingest(IngestConfig(catalog_step="catalog"), pctx)
    assert item.item_id == "box" and item.params.catalog_dir == cat.resolve()
    with pytest.raises(ValueError, match="exactly one"):
        IngestConfig(catalog=cat, catalog_step="catalog")
