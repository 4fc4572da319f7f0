"""Clean dishes in a generated house's kitchen (issue 16): the place-in-rack skill's predicate and hand
rotation (``stages.demos.skill_rack``) on inline packages; the dishes layout of
``house_kitchen(dishes=True)`` (``stages.demos.house_dishes``) in a flat populated by the scene job
and clean_dishes (wipe, then the plate onto the rack) in it are slow (the flat: 20 s on an idle CPU,
3 min on the loaded 2 cores; the episode: 25 s idle)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

RACK = {"depth": 0.3, "width": 0.4, "tine_height": 0.1, "tray_height": 0.04}
PLATE = {"radius": 0.12, "height": 0.02, "thickness": 0.005, "well_ratio": 0.65}
PACKAGE = """#usda 1.0
(
    defaultPrim = "{name}"
)
def Xform "{name}"
{{
    def Xform "{link}" (
        prepend apiSchemas = ["PhysicsRigidBodyAPI"]
    )
    {{
    }}
}}
"""


@pytest.fixture()
def rack_world(tmp_path):
    """A world with a dish rack at (1, 2, 0.9) (yaw 0) and a plate: the facts the predicate reads."""
    from stages.demos.packages import CatalogAsset, Placed

    placed = {}
    for role, name, link, params in (("dish_rack", "dish_rack_00", "base", RACK), ("plate", "plate_00", "body", PLATE)):
        usd = tmp_path / f"{name}.usda"
        usd.write_text(PACKAGE.format(name=name, link=link), encoding="utf-8")
        asset = CatalogAsset(name, role, usd, {"params": params})
        placed[role] = Placed(f"Objects/{name}", asset, (1.0, 2.0, 0.9), 0.0)
    return SimpleNamespace(world=SimpleNamespace(placed=placed))


def _state(inst, plate_pos, plate_q=(1.0, 0.0, 0.0, 0.0), rack_q=(1.0, 0.0, 0.0, 0.0), opening=0.08,
           ee=(1.0, 1.6, 1.2)):
    from asset_catalog.asset_model import Pose
    from stages.simulate.state import BasePose, RobotState, StepState

    pl = inst.world.placed
    robot = RobotState(joint_names=(), q=np.zeros(0), qd=np.zeros(0), ee_pose=Pose(position=ee),
                       base=BasePose(x=1.0, y=1.0, theta=math.pi / 2), gripper_opening=opening)
    return StepState(time=0.0, step=0, world=0, robot=robot, scene_joints={},
                     objects={pl["dish_rack"].body(): Pose(position=(1.0, 2.0, 0.9), orientation=rack_q),
                              pl["plate"].body(): Pose(position=plate_pos, orientation=plate_q)})


def test_place_in_rack_predicate_names_each_miss(rack_world):
    from stages.demos.skill_rack import place_in_rack_success

    tines = 0.9 + 0.004 + RACK["tine_height"]   # the tines' tops [m]
    on = (1.02, 1.95, tines + 0.003)             # lying on the tines, off centre
    half = math.sqrt(0.5)

    def check(*a, **k):
        return place_in_rack_success(rack_world, _state(rack_world, *a, **k))

    assert check(on) == (True, "")
    assert check((1.0, 2.0, 0.905)) == (True, "")                       # flat in the tray
    # 0.2 m east: past the 0.15 m half depth
    assert check((1.2, 2.0, tines + 0.003)) == (False, "object_not_in_container")
    assert check((1.0, 2.25, 0.905)) == (False, "object_not_in_container")          # past the 0.2 m half width
    assert check((1.0, 2.0, tines + 0.06)) == (False, "not_resting")
    assert check(on, plate_q=(half, half, 0.0, 0.0)) == (False, "plate_tipped")     # on edge
    assert check(on, opening=0.02) == (False, "object_still_held")
    assert check(on, rack_q=(half, 0.0, half, 0.0)) == (False, "rack_tipped")


def test_rim_grasp_hand_points_along_y_and_closes_vertically():
    from stages.demos.skill_rack import rim_rot

    for pitch in (0.0, 20.0):
        r = rim_rot(pitch)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        p = math.radians(pitch)
        np.testing.assert_allclose(r[:, 2], [0.0, math.cos(p), -math.sin(p)], atol=1e-12)   # approach: +Y, down
        np.testing.assert_allclose(r[:, 1], [0.0, math.sin(p), math.cos(p)], atol=1e-12)    # fingers: vertical


# the kitchen's required categories, as test_demos_house.py (sponge_00: 61 mm, the hand grasps it across)
PACKAGES = ("fridge_00", "fridge_03", "kitchen_counter_00", "kitchen_counter_03", "kitchen_counter_04", "microwave_01",
            "dish_rack_00", "sponge_00", "plate_00", "mug_04", "mug_00")


@pytest.fixture(scope="module")
def dish_world(tmp_path_factory):
    pytest.importorskip("newton")
    from house_testutil import populate_flat

    from stages.demos.house import house_kitchen

    scene, gen = populate_flat(tmp_path_factory.mktemp("house") / "out", "house", PACKAGES, "kitchen")
    return house_kitchen(scene, tmp_path_factory.mktemp("task"), gen, scene_id=scene.name, dishes=True)


@pytest.mark.slow
def test_dishes_lie_in_a_row_on_the_counter_and_the_rest_is_cut(dish_world):
    from stages.demos.skill_rack import RACK_FRONT, rack_box

    w = dish_world
    pl = w.placed
    x0, y0, x1, y1 = w.table_rect
    plate, sponge, rack = pl["plate"], pl["sponge"], pl["dish_rack"]
    r = float(plate.asset.params["radius"])
    hx, hy, _ = rack_box(rack.asset.params)
    for p in (plate, sponge, rack):
        assert x0 < p.position[0] < x1 and y0 < p.position[1] < y1 and p.position[2] == pytest.approx(w.table_z + 0.002)
    assert rack.position[1] - hy == pytest.approx(y0 + RACK_FRONT)          # the rack's front by the edge
    assert abs(plate.position[0] - rack.position[0]) >= r + hx + 0.03       # beside each other, not overlapping
    assert (plate.position[0] - rack.position[0]) * (sponge.position[0] - plate.position[0]) > 0   # the plate between
    assert plate.position[1] - r == pytest.approx(y0 + 0.03)               # its near rim 3 cm behind the edge
    counter = pl["counter"].name.rsplit("/", 1)[-1]
    micro = pl["microwave"].name.rsplit("/", 1)[-1]
    assert micro in w.cut and counter not in w.cut and w.moved is None
    assert not {p.name.rsplit("/", 1)[-1] for p in (plate, sponge, rack, pl["mug"])} & set(w.cut)


@pytest.mark.slow
def test_clean_dishes_succeeds_in_a_generated_house(dish_world, tmp_path):
    """One episode: the plate wiped, then slid to the counter's edge, taken by its rim and let down on
    the rack's tines."""
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    cfg = EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True)
    eng = BatchEngine(dish_world, panda_root=None, work_dir=tmp_path / "w", config=cfg)
    results = []
    eng.run(Listed(dish_world, {0: [("clean_dishes", 1, None)]}), begin=lambda w, t: None,
            end=lambda w, t, r: results.append(r))
    assert results[0].success, (results[0].reason, results[0].detail)
