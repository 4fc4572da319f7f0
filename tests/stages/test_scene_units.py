"""Scene stage units: rule files, exact convex penetration, 2-D geometry, lighting and materials."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stages.scene.collide import box_piece, convex_piece, find_penetrations, penetration_depth
from stages.scene.geom import convex_hull_2d, convex_inside, convex_overlap, polygon_area, rot3, shrink_convex
from stages.scene.lighting import KELVIN_RANGE, SCENE_EXPOSURE, LightingConfig, plan_lights
from stages.scene.materials import FLOOR_KINDS, WALL_KINDS, planar_st, sample_looks, write_textures
from stages.scene.rules import DEFAULT_RULES, HOUSEHOLD_TASK_RULES, RulesError, load_rules, rule_files


def test_default_rules_cover_the_dataset_rooms():
    rules = load_rules()
    req = {rt: {e.category for e in rules.for_room(rt).furniture if e.count[0] > 0}
           for rt in ("living_room", "kitchen", "bedroom")}
    assert {"sofa", "tv_stand", "coffee_table"} <= req["living_room"]
    assert {"kitchen_counter", "fridge"} <= req["kitchen"]
    assert {"bed", "nightstand"} <= req["bedroom"]
    assert {"pillow"} <= {o.category for o in rules.for_room("bedroom").objects}
    assert rules.setting("kitchen", "path_width") == pytest.approx(0.6)
    # the generators know every category the rules name
    from asset_catalog.generators import GENERATORS_BY_CATEGORY

    assert rules.categories() <= set(GENERATORS_BY_CATEGORY)


def test_household_task_rules_require_what_the_tasks_use():
    from asset_catalog.generators import GENERATORS_BY_CATEGORY

    base, rules = load_rules(), load_rules(HOUSEHOLD_TASK_RULES)
    assert rules.categories() <= set(GENERATORS_BY_CATEGORY)
    req = {rt: {e.category for e in (*rules.for_room(rt).furniture, *rules.for_room(rt).objects)
                if e.count[0] > 0} for rt in ("living_room", "kitchen", "bedroom")}
    assert {"bookshelf", "book", "pitcher", "cup", "trash_can", "crumpled_paper"} <= req["living_room"]
    assert {"wardrobe", "hanger", "pillow", "alarm_clock", "bed"} <= req["bedroom"]
    assert {"dish_rack", "sponge", "plate", "microwave", "fridge"} <= req["kitchen"]
    # what the file does not name comes from the default rules unchanged
    assert rules.for_room("bathroom") == base.for_room("bathroom")
    assert rules.setting("bedroom", "door_clearance") == base.setting("bedroom", "door_clearance")
    dflt = {e.category: e for e in base.for_room("living_room").furniture}
    assert {e.category: e for e in rules.for_room("living_room").furniture}["armchair"] == dflt["armchair"]
    # the bedroom's furniture list is the file's own (replace = ["furniture"]): the wardrobe first
    assert rules.for_room("bedroom").furniture[0].category == "wardrobe"
    assert rule_files(HOUSEHOLD_TASK_RULES) == (HOUSEHOLD_TASK_RULES, DEFAULT_RULES)
    # the hangers go where the rules put them: inside a wardrobe or closet
    assert {e.category: e.on for e in rules.for_room("bedroom").objects}["hanger"] == ("wardrobe", "closet")


def test_rule_file_extends_another(tmp_path: Path):
    (tmp_path / "base.toml").write_text(
        '[defaults]\nreach = 0.8\nmax_tries = 10\n[room.kitchen]\nwall_gap = 0.05\n'
        '[[room.kitchen.furniture]]\ncategory = "fridge"\n'
        '[[room.kitchen.furniture]]\ncategory = "cabinet"\ncount = [0, 1]\n'
        '[[room.kitchen.furniture]]\ncategory = "fridge"\ncount = [0, 1]\nmode = "floor"\n'
        '[[room.kitchen.objects]]\ncategory = "mug"\n', encoding="utf-8")
    p = tmp_path / "task.toml"
    p.write_text('extends = "base.toml"\n[defaults]\nreach = 1.1\n[room.kitchen]\nmin_gap = 0.1\n'
                 'replace = ["objects"]\n[[room.kitchen.objects]]\ncategory = "plate"\n'
                 '[[room.kitchen.furniture]]\ncategory = "fridge"\ncount = [1, 1]\nsnap = 0.5\n'
                 '[[room.kitchen.furniture]]\ncategory = "fridge"\ncount = [0, 2]\n'
                 '[[room.kitchen.furniture]]\ncategory = "oven"\n'
                 '[room.bedroom]\n[[room.bedroom.furniture]]\ncategory = "bed"\n', encoding="utf-8")
    r = load_rules(p)
    assert (r.defaults.reach, r.defaults.max_tries) == (1.1, 10)
    k = r.for_room("kitchen")
    assert (k.wall_gap, k.min_gap) == (0.05, 0.1)
    # both base fridge entries are replaced by the task's two, at the first one's place; oven appended
    assert [(e.category, e.count) for e in k.furniture] == [("fridge", (1, 1)), ("fridge", (0, 2)),
                                                             ("cabinet", (0, 1)), ("oven", (1, 1))]
    assert k.furniture[0].snap == 0.5 and [e.category for e in k.objects] == ["plate"]
    assert [e.category for e in r.for_room("bedroom").furniture] == ["bed"]
    assert rule_files(p) == (p, tmp_path / "base.toml")
    # a cycle and a missing base are errors that name the file
    (tmp_path / "a.toml").write_text('extends = "b.toml"\n', encoding="utf-8")
    (tmp_path / "b.toml").write_text('extends = "a.toml"\n', encoding="utf-8")
    with pytest.raises(RulesError, match="cycle"):
        load_rules(tmp_path / "a.toml")
    (tmp_path / "c.toml").write_text('extends = "nope.toml"\n', encoding="utf-8")
    with pytest.raises(RulesError, match="nope.toml: rule file not found"):
        load_rules(tmp_path / "c.toml")
    assert rule_files(tmp_path / "a.toml")[:2] == (tmp_path / "a.toml", tmp_path / "b.toml")


def test_bad_rule_file_names_file_and_every_problem(tmp_path: Path):
    p = tmp_path / "rules.toml"
    p.write_text('[room.kitchen]\n[[room.kitchen.furniture]]\ncategory = "fridge"\nmode = "beside"\n'
                 'count = [2, 1]\n[[room.attic.furniture]]\ncategory = "x"\n', encoding="utf-8")
    with pytest.raises(RulesError) as e:
        load_rules(p)
    msg = str(e.value)
    assert str(p) in msg and "target" in msg and "count" in msg and "attic" in msg
    with pytest.raises(RulesError, match="not found"):
        load_rules(tmp_path / "missing.toml")
    assert DEFAULT_RULES.is_file()


def test_penetration_depth_of_boxes_is_exact():
    a = box_piece([0, 0, 0], [1, 1, 1])
    assert penetration_depth(a, box_piece([0.9985, 0.2, 0.2], [2, 2, 2])) == pytest.approx(0.0015)
    assert penetration_depth(a, box_piece([1.0, 0, 0], [2, 1, 1])) == pytest.approx(0.0)   # touching
    assert penetration_depth(a, box_piece([1.2, 0, 0], [2, 1, 1])) == pytest.approx(-0.2)  # apart
    # a box rotated 45 deg about z, its corner pushed 5 mm into a's +x face
    h = 0.5 / math.sqrt(2)
    b = box_piece([-h, -h, 0.2], [h, h, 0.8])
    r = rot3(math.pi / 4)
    b = b.transformed(r, np.array([1.0 + 0.5 - 0.005, 0.5, 0.0]))
    assert penetration_depth(a, b) == pytest.approx(0.005, abs=1e-9)


def test_edge_edge_separation_is_found():
    # two tetrahedra whose face normals all overlap but an edge x edge axis separates them
    t1 = convex_piece(np.array([[0, 0, 0], [1, 0, 0], [0.5, 0, 1], [0.5, 1, 0.5]], dtype=float) * 1.0)
    t2 = convex_piece(np.array([[0, 0, 0], [1, 0, 0], [0.5, 0, 1], [0.5, 1, 0.5]], dtype=float) @ rot3(math.pi).T
                      + np.array([0.5, 1.02, 0.0]))
    d = penetration_depth(t1, t2)
    from stages.scene.collide import face_overlap

    assert d <= face_overlap(t1, t2) + 1e-12


@settings(max_examples=30, deadline=None)
@given(st.floats(-0.05, 0.05), st.floats(0, 2 * math.pi))
def test_translation_along_x_gives_the_overlap(gap, yaw):
    """A unit cube and a cube shifted by (1 + gap) along x overlap by -gap, whatever both are rotated by."""
    a = box_piece([0, 0, 0], [1, 1, 1])
    b = box_piece([1 + gap, 0, 0], [2 + gap, 1, 1])
    r = rot3(yaw)
    assert penetration_depth(a.transformed(r, np.zeros(3)), b.transformed(r, np.zeros(3))) == pytest.approx(-gap, abs=1e-9)


def test_find_penetrations_reports_owner_pairs_over_tolerance():
    a = box_piece([0, 0, 0], [1, 1, 1], owner="table")
    b = box_piece([0.2, 0.2, 0.998], [0.4, 0.4, 1.2], owner="mug")    # 2 mm into the top
    c = box_piece([0.6, 0.6, 0.9995], [0.8, 0.8, 1.2], owner="plate")  # 0.5 mm: tolerated
    hits = find_penetrations([b, c], [a])
    assert [(h.owner_a, h.owner_b) for h in hits] == [("mug", "table")]
    assert hits[0].depth == pytest.approx(0.002)


def test_2d_helpers():
    sq = convex_hull_2d(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]))
    assert polygon_area(sq) == pytest.approx(1.0)
    assert convex_overlap(sq, sq + [0.99, 0]) and not convex_overlap(sq, sq + [1.01, 0])
    assert not convex_overlap(sq, sq + [1.01, 0], gap=0.0) and convex_overlap(sq, sq + [1.01, 0], gap=0.02)
    ell = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
    assert convex_inside(sq * 0.9 + 0.05, ell)
    assert not convex_inside(sq * 1.2 + [0.5, 0.5], ell)          # covers the reflex corner
    inner = shrink_convex(sq, 0.1)
    assert polygon_area(inner) == pytest.approx(0.64)


def test_lights_hit_their_target_lux():
    poly = np.array([[0, 0], [4, 0], [4, 3], [0, 3]], dtype=float)
    rng = np.random.default_rng(3)
    lights = plan_lights([("r1", poly, 0.0, 2.6), ("r2", poly + 5, 2.8, 2.6)], LightingConfig(daylight=1.0), rng)
    ceil = [lt for lt in lights if lt.type == "SphereLight"]
    assert len(ceil) == 2 and {lt.type for lt in lights} == {"SphereLight", "DistantLight", "DomeLight"}
    for lt in ceil:
        h = lt.position[2] - (0.0 if lt.name.endswith("r1") else 2.8)
        assert lt.floor_lux(h) == pytest.approx(lt.target_lux, rel=1e-9)
    for lt in lights:
        assert 50 <= lt.target_lux <= 20000 and KELVIN_RANGE[0] <= lt.color_temperature <= KELVIN_RANGE[1]
        # one exposure for every light of a scene; the dome's is in its intensity
        assert lt.exposure == (0.0 if lt.type == "DomeLight" else SCENE_EXPOSURE)


def test_textures_and_looks(tmp_path: Path):
    from PIL import Image

    rng = np.random.default_rng(0)
    tex = write_textures([*FLOOR_KINDS, *WALL_KINDS, "asset_metal", "asset_fabric"], tmp_path / "textures", rng,
                         px=64, rel_to=tmp_path)
    assert tex["asset_metal"].metallic and tex["wood"].metallic is None
    n = np.asarray(Image.open(tmp_path / tex["brick"].normal), dtype=float) / 255 * 2 - 1
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=0.03)        # unit normals
    assert n[..., 2].min() > 0                                             # facing out of the surface
    rough = np.asarray(Image.open(tmp_path / tex["tile"].roughness))
    assert rough.ndim == 2 and rough.std() > 5                              # grout vs glaze
    looks = sample_looks(["a", "b"], ["wood", "metal"], 3, rng)
    assert len({lk.floors["a"].name for lk in looks}) == 3
    assert {m.kind for lk in looks for m in lk.floors.values()} <= set(FLOOR_KINDS)
    st_ = planar_st(np.array([[0, 0, 0], [2, 0, 0], [0, 3, 0]], float), np.array([0, 1, 2]))
    assert st_.tolist() == [[0, 0], [2, 0], [0, 3]]


def test_path_grid_windowed_distances_match_the_whole_grid():
    """PathGrid.components / reach_mask (cached free mask, distance transforms over a window around
    the extra cells) give exactly what the whole-grid distance transform gives."""
    from scipy import ndimage

    from stages.scene.room import PathGrid

    rng = np.random.default_rng(3)
    for _ in range(20):
        g = PathGrid.__new__(PathGrid)
        shape = (int(rng.integers(20, 60)), int(rng.integers(20, 60)))
        g.origin, g.cell, g.shape = np.zeros(2), 0.05, shape
        g.base = rng.random(shape) < 0.02
        g.base[0, :] = g.base[-1, :] = True
        g.radius = float(rng.uniform(0.1, 0.4))
        g.blocks, g._free_key, g._free_mask, g._labels = {}, None, np.zeros(shape, dtype=bool), None
        for k in range(3):
            g.blocks[f"b{k}"] = g.raster(convex_hull_2d(rng.uniform(0, 2.5, (6, 2))))
        extra = g.raster(convex_hull_2d(rng.uniform(0, 2.5, (5, 2))))
        fp = convex_hull_2d(rng.uniform(0, 2.5, (5, 2)))
        occ = g.base | extra
        for m in g.blocks.values():
            occ |= m
        free = ndimage.distance_transform_edt(~occ) * g.cell >= g.radius + g.cell * 0.5
        want = ndimage.label(free, structure=np.ones((3, 3), dtype=bool))[0]
        assert np.array_equal(g.components(extra), want)
        m = g.raster(fp)
        if m.any():
            assert np.array_equal(g.reach_mask(fp, 0.6), ndimage.distance_transform_edt(~m) * g.cell <= 0.6)
        g.blocks.pop("b0")  # a changed set of blocks is seen
        occ = g.base.copy()
        for b in g.blocks.values():
            occ |= b
        free = ndimage.distance_transform_edt(~occ) * g.cell >= g.radius + g.cell * 0.5
        assert np.array_equal(g.components(), ndimage.label(free, structure=np.ones((3, 3), dtype=bool))[0])
