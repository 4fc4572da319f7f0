"""Opening a fridge door whose handle's arc runs out of floor (issue 16, store_food in generated
flats: a fridge against one wall, the counter 1.5 m before it): the half-open leaf is pushed on by
its inner face with the closed hand from before the fridge's opening (``mode="inner"``), and the
plans only take base poses the planner reaches from where the base stands (a half-open leaf can cut
the kitchen in two). Geometry only: the fridge door of a generated flat (flat_007 of the house
benchmark, fridge_01), no simulation."""

from __future__ import annotations

import math

import numpy as np

from stages.demos.part_grasps import INNER_INBOARD, LEAF_THICKNESS, PUSH_STANDOFF, _edge_gap, gesture, lateral
from stages.demos.part_planning import _swing_bases, connected
from stages.demos.parts import ArticulatedPart
from stages.demos.planner import NavGrid


def _fridge_door() -> ArticulatedPart:
    """flat_007's fridge door: front +Y, hinge at x = 2.61 (right), handle at x = 1.79."""
    return ArticulatedPart(asset_id="fridge_01", category="fridge", role="door", joint_path="/door_0_joint",
                           link="door_0", kind="revolute", axis=(0.0, 0.0, -1.0), origin=(2.608, 0.7, 0.701),
                           lower=0.0, upper=math.pi / 2, closed=0.0, handle=(1.788, 0.746, 1.071),
                           bar_axis=(0.0, 0.0, 1.0), grip_width=0.02463, clearance=0.03324, front=(0.0, 1.0, 0.0))


def _room(wall_y: float | None = None) -> NavGrid:
    """A 4 x 3.4 m kitchen (walls round it, 5 cm cells) with the fridge's body against its south
    wall; ``wall_y``: a wall across it at that y [m] from x = 0 to 2.3 (a door leaf)."""
    occ = np.zeros((68, 80), bool)
    occ[:2], occ[-2:], occ[:, :2], occ[:, -2:] = True, True, True, True
    occ[:14, 34:54] = True  # the fridge body (x 1.7-2.7, y 0-0.7)
    if wall_y is not None:
        occ[int(wall_y / 0.05), :] = True
    return NavGrid((0.0, 0.0), 0.05, occ)


def test_inner_push_presses_the_inner_face_outward():
    part = _fridge_door()
    q0 = math.radians(48.0)
    qs = [q0 + math.radians(6.0) * k for k in range(1, 7)]
    approach, arc = gesture(part, q0, qs, 0.0, mode="inner")
    h, n0, lat = np.asarray(part.handle), np.asarray(part.front), lateral(part)
    front_face = h - (part.clearance + part.grip_width / 2) * n0 - (INNER_INBOARD - _edge_gap(part)) * lat
    for q, pose, off in [(q0, approach[-1], PUSH_STANDOFF), *((q, p, 0.0) for q, p in zip(qs, arc))]:
        n = part.front_at(q)
        rel = pose[:3, 3] - part.point_at(front_face, q)
        assert abs(rel @ n + LEAF_THICKNESS + off) < 1e-6, (q, rel @ n)  # behind the inner face
        assert pose[:3, 2] @ n > 0.99, q  # the fist pushes along the front normal: opening
        # INNER_INBOARD in from the free edge, along the leaf
        assert abs((part.point_at(h, q) - pose[:3, 3]) @ (part.rotation_at(q) @ lat)
                   - (INNER_INBOARD - _edge_gap(part))) < 1e-6
    # the approach comes from behind the leaf, not round its free edge
    assert (approach[0][:3, 3] - approach[-1][:3, 3]) @ part.front_at(q0) < -0.1


def test_inner_bases_stand_behind_the_leaf():
    part = _fridge_door()
    q0 = math.radians(48.0)
    qs = [q0 + math.radians(6.0) * k for k in range(1, 7)]
    bases = _swing_bases(part, _room(), q0, qs, spread=80.0, inner=True)
    assert bases
    h, n = part.handle_at(q0)[:2], part.front_at(q0)[:2]
    assert all((np.asarray(b[:2]) - h) @ n < 0.0 for b in bases)
    front = _swing_bases(part, _room(), q0, qs)
    assert all((np.asarray(b[:2]) - h) @ n > -0.2 for b in front)  # (the default: before the leaf)


def test_bases_only_where_the_base_can_drive():
    part = _fridge_door()
    room = _room(wall_y=1.55)  # the kitchen cut in two
    q0 = math.radians(48.0)
    qs = [q0 + math.radians(6.0) * k for k in range(1, 7)]
    south = connected(room, (1.0, 1.0))
    assert south[room.cell_of(1.0, 1.1)] and not south[room.cell_of(1.0, 2.5)]
    every = _swing_bases(part, room, q0, qs)
    kept = _swing_bases(part, room, q0, qs, within=south)
    assert kept and len(kept) < len(every)
    assert all(south[room.cell_of(b[0], b[1])] for b in kept)
    # a start in a blocked cell counts from the nearest free one (where the experts escape to)
    assert connected(room, (1.0, 1.52))[room.cell_of(1.0, 1.1)]


def test_counter_pose_beside_the_open_leaf():
    """pick_place_fridge takes the mug from a counter pose whose planned drive ends before the
    open leaf (flat_007: the counter 1.5 m before the fridge, the mug's usual pose 0.28 m from the
    leaf at 90 deg: ``no_path``)."""
    from stages.demos.counter import COUNTER_STAGE, facing_north_goal
    from stages.demos.driver import ROBOT_RADIUS
    from stages.demos.part_planning import is_free, swept_grid
    from stages.demos.skill_fridge import COUNTER_SHIFT, MUG_OFF, counter_x

    part = _fridge_door()
    room = _room()
    room.occupied[int(2.2 / 0.05):, 20:66] = True  # the counter, its front at y = 2.2, x 1.0-3.3
    open_leaf = swept_grid(room, part, math.pi / 2, math.pi / 2)
    blocked = open_leaf.inflate(ROBOT_RADIUS)

    def stage_free(x):
        gx, gy, _ = facing_north_goal(2.2, x)
        return is_free(open_leaf, blocked, gx, gy - COUNTER_STAGE)

    assert not stage_free(2.33)
    # the mug beside the microwave on its handle side, towards the leaf (seed 1 of flat_007: 0.45 m off)
    x = counter_x(open_leaf, 2.2, 2.33, 2.6)
    assert x != 2.33 and stage_free(x) and abs(x - 2.33) <= COUNTER_SHIFT + 1e-9 and abs(x - 2.6) <= MUG_OFF
    assert not stage_free(x + 0.011)  # the nearest free one
    assert counter_x(open_leaf, 2.2, 2.33, 2.9) == 2.33  # not further than MUG_OFF from the mug
    assert counter_x(room, 2.2, 2.33, 2.2) == 2.33  # the leaf closed: where it was
