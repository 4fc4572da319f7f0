"""serve_drinks in a generated living room (issue 16): the episode's setup on a coffee table that also
holds the paper and the books (``stages.demos.drink.pour_setup``), the grasp rotations
(``stages.demos.skill_pour.grip_rots``) and the drink's sublayer moved with the house
(``stages.demos.house_room.write_task_scene``)."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pipeline.types import ItemError
from stages.demos.drink import DRINK_COUNT, drink_world, pour_setup
from stages.demos.packages import CatalogAsset, Placed
from stages.demos.skill_trash import MAX_PAPER_RADIUS, PAPER_AT

PITCHER = {"radius": 0.07, "height": 0.25, "wall": 0.004, "spout": 0.035}
CUP = {"rim_radius": 0.045, "height": 0.1}
BOOK = ((-0.13, -0.095, 0.0), (0.13, 0.095, 0.046))  # the widest, longest, thickest book on a table


def _asset(category: str, params: dict, lo=(-0.05, -0.05, 0.0), hi=(0.05, 0.05, 0.1)) -> CatalogAsset:
    a = CatalogAsset(asset_id=f"{category}_00", category=category, usd=Path(f"/nonexistent/{category}.usda"),
                     info={"params": params})
    a.__dict__["_facts"] = (tuple(lo), tuple(hi), "base")  # bounds as _package_facts reads them from the USD
    return a


def _living(rect, z: float = 0.43):
    """A living-room world as pour_setup reads it: the table top ``rect``, paper, two books, a pitcher,
    a cup and the drink's bodies."""
    placed = {"pitcher": Placed("Objects/pitcher", _asset("pitcher", PITCHER), (0.0, 0.0, z), 0.0),
              "cup": Placed("Objects/cup", _asset("cup", CUP), (0.0, 0.0, z), 0.0),
              "paper": Placed("Objects/paper", _asset("crumpled_paper", {}), (0.0, 0.0, z), 0.0)}
    for k in (1, 2):
        placed[f"book_{k}"] = Placed(f"Objects/book_{k}", _asset("book", {}, *BOOK), (0.0, 0.0, z), 0.0)
    return SimpleNamespace(usd=Path("scene.usda"), placed=placed, table_rect=rect, table_z=z, shelves=(),
                           drink=tuple(f"/World/Drink/D{k:02d}" for k in range(DRINK_COUNT)))


def _book_box(pose, lo, hi) -> tuple[float, float, float, float]:
    x, y, _, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    pts = np.array([[x + c * px - s * py, y + s * px + c * py] for px in (lo[0], hi[0]) for py in (lo[1], hi[1])])
    return (*pts.min(axis=0), *pts.max(axis=0))


@pytest.mark.parametrize("rect", [(0.0, 0.0, 0.85, 0.37), (1.0, 2.0, 2.26, 2.6)])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_living_room_setup_keeps_paper_books_pitcher_and_cup_apart_on_the_table(rect, seed):
    world = _living(rect)
    objects, plan = pour_setup(world, np.random.default_rng(seed))
    x0, y0, x1, y1 = rect
    paper = (x0 + PAPER_AT[0], y0 + PAPER_AT[1])
    boxes = [_book_box(objects[world.placed[f"book_{k}"].body()], *BOOK) for k in (1, 2)]
    r = PITCHER["radius"]
    for b in boxes:   # on the top, west of the pitcher's body, clear of the paper
        assert x0 <= b[0] and b[2] <= x1 and y0 <= b[1] and b[3] <= y1
        assert b[2] < plan.home[0] - r
        assert b[1] > paper[1] + MAX_PAPER_RADIUS or b[0] > paper[0] + MAX_PAPER_RADIUS
    z1, z2 = (objects[world.placed[f"book_{k}"].body()][2] for k in (1, 2))
    assert z2 >= z1 + (BOOK[1][2] - BOOK[0][2])                      # the second lies on the first
    assert plan.home[0] - r > paper[0] + MAX_PAPER_RADIUS            # the pitcher east of the paper
    assert plan.cup_xy[0] - plan.home[0] >= 0.2                      # room to pour beside the cup
    assert plan.cup_xy[0] + CUP["rim_radius"] <= x1                  # the cup on the top
    assert plan.home[1] + r + PITCHER["spout"] <= y1                 # the pitcher's spout on the top
    drink = np.array([objects[b][:3] for b in plan.drink])
    np.testing.assert_allclose(drink, drink_world(plan.home, PITCHER, DRINK_COUNT))


def test_a_table_too_short_for_paper_pitcher_and_cup_is_an_item_error():
    with pytest.raises(ItemError, match="too short"):
        pour_setup(_living((0.0, 0.0, 0.55, 0.5)), np.random.default_rng(0))


@pytest.mark.parametrize("table_z", [0.74, 0.43])
def test_the_two_grasps_point_along_y_close_along_x_and_differ_by_a_half_turn(table_z):
    from stages.demos.skill_pour import LOW_PITCH, LOW_TABLE, grip_rots

    a, b = grip_rots(table_z)
    for r in (a, b):
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert abs(abs(r[0, 1]) - 1.0) < 1e-12                       # the fingers close along world X
        pitch = math.degrees(math.atan2(-r[2, 2], r[1, 2]))          # the approach: +Y, pitched down
        assert pitch == pytest.approx(0.0 if table_z >= LOW_TABLE else LOW_PITCH)
    turn = a.T @ b                                                   # b: a turned 180 deg about its approach
    np.testing.assert_allclose(turn, np.diag([-1.0, -1.0, 1.0]), atol=1e-12)


def test_the_task_scene_moves_the_drink_layer_with_the_house(tmp_path):
    from pxr import Gf, Usd, UsdGeom

    from stages.demos.house_room import write_task_scene

    house = tmp_path / "house" / "scene.usda"
    house.parent.mkdir()
    house.write_text('#usda 1.0\n(\n    defaultPrim = "World"\n    upAxis = "Z"\n)\n\ndef Xform "World"\n{\n'
                     '    def Xform "Objects"\n    {\n    }\n}\n')
    drink = tmp_path / "task" / "drink.usda"
    drink.parent.mkdir()
    drink.write_text('#usda 1.0\n(\n    defaultPrim = "World"\n)\n\nover "World"\n{\n    def Xform "Drink"\n    {\n'
                     '        def Xform "D00"\n        {\n            double3 xformOp:translate = (1, 0, 0.5)\n'
                     '            uniform token[] xformOpOrder = ["xformOp:translate"]\n        }\n    }\n}\n')
    usd = tmp_path / "task" / "scene.usda"
    write_task_scene(usd, house, (2.0, 3.0, math.pi / 2), [], None, layers=[drink])
    stage = Usd.Stage.Open(str(usd))
    m = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Drink/D00")).ComputeLocalToWorldTransform(
        Usd.TimeCode.Default())
    assert stage.GetPrimAtPath("/World/Objects").IsValid()
    p = m.ExtractTranslation()
    assert (p - Gf.Vec3d(2.0, 4.0, 0.5)).GetLength() < 1e-9          # Rz(90) (1, 0) + (2, 3) = (2, 4)
