"""Room geometry for the placement solver: a room's interior outline (wall faces), its doors' and
windows' keep-out zones (``RoomContext``), the layout's collider boxes, and the robot-path grid
(``PathGrid``: occupancy of a floor, connectivity of doors and reach zones). Lengths in meters.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import math

import numpy as np

from stages.layout.floorplan import FloorPlan, RoomModel
from stages.scene.collide import ConvexPiece, box_piece
from stages.scene.geom import convex_hull_2d, points_in_convex


def room_interior(plan: FloorPlan, room: RoomModel) -> np.ndarray:
    """(K, 2) CCW interior outline of a rectilinear room: its polygon with each edge moved to the
    face of the walls along it [m]."""
    poly = np.asarray(room.polygon, dtype=np.float64)
    walls = plan.floors[room.floor].walls
    k = len(poly)
    lines = []  # per edge: (axis 0 for vertical x = c, 1 for horizontal y = c, c)
    for i in range(k):
        a, b = poly[i], poly[(i + 1) % k]
        d = b - a
        n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-12)  # inward for CCW
        horizontal = abs(d[1]) < 1e-9
        c = a[1] if horizontal else a[0]
        lo, hi = sorted((a[0], b[0]) if horizontal else (a[1], b[1]))
        face = c
        for w in walls:
            if (abs(w.start[1] - w.end[1]) < 1e-9) != horizontal:
                continue
            x0, y0, x1, y1 = w.box
            across = (y0, y1) if horizontal else (x0, x1)
            along = (x0, x1) if horizontal else (y0, y1)
            if across[0] - 1e-6 <= c <= across[1] + 1e-6 and min(along[1], hi) - max(along[0], lo) > 0.05:
                inward_face = across[1] if (n[1] if horizontal else n[0]) > 0 else across[0]
                if (inward_face - c) * (n[1] if horizontal else n[0]) > (face - c) * (n[1] if horizontal else n[0]):
                    face = inward_face
        lines.append((1 if horizontal else 0, face))
    out = []
    for i in range(k):
        (ax0, c0), (ax1, c1) = lines[i - 1], lines[i]
        if ax0 == ax1:
            continue
        x = c0 if ax0 == 0 else c1
        y = c0 if ax0 == 1 else c1
        out.append((x, y))
    return np.asarray(out, dtype=np.float64)


def _edges(poly: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, float, np.ndarray]]:
    """(start, unit direction, length, inward normal) of each edge of a CCW polygon."""
    out = []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        d = b - a
        L = float(np.linalg.norm(d))
        if L > 1e-6:
            t = d / L
            out.append((a, t, L, np.array([-t[1], t[0]])))
    return out


def _rect(center: np.ndarray, along: np.ndarray, half_w: float, normal: np.ndarray, depth: float,
          back: float = 0.0) -> np.ndarray:
    """CCW rectangle: width 2 half_w along ``along``, from ``back`` behind to ``depth`` in front of
    ``center`` along ``normal``."""
    c = [center + along * s * half_w + normal * d for s, d in ((-1, -back), (1, -back), (1, depth), (-1, depth))]
    return convex_hull_2d(np.array(c))


def layout_pieces(layout_usd: Path, floor_z: tuple[float, float] | None = None) -> list[ConvexPiece]:
    """Collider boxes of the layout layer (Cube prims with CollisionAPI, translate + scale) as pieces
    (owner = prim path), optionally only those overlapping the height range floor_z [m]."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(layout_usd))
    if layer is None:
        raise ValueError(f"{layout_usd}: cannot open the layout layer")
    out: list[ConvexPiece] = []

    def visit(path):
        spec = layer.GetPrimAtPath(path)
        if spec is None:
            return
        if spec.typeName == "Cube" and "xformOp:translate" in spec.attributes:
            t = np.asarray(spec.attributes["xformOp:translate"].default, dtype=np.float64)
            s = np.asarray(spec.attributes["xformOp:scale"].default, dtype=np.float64)
            lo, hi = t - s / 2, t + s / 2
            if floor_z is None or (lo[2] < floor_z[1] and hi[2] > floor_z[0]):
                out.append(box_piece(lo, hi, owner=str(path)))
        for child in spec.nameChildren:
            visit(child.path)

    visit(Sdf.Path.absoluteRootPath)
    return out


class PathGrid:
    """Occupancy of one floor for the path check: the plan's occupied cells plus the footprints of
    floor-standing assets. ``check`` says whether every door of a room and every reach zone stay
    connected for a robot needing a ``path_width`` wide corridor."""

    def __init__(self, plan: FloorPlan, floor: int, path_width: float):
        g = plan.occupancy(floor)
        self.origin = np.asarray(g.origin, dtype=np.float64)
        self.cell = float(g.cell)
        self.base = g.occupied.copy()
        self.shape = self.base.shape
        self.radius = path_width / 2
        self.blocks: dict[str, np.ndarray] = {}
        self._free_key: tuple | None = None  # the block masks _free_mask was computed with
        self._free_mask = np.zeros(self.shape, dtype=bool)
        self._labels: np.ndarray | None = None  # components() of _free_mask

    def raster(self, poly: np.ndarray) -> np.ndarray:
        """(ny, nx) bool: cells whose center lies inside the convex polygon (world [m])."""
        ny, nx = self.shape
        lo = np.floor((poly.min(axis=0) - self.origin) / self.cell).astype(int) - 1
        hi = np.ceil((poly.max(axis=0) - self.origin) / self.cell).astype(int) + 1
        lo = np.clip(lo, 0, [nx, ny])
        hi = np.clip(hi, 0, [nx, ny])
        out = np.zeros(self.shape, dtype=bool)
        if hi[0] <= lo[0] or hi[1] <= lo[1]:
            return out
        xs = self.origin[0] + (np.arange(lo[0], hi[0]) + 0.5) * self.cell
        ys = self.origin[1] + (np.arange(lo[1], hi[1]) + 0.5) * self.cell
        X, Y = np.meshgrid(xs, ys)
        inside = points_in_convex(np.stack([X.ravel(), Y.ravel()], axis=1), poly, margin=-self.cell * 0.5)
        out[lo[1]:hi[1], lo[0]:hi[0]] = inside.reshape(X.shape)
        return out

    def components(self, extra: np.ndarray | None = None) -> np.ndarray:
        """Connected-component labels of the cells where the robot's center may be (0: none)."""
        from scipy import ndimage

        thr = self.radius + self.cell * 0.5
        free = self._free()
        if extra is None:
            if self._labels is None:
                self._labels = ndimage.label(free, structure=np.ones((3, 3), dtype=bool))[0]
            return self._labels
        if extra.any():  # cells near the extra occupancy only: the rest keep their distance to it
            win, d = self._local_dist(extra, thr)
            free = free.copy()
            free[win] &= d >= thr
        labels, _ = ndimage.label(free, structure=np.ones((3, 3), dtype=bool))
        return labels

    def _free(self) -> np.ndarray:
        """(ny, nx) bool: cells at least path_width / 2 (+ half a cell) away from the base occupancy and
        every block; computed again only when ``blocks`` changed (the same mask objects: cached)."""
        from scipy import ndimage

        key = tuple(self.blocks.values())
        if self._free_key is None or len(key) != len(self._free_key) or any(
                a is not b for a, b in zip(key, self._free_key)):
            occ = self.base.copy()
            for m in key:
                occ |= m
            dist = ndimage.distance_transform_edt(~occ) * self.cell
            self._free_mask = dist >= self.radius + self.cell * 0.5
            self._free_key, self._labels = key, None
        return self._free_mask

    def _local_dist(self, mask: np.ndarray, limit: float) -> tuple[tuple[slice, slice], np.ndarray]:
        """(window, distance [m] to the nearest True cell of ``mask`` in that window): the window
        holds every True cell and every cell closer than ``limit`` [m] to one; the distances are
        those of a whole-grid Euclidean distance transform (the same integer offsets). ``mask``
        must have a True cell."""
        from scipy import ndimage

        pad = int(math.ceil(limit / self.cell)) + 2
        ys, xs = np.nonzero(mask)
        y0, y1 = max(int(ys.min()) - pad, 0), min(int(ys.max()) + pad + 1, self.shape[0])
        x0, x1 = max(int(xs.min()) - pad, 0), min(int(xs.max()) + pad + 1, self.shape[1])
        win = (slice(y0, y1), slice(x0, x1))
        return win, ndimage.distance_transform_edt(~mask[win]) * self.cell

    def cell_label(self, labels: np.ndarray, xy: np.ndarray, within: float = 0.45) -> int:
        """Label of the reachable cell nearest to xy within ``within`` [m] (0 if none)."""
        ny, nx = self.shape
        c = ((xy - self.origin) / self.cell).astype(int)
        r = int(math.ceil(within / self.cell))
        x0, x1 = max(c[0] - r, 0), min(c[0] + r + 1, nx)
        y0, y1 = max(c[1] - r, 0), min(c[1] + r + 1, ny)
        sub = labels[y0:y1, x0:x1]
        if not sub.any():
            return 0
        iy, ix = np.nonzero(sub)
        d = (ix + x0 - c[0]) ** 2 + (iy + y0 - c[1]) ** 2
        k = int(np.argmin(d))
        return int(sub[iy[k], ix[k]])

    def reach_mask(self, footprint: np.ndarray, reach: float) -> np.ndarray:
        from scipy import ndimage

        m = self.raster(footprint)
        if not m.any():
            c = ((footprint.mean(axis=0) - self.origin) / self.cell).astype(int)
            if 0 <= c[1] < self.shape[0] and 0 <= c[0] < self.shape[1]:
                m[c[1], c[0]] = True
        if not m.any():
            return ndimage.distance_transform_edt(~m) * self.cell <= reach
        win, d = self._local_dist(m, reach)  # farther cells are out of reach
        out = np.zeros(self.shape, dtype=bool)
        out[win] = d <= reach
        return out


@dataclass(frozen=True)
class RoomContext:
    """A room being populated: plan, room, its interior polygon, door points (inside the room, [m])
    and door keep-out zones, window keep-outs with sill heights, floor elevation [m]."""

    room: RoomModel
    interior: np.ndarray
    door_points: tuple[np.ndarray, ...]
    door_zones: tuple[np.ndarray, ...]
    windows: tuple[tuple[np.ndarray, float], ...]
    elevation: float
    height: float  # clear height of the room [m]


def room_context(plan: FloorPlan, room: RoomModel, door_clearance: float) -> RoomContext:
    interior = room_interior(plan, room)
    fl = plan.floors[room.floor]
    pts, zones = [], []
    for d in fl.doors:
        if room.id not in d.rooms:
            continue
        n = np.asarray(d.normal, dtype=np.float64)
        n_in = -n if d.rooms[0] == room.id else n
        c = np.asarray(d.position, dtype=np.float64)
        along = np.array([-n[1], n[0]])
        wall = next((w for w in fl.walls if w.id == d.wall), None)
        half_t = (wall.thickness / 2) if wall else 0.1
        pts.append(c + n_in * (half_t + 0.4))
        zones.append(_rect(c, along, d.width / 2 + 0.1, n_in, half_t + door_clearance))
    wins = []
    for w in fl.windows:
        if w.room != room.id:
            continue
        wall = next((x for x in fl.walls if x.id == w.wall), None)
        c = np.asarray(w.position, dtype=np.float64)
        cen = np.asarray(room.polygon, dtype=np.float64).mean(axis=0)
        horizontal = wall is not None and abs(wall.start[1] - wall.end[1]) < 1e-9
        n_in = np.array([0.0, np.sign(cen[1] - c[1]) or 1.0]) if horizontal else np.array([np.sign(cen[0] - c[0]) or 1.0, 0.0])
        along = np.array([-n_in[1], n_in[0]])
        wins.append((_rect(c, along, w.width / 2, n_in, 0.6), float(w.sill)))
    return RoomContext(room, interior, tuple(pts), tuple(zones), tuple(wins), fl.elevation, fl.ceiling_height)


@dataclass
class RoomReport:
    """What happened in one room: placed counts per category, rejected candidates by reason, and
    the arrangements of the room that were given up (a required entry failed) with the reason."""

    room: str
    room_type: str
    placed: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)
    arrangements_rejected: list[str] = field(default_factory=list)

    def reject(self, reason: str) -> None:
        self.rejected[reason] = self.rejected.get(reason, 0) + 1
