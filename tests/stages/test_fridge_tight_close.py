"""Closing a fridge door opened in a tight kitchen (issue 16, store_food in generated flats: flat_002
of the house benchmark, job seed 0): the leaf opened 81 deg faces its hinge side, where the wall is
0.62 m away, and the kitchen is 1.85 m deep before the fridge. The push bases round the free edge are
free, but the straight leg of the drive (``Driver.drive_to`` stages ``part_planning.STAGING`` behind
the goal) starts in the south wall's inflation: with it 1 candidate base (close_fridge
``no_base_pose`` in 2 of 3 seeds); staged ``driver.NEAR_STAGING`` behind (the Driver falls back to
that where the farther point is blocked) 20-odd. Geometry only (the flat's door, walls and floor
furniture), no simulation."""

from __future__ import annotations

import math

import numpy as np

from stages.demos.driver import NEAR_STAGING, ROBOT_RADIUS
from stages.demos.part_planning import STAGING, _swing_bases, is_free, swept_grid
from stages.demos.parts import ArticulatedPart
from stages.demos.planner import NavGrid

OPEN = 1.45  # [rad] where open_fridge leaves the leaf (its goal 0.9 x 90 deg, a little past it)


def _flat_002():
    """(door, NavGrid): flat_002's fridge_04 door (front -Y, hinge at x 3.25, handle at x 2.52) and its
    kitchen's walls and floor furniture (task frame)."""
    part = ArticulatedPart(asset_id="fridge_04", category="fridge", role="door", joint_path="/door_0_joint",
                           link="door_0", kind="revolute", axis=(0.0, 0.0, 1.0), origin=(3.2458, 2.1181, 0.8967),
                           lower=0.0, upper=math.pi / 2, closed=0.0, handle=(2.5194, 2.0745, 1.0579),
                           bar_axis=(0.0, 0.0, 1.0), grip_width=0.01963, clearance=0.03384, front=(0.0, -1.0, 0.0))
    walls = [(3.89, 0.0, 4.1, 6.25), (-3.64, 0.0, 3.89, 0.21), (-0.07, 2.83, 3.89, 2.97), (-0.07, 0.21, 0.07, 6.04)]
    furniture = [(2.469, 2.065, 3.249, 2.81), (0.221, 2.152, 2.406, 2.81)]  # fridge, counter
    return part, NavGrid.from_boxes((-0.2, -0.2, 4.3, 3.1), np.asarray(walls + furniture, float))


def _closing():
    part, grid = _flat_002()
    step = -math.radians(6.0)
    qs = [float(v) for v in np.arange(OPEN + step, part.closed + 0.5 * step, step)] + [part.closed + 0.01]
    return part, grid, swept_grid(grid, part, part.closed, OPEN), qs


def test_the_staging_point_is_what_leaves_no_push_base():
    part, grid, plan, qs = _closing()
    far = _swing_bases(part, plan, OPEN, qs, spread=140.0)
    near = _swing_bases(part, plan, OPEN, qs, spread=140.0, staging=NEAR_STAGING)
    assert STAGING > NEAR_STAGING
    assert len(far) <= 1 and len(near) >= 10
    blocked = plan.inflate(ROBOT_RADIUS)
    h = part.handle_at(OPEN)
    for x, y, yaw in near:
        # free, round the open leaf's free edge (south of it: before the fridge), its near staging free too
        assert is_free(plan, blocked, x, y) and y < h[1]
        assert is_free(plan, blocked, x - NEAR_STAGING * math.cos(yaw), y - NEAR_STAGING * math.sin(yaw))
    # the far staging point of the new bases is blocked for the planner: the drive must stage nearer
    assert any(not is_free(plan, blocked, x - STAGING * math.cos(yaw), y - STAGING * math.sin(yaw))
               for x, y, yaw in near if (x, y, yaw) not in far)
