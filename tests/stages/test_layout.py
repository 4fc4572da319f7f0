"""Layout stage: spec validation, exact 2-D helpers, determinism, geometry, USD layer, floor plan
files, the job kind through the runner, the plan picture, and Newton physics on the stairs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from asset_catalog.annotations import RoomType as R
from stages.layout.build import generate_layout, plan_house
from stages.layout.floorplan import load_floor_plan
from stages.layout.geom2d import Rect, rects_minus, union_area
from stages.layout.spec import LayoutSpec, rooms_per_floor

TWO_FLOORS = LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 2, R.BATHROOM: 1}, floors=2,
                        stair_shape="straight")
THREE_ROOMS = LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 1})


@pytest.fixture(scope="module")
def two_floor(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("two_floor")
    generate_layout(TWO_FLOORS, 7, out)
    return out


# -- spec -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, needle", [
    ({"rooms": {"bedroom": 1}, "exterior_wall": (0.05, 0.2)}, "wall thickness"),
    ({"rooms": {"bedroom": 1}, "door_width": (0.7, 0.9)}, "door width"),
    ({"rooms": {"bedroom": 1}, "floors": 2}, "cannot fill 2 floors"),
    ({"rooms": {"bedroom": 1}, "floors": 4}, "less than or equal to 3"),
    ({"rooms": {"garage": 1}}, "rooms"),
    ({"rooms": {"bedroom": 0}}, "at least one room"),
    ({"rooms": {"hallway": 1}}, "besides hallways"),
])
def test_spec_rejects_bad_input(kwargs, needle) -> None:
    with pytest.raises(ValidationError, match=needle):
        LayoutSpec(**kwargs)


def test_rooms_per_floor_puts_public_rooms_down_and_adds_bathroom() -> None:
    spec = LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 2}, floors=2)
    down, up = rooms_per_floor(spec)
    assert sorted(down) == [R.KITCHEN, R.LIVING_ROOM]
    assert sorted(up) == [R.BATHROOM, R.BEDROOM, R.BEDROOM]  # auto bathroom for 2 bedrooms
    assert rooms_per_floor(THREE_ROOMS) == [[R.LIVING_ROOM, R.KITCHEN, R.BEDROOM]]


def test_rects_minus_is_exact() -> None:
    outer = [Rect(0, 0, 100, 60), Rect(100, 0, 140, 30)]
    holes = [Rect(20, 10, 40, 70), Rect(90, 20, 120, 25)]
    pieces = rects_minus(outer, holes)
    assert union_area(pieces) == sum(p.area for p in pieces)  # disjoint
    assert sum(p.area for p in pieces) == 6000 + 1200 - 20 * 50 - 30 * 5
    assert not any(p.intersects(h) for p in pieces for h in holes)


# -- plans ----------------------------------------------------------------------------------------


def test_plan_rules_hold() -> None:
    house, grids = plan_house(TWO_FLOORS, 3)
    assert 10 <= house.t_int <= 15 and 20 <= house.t_ext <= 25
    for fl in house.floors:
        for w in fl.walls:
            assert 10 <= w.thickness <= 25
        types = {r.type for r in fl.rooms}
        assert R.HALLWAY in types  # the stair hall
    (stair,) = house.stairs
    assert 0.15 <= stair.rise <= 0.19 and stair.run >= 25
    assert stair.n_risers * stair.rise == pytest.approx(TWO_FLOORS.floor_height)
    assert len(grids) == 2 and grids[0].cell == 0.05
    # the stairwell is blocked upstairs, the stairs are blocked downstairs
    x0, y0, x1, y1 = (v / 100 for v in (stair.opening[0].x0, stair.opening[0].y0, stair.opening[0].x1,
                                        stair.opening[0].y1))
    assert not grids[1].is_traversable((x0 + x1) / 2, (y0 + y1) / 2)
    assert not grids[0].is_traversable((x0 + x1) / 2, (y0 + y1) / 2)


def test_l_shaped_rooms_and_stairs_occur() -> None:
    spec = LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 2, R.BATHROOM: 1}, floors=2,
                      stair_shape="l_shaped")
    l_rooms = 0
    for seed in range(12):
        house, _ = plan_house(spec, seed)
        assert house.stairs[0].shape == "l_shaped"
        l_rooms += sum(r.is_l for fl in house.floors for r in fl.rooms)
        for fl in house.floors:
            for r in fl.rooms:
                if r.is_l:
                    assert len(r.outline) == 6 and r.area / r.bbox.area < 1.0
    assert l_rooms > 0


def test_impossible_spec_fails_with_one_clear_line() -> None:
    from stages.layout.plan import LayoutError

    spec = LayoutSpec(rooms={R.BEDROOM: 8, R.BATHROOM: 8, R.KITCHEN: 1}, max_attempts=5, hallway="never")
    with pytest.raises(LayoutError, match="no valid plan in 5 attempts"):
        plan_house(spec, 0)


def test_same_seed_same_bytes(tmp_path: Path) -> None:
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    generate_layout(TWO_FLOORS, 11, a)
    generate_layout(TWO_FLOORS, 11, b)
    generate_layout(TWO_FLOORS, 12, c)
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    for n in names:
        assert (a / n).read_bytes() == (b / n).read_bytes(), n
    assert (a / "floorplan.json").read_bytes() != (c / "floorplan.json").read_bytes()


# -- floor plan files -----------------------------------------------------------------------------


def test_floor_plan_round_trip(two_floor: Path) -> None:
    plan = load_floor_plan(two_floor / "floorplan.json")
    house, grids = plan_house(TWO_FLOORS, 7)
    assert len(plan.floors) == 2 and len(plan.stairs) == 1
    for f, g in enumerate(grids):
        occ = plan.occupancy(f)
        assert np.array_equal(occ.traversable, g.traversable)
        assert np.array_equal(occ.occupied, g.occupied)
        assert np.array_equal(occ.room_index, g.room_index)
        # every room has traversable floor, and the cells say which room they are in
        for k, room in enumerate(plan.floors[f].rooms):
            assert (occ.traversable & (occ.room_index == k)).any(), room.id
    assert {d.exterior for d in plan.floors[0].doors} == {True, False}
    assert plan.room(plan.floors[1].rooms[0].id).floor == 1


def test_load_floor_plan_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="floor plan not found"):
        load_floor_plan(tmp_path / "missing.json")
    bad = tmp_path / "floorplan.json"
    bad.write_text(json.dumps({"format": "agentworld.floorplan/1", "seed": 1}))
    with pytest.raises(ValueError, match=r"floorplan.json: not a valid floor plan"):
        load_floor_plan(bad)


# -- geometry and USD -----------------------------------------------------------------------------


def test_colliders_match_visual_solids() -> None:
    import manifold3d as m3

    from stages.layout.geometry import build_geometry

    house, _ = plan_house(TWO_FLOORS, 5)
    elements = build_geometry(house)
    labels = {e.label for e in elements}
    assert {"wall", "floor", "ceiling", "roof", "stairs", "railing", "window"} <= labels
    for e in elements:
        mesh = m3.Mesh(vert_properties=e.vertices.astype(np.float32), tri_verts=e.faces.astype(np.uint32))
        solid = m3.Manifold(mesh)
        assert solid.status() == m3.Error.NoError, e.name
        assert solid.volume() == pytest.approx(sum(b.volume for b in e.colliders), rel=1e-4, abs=1e-6), e.name
    # doors are real holes: every interior door wall has less volume than its uncut box
    cut = [e for e in elements if e.label == "wall" and len(e.colliders) > 1]
    assert cut


def test_usd_layer_is_valid_and_labelled(two_floor: Path) -> None:
    import usd_schemas
    from pxr import Usd, UsdGeom, UsdPhysics, UsdSemantics

    path = two_floor / "layout.usdc"
    stage = Usd.Stage.Open(str(path))
    assert not stage.GetCompositionErrors()
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    house = stage.GetDefaultPrim()
    assert house.GetPath() == "/House" and Usd.ModelAPI(house).GetKind() == "assembly"
    labels, colliders = set(), 0
    for prim in stage.Traverse():
        if prim.HasAPI(UsdSemantics.LabelsAPI, "class"):
            labels.update(UsdSemantics.LabelsAPI(prim, "class").GetLabelsAttr().Get())
        if prim.HasAPI(UsdPhysics.CollisionAPI):
            colliders += 1
            assert prim.IsA(UsdGeom.Cube) and not prim.HasAPI(UsdPhysics.RigidBodyAPI)
    assert {"wall", "floor", "ceiling", "stairs", "railing", "window", "roof", "bedroom", "kitchen",
            "living_room", "hallway", "bathroom"} <= labels
    assert colliders > 50
    report = usd_schemas.validate_package(path)
    assert not report.errors, [i.line() for i in report.errors]


# -- job kind through the runner ------------------------------------------------------------------


def test_layout_job_runs_through_the_runner(tmp_path: Path) -> None:
    from pipeline import load_job, run_job

    job = tmp_path / "layouts.toml"
    job.write_text(f'''
[job]
name = "layouts_test"
seed = 3
out = "{tmp_path / 'out'}"
executor = "inline"

[[step]]
name = "layouts"
kind = "layout"
[[step.config.house]]
id = "flat"
count = 2
spec = {{ rooms = {{ living_room = 1, kitchen = 1, bedroom = 1 }} }}
''')
    summary = run_job(load_job(job))
    assert summary.failed == 0 and summary.done == 2
    for k in range(2):
        d = tmp_path / "out" / "layouts" / f"flat_{k:03d}"
        assert (d / "layout.usdc").is_file()
        plan = load_floor_plan(d / "floorplan.json")
        assert len(plan.floors[0].rooms) == 3
    again = run_job(load_job(job))
    assert again.cached == 2


# -- pictures and physics -------------------------------------------------------------------------


def test_plan_png(two_floor: Path, tmp_path: Path) -> None:
    from PIL import Image

    from stages.layout.render import WALL, render_plan_png

    plan = load_floor_plan(two_floor / "floorplan.json")
    path = render_plan_png(plan, tmp_path / "plan.png")
    img = np.asarray(Image.open(path).convert("RGB"))
    assert img.shape[1] > img.shape[0] * 0.5
    assert (img == np.array(WALL)).all(axis=2).sum() > 1000   # walls drawn
    packed = (img[..., 0].astype(np.int32) << 16) | (img[..., 1].astype(np.int32) << 8) | img[..., 2]
    assert np.unique(packed).size > 8                            # rooms in several colors


@pytest.mark.slow
def test_render_3d_png(two_floor: Path, tmp_path: Path) -> None:
    from PIL import Image

    from stages.layout.render import render_3d_png

    path = render_3d_png(two_floor / "layout.usdc", tmp_path / "render.png", width=320, height=200)
    img = np.asarray(Image.open(path).convert("RGB")).astype(int)
    background = img[0, 0]
    assert (np.abs(img - background).sum(axis=2) > 30).mean() > 0.2  # the house fills the picture


def test_sphere_rolls_down_the_stairs_in_newton(two_floor: Path) -> None:
    from stages.layout.simcheck import penetrations, roll_sphere_down_stairs

    plan = load_floor_plan(two_floor / "floorplan.json")
    run = roll_sphere_down_stairs(two_floor / "layout.usdc", plan, seconds=2.5)
    stair = plan.stairs[0]
    z_top = plan.floors[1].elevation
    assert run.start[2] > z_top - 0.3
    end = run.path[-1]
    # ends on the ground floor level, never through a slab, step or wall
    assert end[2] == pytest.approx(plan.floors[0].elevation + run.radius, abs=0.02)
    assert run.path[:, 2].min() > plan.floors[0].elevation + run.radius - 0.03
    assert not penetrations(run), penetrations(run)[:5]
    # it went down the flight: past the first step, against the ascent direction
    d = np.array(stair.direction)
    assert (end[:2] - np.array(stair.bottom)) @ d < 0.2
    assert run.loader in ("add_usd", "pxr")


def test_importing_the_stage_loads_no_heavy_modules() -> None:
    import subprocess
    import sys

    code = ("import sys, stages.layout, stages.layout.job, stages.layout.render, stages.layout.simcheck; "
            "print(sorted(m for m in ('pxr', 'warp', 'newton', 'torch', 'manifold3d') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[2])
    assert out.stdout.strip() == "[]"
