"""The organize-books skill (issue 16, ``stages.demos.skill_books``) without a simulation: a start pose
with a roll stands a catalog book spine up (the engine's free-joint coordinates), the episode's books
stand apart on the coffee table's near band, each goes to its own spot side by side on a reachable
board with room above it, the predicate accepts a book standing on a board and names what is wrong
otherwise, and the household rule admits only books the Franka hand grasps across their covers."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from asset_catalog.asset_model import Pose
from stages.simulate.state import BasePose, RobotState, StepState


def _rot(q) -> np.ndarray:
    from stages.demos.skill_books import _rot as rot

    return rot(q)


def _quat_wxyz(pose) -> tuple:
    from stages.demos.sampling import object_coords

    c = object_coords(pose)
    return (c[6], c[3], c[4], c[5])


def _book(name: str, length: float, width: float, thick: float):
    """A placed catalog book (the generator's frame: length along X, width along Y with the spine at
    -Y, thickness along Z from 0)."""
    asset = SimpleNamespace(lo=(-length / 2, -width / 2, 0.0), hi=(length / 2, width / 2, thick), params={},
                            asset_id=name)
    return SimpleNamespace(asset=asset, body=lambda: f"/World/Objects/{name}/base", position=(0.0, 0.0, 0.0),
                           yaw=0.0, name=f"Objects/{name}")


BOARDS = tuple((1.0, 3.0, 1.9, 3.27, z, 0.30) for z in (0.02, 0.35, 0.68, 1.01, 1.34))


def _world(boards=BOARDS):
    """A living room's facts: the coffee table's top (x 1-2, y 1-1.6 at 0.42 m), two books, the paper
    and a bookshelf against the north wall (its front, asset +X, facing -Y) with ``boards``."""
    shelf = SimpleNamespace(yaw=-math.pi / 2, position=(1.45, 3.14, 0.0))
    paper = SimpleNamespace(body=lambda: "/World/Objects/paper/base")
    return SimpleNamespace(usd="scene.usda", table_rect=(1.0, 1.0, 2.0, 1.6), table_z=0.42, shelves=boards,
                           placed={"book_1": _book("book_a", 0.24, 0.144, 0.033),
                                   "book_2": _book("book_b", 0.156, 0.118, 0.042),
                                   "paper": paper, "bookshelf": shelf})


def _state(objects: dict, ee=(0.0, 0.0, 2.0), opening: float = 0.08) -> StepState:
    robot = RobotState(joint_names=(), q=np.zeros(0), qd=np.zeros(0), ee_pose=Pose(position=ee),
                       base=BasePose(x=0.0, y=0.0, theta=0.0), gripper_opening=opening)
    return StepState(time=0.0, step=0, world=0, robot=robot, objects=objects, scene_joints={})


def test_a_start_pose_with_a_roll_stands_the_book_spine_up():
    """(x, y, z, yaw) keeps its quaternion (a yaw about +Z); (x, y, z, yaw, roll) rolls about the
    body's X first: the book's spine (local -Y) up, its length (local X) along the yaw."""
    from stages.demos.sampling import object_coords
    from stages.demos.skill_books import STAND_ROLL

    assert object_coords((1.0, 2.0, 3.0, 0.7)) == pytest.approx((1.0, 2.0, 3.0, 0.0, 0.0, math.sin(0.35),
                                                                 math.cos(0.35)))
    r = _rot(_quat_wxyz((0.0, 0.0, 0.0, 0.3, STAND_ROLL)))
    assert r @ (0.0, -1.0, 0.0) == pytest.approx((0.0, 0.0, 1.0), abs=1e-9)
    assert r @ (1.0, 0.0, 0.0) == pytest.approx((math.cos(0.3), math.sin(0.3), 0.0), abs=1e-9)


def test_the_episode_stands_the_books_apart_on_the_tables_near_band():
    from stages.demos.skill_trash import PAPER_AT
    from stages.demos.skill_books import BOOK_DX, BOOK_IN, book_setup, book_state

    w = _world()
    poses = book_setup(w, 3)
    assert poses == book_setup(w, 3)  # its own stream: the same every time for a seed
    centres = []
    for role in ("book_1", "book_2"):
        b = w.placed[role]
        pose = poses[b.body()]
        q = _quat_wxyz(pose)
        st = _state({b.body(): Pose(position=pose[:3], orientation=q)})
        c, r = book_state(st, b)
        lo, hi = b.asset.lo, b.asset.hi
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        world = corners @ r.T + pose[:3]
        assert world[:, 2].min() == pytest.approx(w.table_z + 0.001, abs=1e-9)   # standing on the top
        assert -r[2, 1] > 0.999                                                # spine up
        assert abs(r[0, 0]) < 0.07 and r[1, 0] > 0.99                          # its length across the table
        assert w.table_rect[0] < world[:, 0].min() and world[:, 0].max() < w.table_rect[2]
        assert world[:, 1].min() == pytest.approx(w.table_rect[1] + BOOK_IN, abs=0.02)
        centres.append(c)
    assert centres[1][0] - centres[0][0] == pytest.approx(BOOK_DX, abs=0.021)
    px, py = poses[w.placed["paper"].body()][:2]
    assert (px, py) == pytest.approx((w.table_rect[0] + PAPER_AT[0], w.table_rect[1] + PAPER_AT[1]))


def test_a_room_without_two_books_has_no_organize_books_episode():
    from pipeline.types import ItemError
    from stages.demos.skill_books import book_setup

    w = _world()
    del w.placed["book_2"]
    with pytest.raises(ItemError, match="needs 2 books"):
        book_setup(w, 1)


def test_the_books_go_side_by_side_on_the_reachable_board_with_room_above():
    """Of boards 0.02-1.34 m high the one nearest 0.75 m (0.68), the books' spots SPOT_DX apart across
    it, their centres EDGE_IN behind its front edge; boards too low for the hand over the tallest book,
    or all out of reach, give no_board."""
    from stages.demos.driver import ExpertFailure
    from stages.demos.skill_books import EDGE_IN, HAND_ROOM, SPOT_DX, shelf_spot

    w = _world()
    spots = [shelf_spot(w, k) for k in (0, 1)]
    assert all(s.board[4] == 0.68 for s in spots)
    assert spots[0].front == pytest.approx((0.0, -1.0), abs=1e-9)
    assert spots[0].edge[1] == pytest.approx(3.0) and spots[1].edge[1] == pytest.approx(3.0)
    assert abs(spots[1].edge[0] - spots[0].edge[0]) == pytest.approx(SPOT_DX)
    for s in spots:
        x0, y0, x1, y1 = s.board[:4]
        assert s.centre == pytest.approx((s.edge[0], s.edge[1] + EDGE_IN))  # EDGE_IN in from the front (-Y)
        assert x0 < s.centre[0] < x1 and y0 < s.centre[1] < y1
    low = tuple((*b[:5], 0.144 + HAND_ROOM - 0.01) for b in BOARDS)
    with pytest.raises(ExpertFailure, match="no board"):
        shelf_spot(_world(low), 0)
    with pytest.raises(ExpertFailure, match="no board"):
        shelf_spot(_world(tuple(b for b in BOARDS if b[4] < 0.4 or b[4] > 1.2)), 0)


def test_a_book_counts_as_shelved_standing_on_a_board_released():
    from stages.demos.skill_books import STAND_ROLL, shelve_book_success, standing_pose

    w = _world()
    inst = SimpleNamespace(world=w)
    b = w.placed["book_1"]

    def at(centre, bottom, roll=STAND_ROLL, yaw=math.pi / 2, ee=(1.0, 2.0, 1.5), opening=0.08):
        pose = standing_pose(b, centre, bottom, yaw)[:4] + (roll,)
        if roll != STAND_ROLL:  # lying on a cover: its origin (the bottom cover) on the surface
            pose = (*centre, bottom, yaw, roll)
        st = _state({b.body(): Pose(position=pose[:3], orientation=_quat_wxyz(pose))}, ee=ee, opening=opening)
        return shelve_book_success(inst, st, k=0)

    board = (1.3, 3.13)
    assert at(board, 0.68) == (True, "")
    assert at(board, 0.73)[1] == "not_on_shelf"                     # held 5 cm over it
    assert at((1.3, 1.3), 0.42)[1] == "not_on_shelf"                 # still on the coffee table
    assert at((1.3, 2.95), 0.68)[1] == "not_on_shelf"                # its centre off the board's front
    assert at(board, 0.68, roll=0.0)[1] == "book_tipped"             # fallen onto a cover
    assert at(board, 0.68, ee=(1.3, 3.13, 0.80), opening=0.033)[1] == "object_still_held"
    assert shelve_book_success(inst, _state({}), k=2)[1] == "no_book"


def test_the_household_rule_admits_only_books_grasped_across_their_covers():
    """The living room's coffee-table book entry (``thickness``) fits exactly the generator's books
    THICKNESS thick (10 variants); an inverted range is a rule error."""
    from asset_catalog.generators import GENERATORS_BY_CATEGORY, generate
    from stages.demos.skill_books import THICKNESS
    from stages.scene.rules import HOUSEHOLD_TASK_RULES, ObjectRule, load_rules

    entry = next(e for e in load_rules(HOUSEHOLD_TASK_RULES).for_room("living_room").objects
                 if e.category == "book" and "coffee_table" in e.on)
    assert entry.count == (2, 2)
    seen = set()
    for k in range(10):
        a = generate(GENERATORS_BY_CATEGORY["book"], np.random.default_rng(k), f"book_{k:02d}")
        pts = np.vstack([p.vertices for lk in a.model.links for p in lk.visuals])
        dims = tuple(float(v) for v in pts.max(0) - pts.min(0))
        fits = THICKNESS[0] <= dims[2] <= THICKNESS[1]
        seen.add(fits)
        assert entry.fits(SimpleNamespace(dimensions=dims)) == fits, (k, dims)
    assert seen == {True, False}
    with pytest.raises(ValueError, match="thickness"):
        ObjectRule(category="book", thickness=(0.05, 0.02))
