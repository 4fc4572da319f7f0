"""Navigation occupancy grids per floor.

A grid covers the footprint [0, W] x [0, D]; ``grid[iy, ix]`` is the cell
[x0 + ix * cell, x0 + (ix + 1) * cell] x [y0 + iy * cell, y0 + (iy + 1) * cell] (row 0 at the
smallest y: an image of it appears upside-down). A cell is *occupied* when it overlaps a wall (doors
cut out), a staircase going up, a stairwell opening or a railing; *traversable* when the robot's
center may stand there: free and at least ``robot_radius`` from every occupied cell (exact distance from the cell
center to the occupied cells' squares).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stages.layout.geom2d import Rect, rects_minus
from stages.layout.model import HousePlan

FREE, INFLATED, OCCUPIED = 255, 128, 0  # PNG encoding of the occupancy image


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """origin: (x, y) of cell (0, 0)'s corner [m]; cell: edge [m]; robot_radius [m];
    occupied, traversable: (ny, nx) bool; room_index: (ny, nx) int16, index into the floor's rooms
    (cell center inside the room's outline), -1 outside every room."""

    floor: int
    origin: tuple[float, float]
    cell: float
    robot_radius: float
    occupied: np.ndarray
    traversable: np.ndarray
    room_index: np.ndarray

    def to_image(self) -> np.ndarray:
        """(ny, nx) uint8: 0 occupied, 128 free but too close for the robot, 255 traversable."""
        img = np.full(self.occupied.shape, INFLATED, dtype=np.uint8)
        img[self.occupied] = OCCUPIED
        img[self.traversable] = FREE
        return img

    @staticmethod
    def from_images(floor: int, origin: tuple[float, float], cell: float, robot_radius: float,
                    occ: np.ndarray, rooms: np.ndarray) -> "OccupancyGrid":
        """Inverse of ``to_image`` (+ the room image, index + 1 with 0 for none)."""
        return OccupancyGrid(floor, origin, cell, robot_radius, occ == OCCUPIED, occ == FREE,
                             rooms.astype(np.int16) - 1)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(iy, ix) of the cell holding point (x, y) [m]."""
        return int(math.floor((y - self.origin[1]) / self.cell)), int(math.floor((x - self.origin[0]) / self.cell))

    def is_traversable(self, x: float, y: float) -> bool:
        iy, ix = self.cell_of(x, y)
        ny, nx = self.traversable.shape
        return 0 <= iy < ny and 0 <= ix < nx and bool(self.traversable[iy, ix])


def _cover(a: int, b: int, c: int) -> tuple[int, int]:
    """Cells [i0, i1) overlapping [a, b] (cm), cell c cm."""
    return a // c, -(-b // c)


def _centers(a: int, b: int, c: int) -> tuple[int, int]:
    """Cells [i0, i1) whose centers lie in [a, b) (cm)."""
    return -(-(2 * a - c) // (2 * c)), -(-(2 * b - c) // (2 * c))


def _inflate(boxes: list[tuple[int, int, int, int]], nx: int, ny: int, radius: float) -> np.ndarray:
    """(ny, nx) bool: cells whose center lies closer than ``radius`` (in cells) to a box of cells
    [i0, i1) x [j0, j1) (exact Euclidean distance to the box)."""
    out = np.zeros((ny, nx), dtype=bool)
    r = int(math.ceil(radius))
    r2 = radius * radius
    for i0, j0, i1, j1 in boxes:
        a0, a1 = max(i0 - r, 0), min(i1 + r, nx)
        b0, b1 = max(j0 - r, 0), min(j1 + r, ny)
        if a1 <= a0 or b1 <= b0:
            continue
        ci = np.arange(a0, a1) + 0.5
        cj = np.arange(b0, b1) + 0.5
        dx = np.maximum(np.maximum(i0 - ci, ci - i1), 0.0)
        dy = np.maximum(np.maximum(j0 - cj, cj - j1), 0.0)
        out[b0:b1, a0:a1] |= (dy[:, None] ** 2 + dx[None, :] ** 2) < r2
    return out


def floor_obstacles(plan: HousePlan, f: int) -> list[Rect]:
    """2-D obstacles of floor f [cm]: walls with doors cut out, stairs, stairwell openings, rails."""
    fl = plan.floors[f]
    out: list[Rect] = []
    for w in fl.walls:
        doors = [o.rect(w) for o in fl.openings if o.wall == w.id and o.kind != "window"]
        out.extend(rects_minus([w.box], doors) if doors else [w.box])
    out.extend(plan.obstacles(f))
    return out


def occupancy_grid(plan: HousePlan, f: int, cell: float, robot_radius: float) -> OccupancyGrid:
    """Rasterize floor f (see module docstring)."""
    c = int(round(cell * 100))
    fp = plan.footprint
    nx, ny = -(-fp.w // c), -(-fp.h // c)
    occ = np.zeros((ny, nx), dtype=bool)
    obstacles_cells = []
    for r in floor_obstacles(plan, f):
        i0, i1 = _cover(r.x0 - fp.x0, r.x1 - fp.x0, c)
        j0, j1 = _cover(r.y0 - fp.y0, r.y1 - fp.y0, c)
        occ[max(j0, 0):min(j1, ny), max(i0, 0):min(i1, nx)] = True
        obstacles_cells.append((i0, j0, i1, j1))
    trav = ~occ & ~_inflate(obstacles_cells, nx, ny, robot_radius / cell)
    rooms = np.full((ny, nx), -1, dtype=np.int16)
    for k, room in enumerate(plan.floors[f].rooms):
        for r in room.rects:
            i0, i1 = _centers(r.x0 - fp.x0, r.x1 - fp.x0, c)
            j0, j1 = _centers(r.y0 - fp.y0, r.y1 - fp.y0, c)
            rooms[max(j0, 0):min(j1, ny), max(i0, 0):min(i1, nx)] = k
    return OccupancyGrid(f, (fp.x0 / 100, fp.y0 / 100), cell, robot_radius, occ, trav, rooms)
