"""The third-person view of a house room (``stages.demos.house_room.view_over``): an eye on the room's
free floor that sees the work surface and the other furniture a room's tasks go to (the kitchen's
fridge, the living room's bookshelf), checked by projecting the corners into the camera."""

from __future__ import annotations

import math

import numpy as np

from stages.demos.house_room import VIEW_ASPECT, VIEW_HALF_ANGLE, VIEW_HEIGHT, VIEW_MIN_DISTANCE, view_over

AREA = (0.0, 0.0, 4.0, 2.8)  # a kitchen-sized room [m]
WALLS = [(-0.1, -0.1, 4.1, 0.0), (-0.1, 2.8, 4.1, 2.9), (-0.1, 0.0, 0.0, 2.8), (4.0, 0.0, 4.1, 2.8)]
COUNTER = (0.4, 2.1, 2.2, 2.8)  # along the north wall
FRIDGE = (2.35, 2.1, 2.95, 2.8)


def _in_view(eye, target, pts) -> bool:
    f = np.subtract(target, eye)
    f /= np.linalg.norm(f)
    right = np.cross(f, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    d = np.asarray(pts, float) - eye
    depth = d @ f
    tan = math.tan(VIEW_HALF_ANGLE)
    return bool((depth > 0).all() and (abs(d @ right) <= tan * VIEW_ASPECT * depth).all()
                and (abs(d @ up) <= tan * depth).all())


def test_the_view_sees_the_counter_and_the_fridge_from_the_free_floor():
    rects = [(COUNTER[0], COUNTER[1] - 0.5, COUNTER[2], COUNTER[3]), FRIDGE]
    boxes = WALLS + [COUNTER, FRIDGE, (3.2, 0.0, 4.0, 0.6)]  # and a cupboard in the south-east corner
    got = view_over(rects, AREA, boxes, 0.9)
    assert got is not None
    eye, target = got
    assert eye[2] == VIEW_HEIGHT and 0.2 <= eye[0] <= 3.8 and 0.2 <= eye[1] <= 2.6
    assert not any(b[0] - 0.25 < eye[0] < b[2] + 0.25 and b[1] - 0.25 < eye[1] < b[3] + 0.25 for b in boxes)
    assert math.dist(eye, target) >= VIEW_MIN_DISTANCE
    assert eye[1] < target[1]  # from the base's side (-Y) of the counter
    corners = [(x, y, 0.9) for x in (0.4, 2.95) for y in (1.6, 2.8)]
    assert _in_view(np.array(eye), np.array(target), corners)


def test_no_view_when_nothing_in_the_room_sees_everything():
    # furniture at both ends of a long narrow room: no eye inside sees both at once
    area = (0.0, 0.0, 12.0, 1.2)
    assert view_over([(0.0, 0.0, 1.0, 1.2), (11.0, 0.0, 12.0, 1.2)], area, [], 0.9) is None
