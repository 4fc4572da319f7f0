"""Base path planning over an occupancy grid and a follower producing base velocity commands.

Frame: world, Z up, metres. A :class:`NavGrid` covers ``[x0, x0 + nx * cell] x [y0, y0 + ny * cell]``;
``occupied[iy, ix]`` is True where an obstacle overlaps the cell (row 0 at the smallest y, as the
layout stage's :class:`stages.layout.occupancy.OccupancyGrid`, which :meth:`NavGrid.from_layout`
reads). Planning runs A* (8-connected, octile heuristic) on the grid inflated by the robot's
footprint radius, then shortcuts the cell path to a few straight segments that stay in free cells.
:class:`PathFollower` turns a path into holonomic base commands (vx, vy in the base frame [m/s],
vtheta [rad/s]): pure pursuit on a lookahead point, speed and turn rate acceleration-limited (ramped
up, and planned down before the goal and before each path vertex), yaw turning to the goal yaw on
the way.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from stages.simulate.cooperative import checkpoint


class NoPathError(RuntimeError):
    """Start or goal is blocked, or no free path joins them."""


@dataclass(frozen=True, eq=False)
class NavGrid:
    """origin: (x, y) of cell (0, 0)'s corner [m]; cell: edge [m]; occupied: (ny, nx) bool."""

    origin: tuple[float, float]
    cell: float
    occupied: np.ndarray

    @staticmethod
    def from_boxes(bounds: tuple[float, float, float, float], boxes: np.ndarray,
                   cell: float = 0.05) -> NavGrid:
        """A grid over ``bounds`` (xmin, ymin, xmax, ymax) [m] with the axis-aligned ``boxes``
        (K, 4) [xmin, ymin, xmax, ymax] marked occupied (every cell they overlap)."""
        x0, y0, x1, y1 = bounds
        nx, ny = int(math.ceil((x1 - x0) / cell)), int(math.ceil((y1 - y0) / cell))
        occ = np.zeros((ny, nx), bool)
        for bx0, by0, bx1, by1 in np.asarray(boxes, float).reshape(-1, 4):
            i0, i1 = max(0, int(math.floor((bx0 - x0) / cell))), min(nx, int(math.ceil((bx1 - x0) / cell)))
            j0, j1 = max(0, int(math.floor((by0 - y0) / cell))), min(ny, int(math.ceil((by1 - y0) / cell)))
            if i1 > i0 and j1 > j0:  # a box beyond the grid's low side would wrap round (negative ends)
                occ[j0:j1, i0:i1] = True
        return NavGrid((x0, y0), cell, occ)

    @staticmethod
    def from_layout(grid) -> NavGrid:
        """From a layout :class:`~stages.layout.occupancy.OccupancyGrid` (its ``occupied`` cells)."""
        return NavGrid(tuple(grid.origin), float(grid.cell), np.asarray(grid.occupied, bool))

    def inflate(self, radius: float) -> np.ndarray:
        """(ny, nx) bool: cells whose centre is closer than ``radius`` [m] to an occupied cell."""
        from scipy import ndimage

        dist = ndimage.distance_transform_edt(~self.occupied) * self.cell
        return dist < radius + 0.5 * self.cell

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        c = self.cell
        return int(math.floor((y - self.origin[1]) / c)), int(math.floor((x - self.origin[0]) / c))

    def center(self, iy: int, ix: int) -> tuple[float, float]:
        return self.origin[0] + (ix + 0.5) * self.cell, self.origin[1] + (iy + 0.5) * self.cell


def astar(blocked: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]]:
    """Shortest 8-connected path of cells (iy, ix) from ``start`` to ``goal`` avoiding ``blocked``
    (no corner cutting). Raises NoPathError."""
    ny, nx = blocked.shape
    for name, c in (("start", start), ("goal", goal)):
        if not (0 <= c[0] < ny and 0 <= c[1] < nx) or blocked[c]:
            raise NoPathError(f"{name} cell {c} is outside the grid or blocked")
    moves = [(-1, 0, 1.0), (1, 0, 1.0), (0, -1, 1.0), (0, 1, 1.0),
             (-1, -1, math.sqrt(2)), (-1, 1, math.sqrt(2)), (1, -1, math.sqrt(2)), (1, 1, math.sqrt(2))]

    def h(c):
        dy, dx = abs(c[0] - goal[0]), abs(c[1] - goal[1])
        return max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)

    g = {start: 0.0}
    parent: dict = {start: None}
    heap = [(h(start), 0.0, start)]
    while heap:
        _, gc, c = heapq.heappop(heap)
        if c == goal:
            path = [c]
            while parent[path[-1]] is not None:
                path.append(parent[path[-1]])
            return path[::-1]
        if gc > g[c]:
            continue
        for dy, dx, cost in moves:
            n = (c[0] + dy, c[1] + dx)
            if not (0 <= n[0] < ny and 0 <= n[1] < nx) or blocked[n]:
                continue
            if dy and dx and (blocked[c[0] + dy, c[1]] or blocked[c[0], c[1] + dx]):
                continue
            ng = gc + cost
            if ng < g.get(n, math.inf):
                g[n], parent[n] = ng, c
                heapq.heappush(heap, (ng + h(n), ng, n))
    raise NoPathError(f"no free path from cell {start} to cell {goal}")


def _line_free(blocked: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Whether the straight segment between the centres of cells ``a`` and ``b`` crosses only free
    cells (sampled every quarter cell)."""
    n = int(math.ceil(4 * math.hypot(b[0] - a[0], b[1] - a[1]))) + 2
    ys = np.floor(np.linspace(a[0] + 0.5, b[0] + 0.5, n)).astype(int)
    xs = np.floor(np.linspace(a[1] + 0.5, b[1] + 0.5, n)).astype(int)
    return not blocked[ys, xs].any()


def plan_path(grid: NavGrid, start_xy, goal_xy, robot_radius: float) -> np.ndarray:
    """Waypoints (N, 2) [m] from ``start_xy`` to ``goal_xy`` for a robot of footprint radius
    ``robot_radius`` [m]: A* on the inflated grid, shortcut to line-of-sight segments, with the exact
    start and goal as first and last points. Raises NoPathError."""
    checkpoint()  # a search of milliseconds: a cooperative scheduler may run another world first
    blocked = grid.inflate(robot_radius)
    s, g = grid.cell_of(*start_xy), grid.cell_of(*goal_xy)
    cells = astar(blocked, s, g)
    keep = [cells[0]]
    i = 0
    while i < len(cells) - 1:
        j = len(cells) - 1
        while j > i + 1 and not _line_free(blocked, cells[i], cells[j]):
            j -= 1
        keep.append(cells[j])
        i = j
    pts = [grid.center(*c) for c in keep]
    pts[0], pts[-1] = tuple(start_xy), tuple(goal_xy)
    return np.asarray(pts, float)


def wrap(a: float) -> float:
    return float((a + math.pi) % (2 * math.pi) - math.pi)


@dataclass
class PathFollower:
    """Holonomic pure pursuit with speed profiles. path (N, 2) [m]; goal_yaw [rad]; v_max [m/s];
    w_max [rad/s]; accel [m/s^2] / alpha [rad/s^2]: the most the (world-frame) velocity and the
    turn rate change per second (commands come every ``dt`` [s]; the speed is planned down at
    ``brake`` of ``accel`` before the goal and before every path vertex, where the velocity turns
    by ``v_corner`` [m/s] at most); lookahead [m]; corner: how close [m] to a path vertex the carrot
    moves on to the next segment (the most a corner is cut); k_pos [1/s] / k_yaw [1/s]: the
    proportional gains of the last centimetres and degrees; pos_tol [m] / yaw_tol [rad]: when
    :meth:`command` reports done."""

    path: np.ndarray
    goal_yaw: float
    v_max: float = 1.0
    w_max: float = 1.8
    accel: float = 1.5
    alpha: float = 4.0
    brake: float = 0.8
    v_corner: float = 0.25
    dt: float = 1.0 / 30.0
    lookahead: float = 0.35
    corner: float = 0.05
    pos_tol: float = 0.01
    yaw_tol: float = 0.01
    k_pos: float = 6.0
    k_yaw: float = 6.0

    def __post_init__(self) -> None:
        self._v = np.zeros(2)  # the last command's world-frame velocity [m/s]
        self._w = 0.0

    def command(self, x: float, y: float, theta: float) -> tuple[tuple[float, float, float], bool]:
        """Base-frame command (vx, vy, vtheta) for the current base pose, and whether the goal is reached."""
        p = np.array([x, y])
        goal = self.path[-1]
        d_goal = float(np.linalg.norm(goal - p))
        e_yaw = wrap(self.goal_yaw - theta)
        if d_goal < self.pos_tol and abs(e_yaw) < self.yaw_tol:
            lim, n_v = self.accel * self.dt, float(np.linalg.norm(self._v))
            if n_v <= lim and abs(self._w) <= self.alpha * self.dt:
                self._v, self._w = np.zeros(2), 0.0
                return (0.0, 0.0, 0.0), True
            # arrived still moving: brake at ``accel`` (a stop from speed would jump the command)
            self._v = self._v * max(0.0, 1.0 - lim / max(n_v, 1e-12))
            self._w = float(np.clip(0.0, self._w - self.alpha * self.dt, self._w + self.alpha * self.dt))
            c, s = math.cos(theta), math.sin(theta)
            vx, vy = c * self._v[0] + s * self._v[1], -s * self._v[0] + c * self._v[1]
            return (float(vx), float(vy), self._w), False
        target, to_vertex, v_vertex = self._lookahead_point(p)
        d = target - p
        n = float(np.linalg.norm(d))
        a = self.brake * self.accel
        speed = min(self.v_max, math.sqrt(2 * a * d_goal), self.k_pos * d_goal,
                    math.sqrt(v_vertex ** 2 + 2 * a * to_vertex))
        want = d / n * speed if n > 1e-9 else np.zeros(2)
        dv = want - self._v
        dv_n = float(np.linalg.norm(dv))
        lim = self.accel * self.dt
        v_world = self._v = want if dv_n <= lim else self._v + dv * (lim / dv_n)
        c, s = math.cos(theta), math.sin(theta)
        vx, vy = c * v_world[0] + s * v_world[1], -s * v_world[0] + c * v_world[1]
        b = self.brake * self.alpha
        w_abs = min(self.w_max, math.sqrt(2 * b * abs(e_yaw)), self.k_yaw * abs(e_yaw))
        dw = self.alpha * self.dt
        w = float(np.clip(math.copysign(w_abs, e_yaw), self._w - dw, self._w + dw))
        self._w = w
        return (float(vx), float(vy), w), False

    def _vertex_speed(self, i: int) -> float:
        """The speed [m/s] at path vertex ``i``: the velocity turns there by at most ``v_corner``."""
        u, v = self.path[i] - self.path[i - 1], self.path[i + 1] - self.path[i]
        cos = float(np.dot(u, v) / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-12))
        chord = 2.0 * math.sin(0.5 * math.acos(min(1.0, max(-1.0, cos))))  # |dv| / v
        return min(self.v_max, self.v_corner / max(chord, 1e-6))

    def _lookahead_point(self, p: np.ndarray) -> tuple[np.ndarray, float, float]:
        """The point ``lookahead`` along the path past the closest point to ``p``, the distance
        [m] to the next path vertex and the speed [m/s] to pass it at (inf and 0 on the last
        segment)."""
        best, best_d, best_seg, best_t = None, math.inf, 0, 0.0
        for i in range(len(self.path) - 1):
            a, b = self.path[i], self.path[i + 1]
            ab = b - a
            t = float(np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-12), 0.0, 1.0))
            q = a + t * ab
            dd = float(np.linalg.norm(p - q))
            if dd < best_d:
                best, best_d, best_seg, best_t = q, dd, i, t
        if best is None:
            return self.path[-1], math.inf, 0.0
        # the carrot stays on the current segment until the base is within ``corner`` of its end,
        # so corners are cut by at most that much (a holonomic base turns on the spot)
        a, b = self.path[best_seg], self.path[best_seg + 1]
        length = float(np.linalg.norm(b - a))
        left = (1 - best_t) * length
        if best_seg == len(self.path) - 2:
            return a + min(1.0, best_t + self.lookahead / max(length, 1e-12)) * (b - a), math.inf, 0.0
        v_vertex = self._vertex_speed(best_seg + 1)
        if left > self.corner:
            return a + min(1.0, best_t + self.lookahead / max(length, 1e-12)) * (b - a), left, v_vertex
        c = self.path[best_seg + 2]
        nxt = b + min(1.0, self.lookahead / max(float(np.linalg.norm(c - b)), 1e-12)) * (c - b)
        return nxt, 0.0, v_vertex
