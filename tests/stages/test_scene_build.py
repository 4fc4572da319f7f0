"""Scene population on a real floor plan and real asset packages (built in-process from the default
catalog's generators): placement checks, determinism, composition, Newton settle, validation."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from stages.scene.geom import convex_inside, convex_overlap
from stages.scene.rules import load_rules
from stages.scene.solver import Library, Populator, room_context
from stages.scene.verify import verify

CATEGORIES = ["bed", "nightstand", "book", "alarm_clock", "dresser", "rug", "bookshelf", "pillow"]


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from stages.layout.build import generate_layout
    from stages.layout.spec import LayoutSpec
    from stages.scene.standin import build_library

    root = tmp_path_factory.mktemp("scene")
    index = build_library(root / "lib", categories=CATEGORIES, variants=2, seed=0)
    lay = generate_layout(LayoutSpec(rooms={"bedroom": 1}), 7, root / "layout")
    return Library.from_index(index), lay.plan_json, lay.usd, root


def _populate(world, seed):
    lib, plan_json, usd, _ = world
    from stages.layout.floorplan import load_floor_plan

    plan = load_floor_plan(plan_json)
    pop = Populator(plan, usd, lib, load_rules(), np.random.default_rng(seed))
    for r in plan.floors[0].rooms:
        pop.populate_room(r)
    return plan, pop


def test_bedroom_population_is_valid_and_deterministic(world):
    plan, pop = _populate(world, 1)
    cats = [i.p.record.category for i in pop.insts]
    assert "bed" in cats and "nightstand" in cats
    assert any(i.p.support for i in pop.insts)               # something rests on a surface
    check = verify(pop)                                      # exact collider check + robot path
    assert check.penetrations == () and check.path == ()
    room = plan.floors[0].rooms[0]
    ctx = room_context(plan, room, 1.0)
    for i in pop.insts:
        if i.on_floor:
            assert convex_inside(i.footprint, ctx.interior)
            assert not any(convex_overlap(i.footprint, z) for z in ctx.door_zones)
        else:
            sup = next(o for o in pop.insts if o.p.inst == i.p.support)
            assert i.p.position[2] > sup.p.position[2]
    again = _populate(world, 1)[1]
    assert [(i.p.inst, i.p.record.id, i.p.position, i.p.yaw) for i in again.insts] == \
           [(i.p.inst, i.p.record.id, i.p.position, i.p.yaw) for i in pop.insts]
    other = _populate(world, 2)[1]
    assert [i.p.position for i in other.insts] != [i.p.position for i in pop.insts]


def test_robot_path_stays_open_from_the_door(world):
    plan, pop = _populate(world, 3)
    grid = pop.grids[0]
    labels = grid.components()
    ctx = pop.room_ctx[plan.floors[0].rooms[0].id]
    assert ctx.door_points, "the bedroom's door must be usable in the empty room"
    lab = grid.cell_label(labels, ctx.door_points[0])
    assert lab > 0
    for i in pop.insts:
        if i.p.record.interactable:
            assert (grid.reach_mask(i.footprint, 0.9) & (labels == lab)).any()


@pytest.mark.skipif(importlib.util.find_spec("newton_usd_schemas") is None,
                    reason="Newton's add_usd needs newton-usd-schemas")
def test_scene_composes_settles_and_validates(world, tmp_path):
    from pxr import Sdf, Usd, UsdLux, UsdPhysics

    from stages.scene.build import BuildOptions, build_scene
    from stages.scene.settle import load_scene_builder

    lib, plan_json, usd, root = world
    out = tmp_path / "scene"
    s = build_scene(plan_json, usd, lib, load_rules(), np.random.default_rng(5), out, out, BuildOptions(n_looks=2))
    assert s.validation_errors == 0 and s.penetrations == 0 and s.path_problems == 0
    assert s.settle_max_move < 0.01
    scene = out / "scene.usda"
    layer = Sdf.Layer.FindOrOpen(str(scene))
    assert list(layer.subLayerPaths) == ["./lighting.usda", "./materials.usdc", "./placement.usda"]
    stage = Usd.Stage.Open(str(scene))
    assert not stage.GetCompositionErrors()
    objs = stage.GetPrimAtPath("/World/Objects")
    for prim in objs.GetChildren():                                   # references, never copies
        assert prim.HasAuthoredReferences()
    place = Sdf.Layer.FindOrOpen(str(out / "placement.usda"))
    paths = [r.assetPath for p in place.GetPrimAtPath("/World/Objects").nameChildren
             for r in p.referenceList.GetAddedOrExplicitItems()]
    assert paths and all(p.startswith("../") and not Path(p).is_absolute() for p in paths)
    assert not list(out.rglob("*_payload.usdc"))                     # no asset geometry copied in
    assert [p for p in stage.Traverse() if p.IsA(UsdPhysics.Scene)]
    world_prim = stage.GetPrimAtPath("/World")
    vs = world_prim.GetVariantSets().GetVariantSet("look")
    assert vs.GetVariantNames() == ["look_0", "look_1"]
    lights = [UsdLux.LightAPI(p) for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI)]
    assert lights and all(lt.GetEnableColorTemperatureAttr().Get() for lt in lights)
    b = load_scene_builder(scene)                                    # loads in Newton
    assert b.body_count >= len(s.instances) and b.shape_count > 0
    info = json.loads((out / "scene.json").read_text())
    assert len(info["instances"]) == len(s.instances)


def test_rewritten_placement_is_seen_by_the_next_stage(world, tmp_path):
    """The settle repair rewrites placement.usda while an earlier stage may still hold the layer:
    the next stage opened on the scene must see the new content."""
    from pxr import Usd

    from stages.scene import compose
    from stages.scene.build import BuildOptions, build_scene

    lib, plan_json, usd, _ = world
    out = tmp_path / "s"
    s = build_scene(plan_json, usd, lib, load_rules(), np.random.default_rng(4), out, out,
                    BuildOptions(n_looks=1, settle=False, validate=False))
    held = Usd.Stage.Open(str(out / "scene.usda"))                    # keeps the layers alive
    names = [i.name for i in s.instances]
    assert held.GetPrimAtPath(f"/World/Objects/{names[-1]}")
    keep = [compose.InstanceSpec(name=i.name, usd=Path(i.usd), position=i.position, yaw=i.yaw, material="wood",
                                 room=i.room, support=i.support or "", category=i.category) for i in s.instances[:-1]]
    compose.write_placement(out, out, keep)
    fresh = Usd.Stage.Open(str(out / "scene.usda"))
    assert not fresh.GetPrimAtPath(f"/World/Objects/{names[-1]}").IsDefined()
    assert len(fresh.GetPrimAtPath("/World/Objects").GetChildren()) == len(names) - 1


@pytest.mark.skipif(importlib.util.find_spec("newton_usd_schemas") is None,
                    reason="Newton's add_usd needs newton-usd-schemas")
def test_settle_early_exit_keeps_the_1cm_criterion(world, tmp_path):
    """The early exit gives the full 2 s run's verdict: a resting scene stops early with the same
    displacements; a scene with an object dropped from 5 cm is simulated to the end and fails."""
    from stages.scene import compose
    from stages.scene.build import BuildOptions, build_scene
    from stages.scene.settle import settle_check

    lib, plan_json, usd, _ = world
    out = tmp_path / "s"
    s = build_scene(plan_json, usd, lib, load_rules(), np.random.default_rng(5), out, out,
                    BuildOptions(n_looks=1, settle=False, validate=False))
    scene = out / "scene.usda"

    def place(keep, lift=None):
        compose.write_placement(out, out, [
            compose.InstanceSpec(name=i.name, usd=Path(i.usd), material="wood", room=i.room, support=i.support or "",
                                 category=i.category, yaw=i.yaw,
                                 position=(*i.position[:2], i.position[2] + (0.05 if i is lift else 0.0)))
            for i in s.instances if keep(i)])

    full, early = settle_check(scene, early_exit=None), settle_check(scene)        # the whole scene
    assert full.simulated == pytest.approx(2.0) and full.passed == early.passed
    assert set(early.moved) == set(full.moved) and early.offenders == full.offenders
    assert all(abs(early.moved[k] - full.moved[k]) < 0.001 for k in full.moved)   # within 1 mm
    place(lambda i: not i.support)                                                 # the furniture alone rests
    full, early = settle_check(scene, early_exit=None), settle_check(scene)
    assert full.passed and early.passed and early.simulated < 1.0
    assert all(abs(early.moved[k] - full.moved[k]) < 0.001 for k in full.moved)
    # a small object dropped from 5 cm above its support moves ~5 cm: simulated to the end, it fails
    obj = next(i for i in s.instances if i.support)
    place(lambda i: True, lift=obj)
    dropped = settle_check(scene)
    assert not dropped.passed and obj.name in dropped.offenders
    assert dropped.moved[obj.name] > 0.04 and dropped.simulated == pytest.approx(2.0)
