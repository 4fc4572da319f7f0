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
from stages.demos.skill_wipe import COVERAGE, TOUCH_UP_MARGIN, WipeTrace, _rows, _touch_up_rows
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


def _wipe_along(tr: WipeTrace, rows, plate_at) -> None:
    """Record each point of ``rows`` in contact, the plate's centre at ``plate_at(xy)`` then."""
    for row in rows:
        for xy in row:
            pc = plate_at(xy)
            r = np.linalg.norm(tr.footprint(xy, 0.0) - pc, axis=1)
            tr.record(_state({"/P": Pose(position=(*pc, 0.75)),
                              "/S": Pose(position=(*xy, 0.75 + float(tr.surface(r).max())))}))


def test_touch_up_rows_wipe_what_a_dragged_plate_left():
    """The plate dragged along by the sponge (its centre following the sponge by 90 % along the rows, 50 % across): the rows
    wipe less than COVERAGE; strokes over the cells left, from where the plate now stands, wipe
    them."""
    tr = _trace()
    _wipe_along(tr, _rows(tr, (1.0, 2.0), 0.0),
                lambda xy: np.array([1.0 + 0.9 * (xy[0] - 1.0), 2.0 + 0.5 * (xy[1] - 2.0)]))
    assert 0.3 < tr.coverage < COVERAGE
    here = np.array([1.03, 2.0])
    for _ in range(2):
        _wipe_along(tr, _touch_up_rows(tr, here, 0.0), lambda xy: here)
    assert tr.coverage >= COVERAGE + TOUCH_UP_MARGIN
    assert _touch_up_rows(SimpleNamespace(**{**tr.__dict__, "wiped": np.ones_like(tr.wiped)}), here, 0.0) == []


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


def test_the_fridge_staging_point_is_free_for_the_planner_and_its_side_leg_misses_the_leaf():
    """A fridge in a corner (west wall at x = 0, its front at y = 2, the door's leaf open along
    x = 0.75 down to y = 1.2): the base pose before it (x = 0.39) lies inside the planner's 0.4 m
    disc round the wall, so the planned drive ends at a free point aside, further back than the
    leaf's end (the sideways leg would hit it nearer), and the base drives on straight in."""
    import pytest

    from stages.demos.driver import ExpertFailure
    from stages.demos.planner import NavGrid
    from stages.demos.base_approach import HALF_WIDTH, staging

    walls = np.array([(-0.1, -0.1, 0.0, 3.0), (0.0, 2.0, 0.8, 2.8), (-0.1, -0.1, 3.0, 0.0)])
    leaf = np.array([(0.75, y) for y in np.linspace(1.2, 2.0, 30)])
    grid = NavGrid.from_boxes((-0.2, -0.2, 3.0, 3.0), np.vstack([walls, [(0.72, 1.2, 0.78, 2.0)]]))
    goal = (0.39, 1.62, math.pi / 2)
    point, behind = staging(grid, goal, leaf)
    blocked = grid.inflate(0.40)
    iy, ix = grid.cell_of(*point)
    assert not blocked[iy, ix]
    assert behind[0] == pytest.approx(0.39) and behind[1] < 1.62 - 0.35
    assert point[0] >= behind[0] + 0.04  # aside, away from the wall
    # the chassis (0.3 m either way along the way in) on the sideways leg stays off the leaf
    assert behind[1] + 0.3 < 1.2 or point[0] + HALF_WIDTH < 0.75
    # a way in walled off on both sides has no staging point
    shut = NavGrid.from_boxes((-0.2, -0.2, 3.0, 3.0), np.vstack([walls, [(0.72, -0.1, 3.0, 2.0)]]))
    with pytest.raises(ExpertFailure, match="no free point"):
        staging(shut, goal, leaf)


def test_paper_counts_as_thrown_away_inside_the_can_below_its_rim():
    from stages.demos.skill_trash import throw_away_success

    can = SimpleNamespace(position=(1.0, 1.0, 0.0), asset=SimpleNamespace(params={
        "shape": 0.0, "rim_radius": 0.14, "height": 0.3, "wall": 0.005}), body=lambda: "/C")
    paper = SimpleNamespace(body=lambda: "/P")
    inst = SimpleNamespace(world=SimpleNamespace(placed={"trash_can": can, "paper": paper}))
    upright = Pose(position=(1.0, 1.0, 0.0))

    def check(p, can_pose=upright, opening=0.08):
        return throw_away_success(inst, _state({"/C": can_pose, "/P": Pose(position=p)}, opening=opening))

    assert check((1.05, 0.95, 0.03)) == (True, "")
    assert check((1.05, 0.95, 0.35))[1] == "object_not_in_container"  # above the rim (on the lid, held)
    assert check((1.2, 1.0, 0.03))[1] == "object_not_in_container"    # beside it on the floor
    tipped = Pose(position=(1.0, 1.0, 0.0), orientation=(math.cos(0.5), math.sin(0.5), 0.0, 0.0))
    assert check((1.0, 1.0, 0.03), tipped)[1] == "container_tipped"
    # the can pushed 10 cm: the paper inside it where it stands now
    assert check((1.1, 1.0, 0.03), Pose(position=(1.1, 1.0, 0.0))) == (True, "")
