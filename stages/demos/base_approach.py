"""Driving the mobile base up to furniture with an open leaf (the fridge's, the wardrobe's) or along
a narrow way in (the bookshelf): the leaf's footprint, the grid with the leaf on it, the staging
point of the planned drive and the drive there (the caller drives the last straight stretch).

Used by the store-food, organize-books and organize-wardrobe skills. Frame: world, Z up, metres,
radians.
"""

from __future__ import annotations

import math

import numpy as np

from stages.demos.driver import ExpertFailure

HALF_WIDTH = 0.25 + 0.06  # the chassis half width and a margin to the open leaf [m]
CHASSIS = 0.60           # chassis length [m]


def leaf_points(part, q: float) -> np.ndarray:
    """Points (N, 2) [m] covering the door leaf (and its handle) at joint value ``q``."""
    from stages.demos.part_grasps import lateral

    o = np.asarray(part.origin, float)
    a = np.asarray(part.axis, float)
    v = np.asarray(part.handle, float) - o
    reach = float(np.linalg.norm(v - np.dot(v, a) * a)) + 0.08
    lat, n, rot = lateral(part), np.asarray(part.front, float), part.rotation_at(q)
    return np.array([(o + rot @ (t * reach * lat + off * n))[:2]
                     for t in np.linspace(0.0, 1.0, 40) for off in (-0.03, 0.04, 0.11)])


def grid_with_leaf(world, part, q: float):
    """The world's occupancy grid with the hinged ``part``'s leaf at joint value ``q`` marked."""
    from stages.demos.part_planning import swept_grid

    return swept_grid(world.grid(), part, q, q)


def staging(grid, goal, leaf: np.ndarray, *, approach: float = 0.35, more: float = 1.5,
            side: float = 0.6) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the planned drive to ``goal`` (x, y, yaw) ends: ``(point, behind)``: the point
    ``approach`` [m] behind the goal on its way in, or where that is blocked for the planner (its
    0.4 m disc near a wall or the open leaf: a fridge in a corner), the free point nearest it up to
    ``more`` further back and ``side`` [m] aside whose sideways drive onto the way in keeps the
    chassis clear of the ``leaf`` (points (N, 2), world) [m]; ``behind`` (x, y): the point on the way
    in level with it, from where the base drives straight in (the chassis, narrower than the disc,
    fits). ExpertFailure("no_path") when there is none."""
    from stages.demos.driver import ROBOT_RADIUS

    blocked = grid.inflate(ROBOT_RADIUS)
    gx, gy, th = goal
    u, v = np.array([math.cos(th), math.sin(th)]), np.array([-math.sin(th), math.cos(th)])
    cands = [(abs(o) + 0.5 * (a - approach), a, o) for a in np.arange(approach, approach + more + 1e-9, 0.05)
             for o in np.arange(-side, side + 1e-9, 0.05)]
    for _, a, o in sorted(cands):
        behind = np.array([gx, gy]) - a * u
        p = behind + o * v
        iy, ix = grid.cell_of(float(p[0]), float(p[1]))
        if not (0 <= iy < blocked.shape[0] and 0 <= ix < blocked.shape[1]) or blocked[iy, ix]:
            continue
        # the chassis (its half length ahead and behind) along the sideways leg, and on the way in
        rel = leaf - behind
        along, across = rel @ u, rel @ v
        lo, hi = min(0.0, o), max(0.0, o)
        near = (np.abs(along) < CHASSIS / 2 + 0.06) & (across > lo - HALF_WIDTH) & (across < hi + HALF_WIDTH)
        if not near.any():
            return (float(p[0]), float(p[1])), (float(behind[0]), float(behind[1]))
    raise ExpertFailure("no_path", f"no free point behind the base pose {goal} before the fridge")


def drive_in(d, grid, goal, leaf: np.ndarray, **kw) -> tuple[tuple[float, float], tuple[float, float]]:
    """Drive the base to the ``staging`` point of ``goal`` (x, y, yaw) (``leaf``, ``kw``: as there) and,
    where that point lies aside, sideways onto the way in; the caller drives the last straight stretch.
    Returns staging's ``(point, behind)`` (the way back out)."""
    point, behind = staging(grid, goal, leaf, **kw)
    d.drive_to((*point, goal[2]), grid, approach=0.0)
    if math.dist(point, behind) > 0.02:
        d.drive_straight((*behind, goal[2]))  # sideways onto the way in
    return point, behind
