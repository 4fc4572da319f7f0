"""The predicates of the store-food and wipe skills (issue 16) on typed states, no simulation:
the wipe's coverage counts only cells the sponge's footprint passed over in contact with the plate's
surface; a mug on the fridge shelf counts as released by a hand closed again far from it (closing
the fridge door after), not by one closed on it."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from asset_catalog.asset_model import Pose
from stages.demos.skill_fridge import Shelf, pick_place_fridge_success
from stages.demos.skill_wipe import COVERAGE, WipeTrace, _rows
from stages.simulate.state import BasePose, RobotState, StepState

PLATE = {"radius": 0.12, "height": 0.022, "thickness": 0.005, "well_ratio": 0.7}


def _state(objects: dict, ee=(0.0, 0.0, 2.0), opening: float = 0.08) -> StepState:
    robot = RobotState(joint_names=(), q=np.zeros(0), qd=np.zeros(0), ee_pose=Pose(position=ee),
                       base=BasePose(x=0.0, y=0.0, theta=0.0), gripper_opening=opening)
    return StepState(time=0.0, step=0, world=0, robot=robot, objects=objects, scene_joints={})


def _trace() -> WipeTrace:
    well = PLATE["radius"] * PLATE["well_ratio"] + 0.01
    g = np.arange(-well + 0.005, well, 0.01)
    cells = np.array([(x, y) for x in g for y in g if math.hypot(x, y) <= well])
    return WipeTrace(plate="/P", sponge="/S", plate_params=PLATE, sponge_size=(0.11, 0.065, 0.03),
                     cells=cells, wiped=np.zeros(len(cells), bool))


def test_the_wipe_counts_cells_under_the_sponge_only_in_contact():
    tr = _trace()
    plate = Pose(position=(1.0, 2.0, 0.75))
    surface = 0.75 + PLATE["thickness"]
    hover = _state({"/P": plate, "/S": Pose(position=(1.0, 2.0, surface + 0.012))})
    assert not tr.record(hover) and tr.coverage == 0.0
    beside = _state({"/P": plate, "/S": Pose(position=(1.0, 2.2, 0.752))})  # on the table next to it
    assert not tr.record(beside) and tr.coverage == 0.0
    touch = _state({"/P": plate, "/S": Pose(position=(1.0, 2.0, surface + 0.001))})
    assert tr.record(touch)
    once = tr.coverage
    assert 0.15 < once < 0.6  # the sponge's footprint over the middle of the well
    # the expert's rows, each point in contact, cover the well
    for row in _rows(tr, (1.0, 2.0), 0.0):
        for xy in row:
            r = np.linalg.norm(tr.footprint(xy, 0.0) - (1.0, 2.0), axis=1)
            z = 0.75 + float(tr.surface(r).max())
            tr.record(_state({"/P": plate, "/S": Pose(position=(*xy, z))}))
    assert tr.coverage >= COVERAGE > once


def test_a_tilted_sponge_does_not_wipe():
    tr = _trace()
    q = (math.cos(math.radians(15)), math.sin(math.radians(15)), 0.0, 0.0)  # 30 deg about x
    s = _state({"/P": Pose(position=(0.0, 0.0, 0.75)), "/S": Pose(position=(0.0, 0.0, 0.755), orientation=q)})
    assert not tr.record(s) and tr.coverage == 0.0


def test_a_mug_on_the_shelf_is_released_by_a_hand_closed_far_from_it():
    shelf = Shelf(rect=(0.0, 0.0, 0.6, 0.4), z=0.9, spot=(0.3, 0.1), front=(0.0, -1.0, 0.0), edge=0.2,
                  door_y=(-0.3, 0.3))
    world = SimpleNamespace(placed={"mug": SimpleNamespace(body=lambda: "/M")})
    inst = SimpleNamespace(place=shelf, world=world)
    mug = Pose(position=(0.3, 0.12, 0.902))
    assert pick_place_fridge_success(inst, _state({"/M": mug}, ee=(0.3, 0.0, 0.95), opening=0.08)) == (True, "")
    # closed again 0.5 m away (pushing the door shut): released
    assert pick_place_fridge_success(inst, _state({"/M": mug}, ee=(0.8, -0.3, 0.9), opening=0.01)) == (True, "")
    # closed on it: held
    assert pick_place_fridge_success(inst, _state({"/M": mug}, ee=(0.3, 0.12, 0.94), opening=0.01)) == (
        False, "object_still_held")
    assert pick_place_fridge_success(inst, _state({"/M": Pose(position=(0.3, -0.2, 0.9))}))[1] == (
        "object_not_in_container")
