"""Where a base the planner counts blocked escapes to (issue 16, store_food in generated flats:
flat_004 seed 1, after open_fridge the base stood 0.04 m inside the open leaf's inflated sweep;
``_escape`` shifted it to the free region's edge, the shift ended 2.5 cm short, still blocked, and
pick_place_fridge's drive failed: ``no_path: start cell ... blocked``). Real planner grid; no
simulation."""

from __future__ import annotations

import math

import numpy as np

from stages.demos.articulated import ESCAPE_MARGIN, escape_target
from stages.demos.driver import ROBOT_RADIUS
from stages.demos.part_planning import is_free
from stages.demos.planner import NavGrid


def _room():
    """A 4 x 3 m room (walls 0.1 m thick) with a 0.1 m wide leaf standing 0.8 m out of the north wall at x = 2."""
    walls = [(0, 0, 4, 0.1), (0, 2.9, 4, 3), (0, 0, 0.1, 3), (3.9, 0, 4, 3), (1.95, 2.1, 2.05, 2.9)]
    return NavGrid.from_boxes((-0.2, -0.2, 4.2, 3.2), np.asarray(walls, float))


def test_a_blocked_base_escapes_into_the_free_region_not_onto_its_edge():
    grid = _room()
    blocked = grid.inflate(ROBOT_RADIUS)
    x, y = 2.3, 2.0  # 0.25 m from the leaf: blocked for the 0.40 m disc
    assert not is_free(grid, blocked, x, y)
    tx, ty = escape_target(grid, x, y, reach=1.0)
    assert is_free(grid, blocked, tx, ty)
    # a shift that ends up to 5 cm short of the target still leaves the base where the planner starts
    u = np.array([tx - x, ty - y]) / math.hypot(tx - x, ty - y)
    for short in (0.025, 0.05):
        px, py = np.array([tx, ty]) - short * u
        assert is_free(grid, blocked, float(px), float(py)), (short, (tx, ty))
    assert math.hypot(tx - x, ty - y) <= 1.0 + ESCAPE_MARGIN


def test_a_free_base_stays():
    assert escape_target(_room(), 1.0, 1.5) is None
