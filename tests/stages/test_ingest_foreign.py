"""Ingest of patterns common in other public packages (issue 18): MJCF bodies hinged to the world or
several top-level bodies, and sources authored in the wrong unit."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

# ------------------------------------------------------------------------------------------ helpers


def _run_ingest(cat: Path, out: Path):
    from pipeline import build_job, run_job

    data = {"job": {"name": "ingest", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
            "step": [{"name": "assets", "kind": "ingest", "config": {"catalog": str(cat)}}]}
    return run_job(build_job(data, source="<test>", base_dir=out.parent), progress=False)


def _catalog(cat: Path, entries: list[dict]) -> None:
    lines = []
    for e in entries:
        lines.append("[[asset]]")
        lines += [f"{k} = {v!r}".replace("'", '"') if not isinstance(v, bool) else f"{k} = {str(v).lower()}"
                  for k, v in e.items()]
        lines.append("")
    (cat / "annotations.toml").write_text("\n".join(lines), encoding="utf-8")


def _usd(out: Path, asset_id: str):
    """(stage, {joint prim name: prim}, [rigid body names]) of an ingested package."""
    from pxr import Usd, UsdPhysics

    stage = Usd.Stage.Open(str(out / "assets" / asset_id / f"{asset_id}.usda"))
    joints = {p.GetName(): p for p in stage.Traverse() if p.IsA(UsdPhysics.Joint)}
    bodies = [p.GetName() for p in stage.Traverse() if p.HasAPI(UsdPhysics.RigidBodyAPI)]
    return stage, joints, bodies


# ---------------------------------------------------------------------------- MJCF: wrapping the world

_HINGED_DOOR = """<mujoco model="door">
  <compiler angle="degree"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1"/>
    <geom name="frame" type="box" pos="0 -0.02 1" size="0.45 0.02 1" mass="20"/>
    <body name="leaf" pos="0.4 0 1">
      <joint name="door_hinge" type="hinge" axis="0 0 1" range="0 100" damping="2"/>
      <geom type="box" pos="-0.4 0.03 0" size="0.4 0.02 0.95" mass="8"/>
    </body>
  </worldbody>
</mujoco>
"""

_TWO_BODIES = """<mujoco model="desk">
  <worldbody>
    <body name="top" pos="0 0 0.7">
      <geom type="box" size="0.6 0.3 0.02" mass="6"/>
    </body>
    <body name="leg" pos="0 0 0.35">
      <geom type="box" size="0.05 0.05 0.35" mass="2"/>
    </body>
    <body name="drawer" pos="0.3 0 0.6">
      <joint name="drawer_slide" type="slide" axis="0 -1 0" range="0 0.25"/>
      <geom type="box" size="0.2 0.25 0.05" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_mjcf_hinged_root_and_several_top_level_bodies_ingest_as_fixed_assets(tmp_path):
    """A root body hinged straight to the world, and three top-level bodies (two welded, one sliding),
    each become one fixed-base package: a 'world' link fixed to the world holding the world's geoms,
    and the source joints below it, with their limits."""
    from pxr import UsdPhysics

    cat = tmp_path / "catalog"
    cat.mkdir()
    (cat / "door.xml").write_text(_HINGED_DOOR, encoding="utf-8")
    (cat / "desk.xml").write_text(_TWO_BODIES, encoding="utf-8")
    _catalog(cat, [
        dict(id="door", source="door.xml", category="door", material="wood"),
        dict(id="desk", source="desk.xml", category="desk", material="wood"),
    ])
    out = tmp_path / "out"
    (step,) = _run_ingest(cat, out).steps
    assert step.failed == 0 and step.done == 2, step.failures

    _, joints, bodies = _usd(out, "door")
    assert sorted(bodies) == ["leaf", "world"]
    hinge = UsdPhysics.RevoluteJoint(joints["door_hinge"])
    assert hinge.GetLowerLimitAttr().Get() == pytest.approx(0.0, abs=1e-6)
    assert hinge.GetUpperLimitAttr().Get() == pytest.approx(100.0, rel=1e-6)   # USD: degrees
    assert [t.name for t in hinge.GetBody0Rel().GetTargets()] == ["world"]
    assert [t.name for t in hinge.GetBody1Rel().GetTargets()] == ["leaf"]
    fixed = [p for p in joints.values() if p.IsA(UsdPhysics.FixedJoint)]
    assert len(fixed) == 1                                                     # the base to the world
    assert [t.name for t in UsdPhysics.FixedJoint(fixed[0]).GetBody1Rel().GetTargets()] == ["world"]

    _, joints, bodies = _usd(out, "desk")
    assert sorted(bodies) == ["drawer", "world"]           # top and leg welded into the wrapping link
    slide = UsdPhysics.PrismaticJoint(joints["drawer_slide"])
    assert (slide.GetLowerLimitAttr().Get(), slide.GetUpperLimitAttr().Get()) == pytest.approx((0.0, 0.25))
    assert sum(p.IsA(UsdPhysics.FixedJoint) for p in joints.values()) == 1

    from asset_catalog.index import index_path, query_index

    recs = {r.id: r for r in query_index(index_path(out))}
    assert recs["desk"].mass == pytest.approx(9.0, rel=1e-3)                   # 6 + 2 + 1 kg from the MJCF
    assert recs["desk"].dimensions == pytest.approx((1.2, 0.6, 0.72), abs=1e-3)
    assert recs["door"].n_joints == 1 and recs["door"].is_articulated
    assert recs["door"].dimensions[2] == pytest.approx(2.0, abs=1e-3)          # the world's frame geom kept
    assert not math.isnan(recs["door"].mass)


def test_mjcf_several_free_top_level_bodies_fail_alone(tmp_path):
    """Two loose objects in one file are not one asset: a one-line error naming the file and the body."""
    from pipeline.types import ItemError
    from stages.loaders.mjcf import load_mjcf

    from asset_catalog.annotations import AssetAnnotation

    p = tmp_path / "two.xml"
    p.write_text('<mujoco><worldbody><body name="a"><freejoint/><geom size=".05"/></body>'
                 '<body name="b" pos="1 0 0"><freejoint/><geom size=".05"/></body></worldbody></mujoco>')
    with pytest.raises(ItemError) as e:
        load_mjcf(p, AssetAnnotation(id="two", source="two.xml", category="ball"), catalog_dir=tmp_path)
    msg = str(e.value)
    assert "\n" not in msg and str(p) in msg and "body 'a' has a free joint beside other top-level" in msg


def test_mjcf_wrapped_door_swings_like_mujoco(tmp_path):
    """The wrapped door's leaf, turned 0.7 rad about its hinge, lies where MuJoCo puts it."""
    import mujoco
    import numpy as np
    from scipy.spatial.transform import Rotation

    from asset_catalog.annotations import AssetAnnotation
    from stages.loaders.mjcf import load_mjcf

    p = tmp_path / "door.xml"
    p.write_text(_HINGED_DOOR.replace('type="hinge"', 'type="hinge" pos="-0.05 0 0"'), encoding="utf-8")
    model = load_mjcf(p, AssetAnnotation(id="door", source="door.xml", category="door"), catalog_dir=tmp_path)
    assert model.fixed_base and [lk.name for lk in model.links] == ["world", "leaf"]
    (j,) = model.joints
    assert (j.parent, j.child, j.name) == ("world", "leaf", "door_hinge")
    assert (j.lower, j.upper) == pytest.approx((0.0, math.radians(100)))
    assert len(model.links[0].visuals) == 1           # the world's frame box (the floor plane is skipped)
    q = 0.7
    motion = np.eye(4)
    motion[:3, :3] = Rotation.from_rotvec(np.asarray(j.axis) * q).as_matrix()
    leaf = model.links[0].pose.matrix() @ j.frame.matrix() @ motion
    centre = leaf[:3, :3] @ model.links[1].visuals[0].vertices.mean(axis=0) + leaf[:3, 3]
    mj = mujoco.MjModel.from_xml_path(str(p))
    d = mujoco.MjData(mj)
    d.qpos[0] = q
    mujoco.mj_kinematics(mj, d)
    gid = next(g for g in range(mj.ngeom) if mj.geom_bodyid[g] == 1)
    np.testing.assert_allclose(centre, d.geom_xpos[gid], atol=1e-9)


# ------------------------------------------------------------------------------- units: plausibility


def _duck(path: Path, scale: float) -> Path:
    """A rubber duck 9 cm long, 7 cm tall (a body ellipsoid and a head sphere), in units of 1/``scale`` m."""
    import numpy as np
    import trimesh

    from ingest_testutil import write_obj

    body = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    body.apply_scale((0.045, 0.035, 0.025))
    body.apply_translation((0, 0, 0.025))
    head = trimesh.creation.icosphere(subdivisions=2, radius=0.02)
    head.apply_translation((0.025, 0, 0.05))
    duck = trimesh.util.concatenate([body, head])
    return write_obj(path, np.asarray(duck.vertices) / scale, np.asarray(duck.faces))


def test_unit_mistake_fails_with_the_likely_meters_per_unit_and_odd_assets_warn(tmp_path, caplog):
    """A duck authored in centimetres fails alone, naming the file and meters_per_unit = 0.01; the same
    file annotated in centimetres, or with a wider annotated range, ingests; an odd mass that no unit
    explains (an annotated 20 kg mug) only warns."""
    import logging

    from asset_catalog.index import index_path, query_index
    from ingest_testutil import box_arrays, write_obj

    cat = tmp_path / "catalog"
    _duck(cat / "duck_cm.obj", 0.01)
    v, f = box_arrays((0.08, 0.08, 0.1))
    write_obj(cat / "mug.obj", v, f)
    toy = dict(category="toy", material="rubber")
    _catalog(cat, [
        dict(id="duck_as_metres", source="duck_cm.obj", **toy),
        dict(id="duck_in_cm", source="duck_cm.obj", meters_per_unit=0.01, **toy),
        dict(id="giant_duck", source="duck_cm.obj", plausible_size=[1.0, 20.0], plausible_mass=[10.0, 1e7],
             **toy),
        dict(id="heavy_mug", source="mug.obj", category="mug", material="ceramic", mass=20.0),
    ])
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING, logger="stages.ingest"):
        (step,) = _run_ingest(cat, out).steps
    reasons = {f.item_id: f.reason for f in step.failures}
    assert set(reasons) == {"duck_as_metres"} and step.done == 3, reasons
    msg = reasons["duck_as_metres"]
    assert "\n" not in msg and str(cat / "duck_cm.obj") in msg
    assert "implausible for category 'toy'" in msg and "meters_per_unit = 0.01 (centimetres)" in msg
    assert not (out / "assets" / "duck_as_metres").exists()
    recs = {r.id: r for r in query_index(index_path(out), status="ok")}
    assert max(recs["duck_in_cm"].dimensions) == pytest.approx(0.09, abs=1e-3)
    assert recs["duck_in_cm"].mass == pytest.approx(1200 * 1.98e-4, rel=0.05)   # rubber, ~198 cm^3
    assert max(recs["giant_duck"].dimensions) == pytest.approx(9.0, abs=0.1)
    assert recs["heavy_mug"].mass == pytest.approx(20.0)
    warned = [r.getMessage() for r in caplog.records if "mug.obj" in r.getMessage()]
    assert len(warned) == 1 and "no unit mistake explains it" in warned[0], warned


def test_plausibility_rule():
    """The rule itself: a range per category, the generic fallback, the unit factors both ways."""
    from asset_catalog.plausibility import GENERIC, PLAUSIBLE, judge

    assert judge("mug", 0.1, 0.35).verdict == "ok"
    mm = judge("mug", 100.0, 0.35 * 1e9)                     # a mug in millimetres, mass from density
    assert mm.verdict == "unit" and mm.factors == (0.001,) and "= 0.001 (millimetres)" in mm.message
    back = judge("sofa", 0.002, 6e-5, meters_per_unit=0.001)   # a 2 m, 60 kg sofa in metres annotated as mm
    assert back.verdict == "unit" and "meters_per_unit = 1 (metres annotated as millimetres)" in back.message
    assert judge("mug", 0.1, 20.0, mass_scales=False).verdict == "odd"   # a heavy mug: no unit explains it
    assert judge("mug", 0.1, 20.0, mass_range=(0.1, 30.0)).verdict == "ok"
    assert judge("widget", 8.0, 50.0).verdict == "ok" and "widget" not in PLAUSIBLE   # generic fallback
    assert 0.01 in judge("widget", 16.0, 5e5).factors and GENERIC.size[1] < 16.0
    for r in PLAUSIBLE.values():   # wide, but narrower than a factor 100: a cm mistake always shows
        assert 0 < r.size[0] < r.size[1] < 100 * r.size[0] and 0 < r.mass[0] < r.mass[1]


def test_default_catalog_categories_fit_their_plausible_size():
    """Every built-in generator's size range lies inside its category's plausible range."""
    from asset_catalog.generators import GENERATORS
    from asset_catalog.plausibility import PLAUSIBLE

    for spec in GENERATORS:
        lo, hi = PLAUSIBLE[spec.category].size
        assert lo <= max(spec.size_min) and max(spec.size_max) <= hi, spec.category


_TWO_OBJECTS = """<mujoco model="tabletop">
  <worldbody>
    <geom name="floor" type="box" size="1 1 0.01" pos="0 0 -0.01"/>
    <body name="block" pos="0 0 0.05"><freejoint/><geom type="box" size="0.05 0.04 0.03" mass="0.3"/></body>
    <body name="flap" pos="0.5 0 0.2">
      <joint name="flap_hinge" type="hinge" axis="1 0 0" range="-45 45"/>
      <geom type="box" size="0.1 0.01 0.1" mass="0.5"/>
      <body name="handle" pos="0 -0.03 0.05"><geom type="box" size="0.04 0.02 0.01" mass="0.05"/></body>
    </body>
  </worldbody>
</mujoco>
"""


def test_mjcf_one_asset_per_top_level_body_when_the_annotation_names_it(tmp_path):
    """Two entries with the same file and ``mjcf_body`` give one asset per top-level body: the free block
    (movable, no joint) and the hinged flap with its welded handle (wrapped in a fixed 'world' link);
    the world's floor belongs to neither. An unknown body name fails alone, naming the top-level bodies."""
    from pxr import UsdPhysics

    from asset_catalog.index import index_path, query_index

    cat = tmp_path / "catalog"
    cat.mkdir()
    (cat / "tabletop.xml").write_text(_TWO_OBJECTS, encoding="utf-8")
    common = dict(source="tabletop.xml", material="wood")
    _catalog(cat, [dict(id="block", category="box", mjcf_body="block", **common),
                   dict(id="flap", category="cabinet", mjcf_body="flap", **common),
                   dict(id="nothing", category="box", mjcf_body="lid", **common)])
    out = tmp_path / "out"
    (step,) = _run_ingest(cat, out).steps
    reasons = {f.item_id: f.reason for f in step.failures}
    assert set(reasons) == {"nothing"} and step.done == 2, reasons
    assert "mjcf_body 'lid' is not a top-level body; those are 'block', 'flap'" in reasons["nothing"]
    assert str(cat / "tabletop.xml") in reasons["nothing"] and "\n" not in reasons["nothing"]

    recs = {r.id: r for r in query_index(index_path(out), status="ok")}
    assert recs["block"].dimensions == pytest.approx((0.1, 0.08, 0.06), abs=1e-4)    # no floor in it
    assert recs["block"].mass == pytest.approx(0.3) and recs["block"].n_joints == 0
    _, joints, bodies = _usd(out, "block")
    assert bodies == ["block"] and not joints                                         # a free rigid body
    from stages.annotate import MIN_LINK_MASS_KG

    assert recs["flap"].mass == pytest.approx(0.55 + MIN_LINK_MASS_KG)   # flap, handle, empty world link
    _, joints, bodies = _usd(out, "flap")
    assert sorted(bodies) == ["flap", "world"] and "flap_hinge" in joints
    hinge = UsdPhysics.RevoluteJoint(joints["flap_hinge"])
    assert (hinge.GetLowerLimitAttr().Get(), hinge.GetUpperLimitAttr().Get()) == pytest.approx((-45.0, 45.0))
