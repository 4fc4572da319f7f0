"""Placement solver: populate the rooms of a floor plan following the rules (``stages.scene.rules``).

Room by room, each furniture entry of the rules is sampled (its mode gives candidate poses: against
a wall, facing another asset, in front of / beside / around a target, free on the floor), and a
candidate is kept only if

- its 2-D footprint lies inside the room's interior (wall faces), keeps ``min_gap`` to other
  floor-standing assets and stays out of keep-out zones (room doors, windows for tall assets, the
  front clearances and door/drawer swings of assets already placed), and its own clearance and
  swing zones are inside the room and free;
- its colliders do not penetrate the layout's colliders or any placed asset's by more than 1 mm
  (``stages.scene.collide``, on the convex collider pieces);
- the robot path stays connected: on the floor's occupancy grid with the footprints added, the
  free space eroded by ``path_width / 2`` still joins every door of the room and the reach zone of
  every interactable placed so far.

Then objects are placed on support surfaces (tops, shelves, seats, beds) of the furniture named by
their rule, resting 1 mm above it, collision-checked the same way, and kept only if reachable.
Randomness comes only from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from asset_catalog.index import CatalogRecord
from stages.layout.floorplan import FloorPlan, RoomModel
from stages.scene.assets import AssetGeometry, load_asset_geometry
from stages.scene.collide import ConvexPiece, box_piece, find_penetrations
from stages.scene.geom import (
    convex_hull_2d, convex_inside, convex_overlap, points_in_convex, points_in_polygon, polygon_area, rot2, rot3)
from stages.scene.rules import FurnitureRule, ObjectRule, PlacementRules

log = logging.getLogger(__name__)

REST_GAP = 0.001          # [m] assets are placed this far above their support
PLACE_GAP = 0.0005         # [m] while sampling, a new asset keeps this gap to every collider (it rests
                           # REST_GAP above its support): touching neighbours would be pushed apart
WINDOW_SILL_MARGIN = 0.3   # [m] assets taller than a window's sill + this stay away from it


class PlacementFailure(Exception):
    """A populate attempt failed (a required rule could not be met); the message says why."""


@dataclass(frozen=True)
class Placement:
    """One placed asset: instance id, catalog record, room id, floor index, position of the asset
    origin [m] (3,), yaw [rad] about +Z, support instance id (None: the floor)."""

    inst: str
    record: CatalogRecord
    room: str
    floor: int
    position: tuple[float, float, float]
    yaw: float
    support: str | None = None

    def matrix(self) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3] = rot3(self.yaw)
        m[:3, 3] = self.position
        return m


@dataclass
class _Inst:
    p: Placement
    geo: AssetGeometry
    pieces: list[ConvexPiece]
    footprint: np.ndarray          # world (K, 2)
    block: np.ndarray | None       # world footprint that blocks the robot, or None
    zones: list[np.ndarray]        # world keep-out zones (clearance, swings)
    on_floor: bool
    reach: np.ndarray | None = None  # cached reach-zone mask on its floor's path grid


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


@dataclass(frozen=True)
class Library:
    """The catalog as the solver sees it: ok records by category, and where their packages are."""

    records: dict[str, tuple[CatalogRecord, ...]]
    root: Path  # usd_path of a record is relative to this folder

    @staticmethod
    def from_index(index_path: Path) -> "Library":
        from asset_catalog.index import query_index

        by: dict[str, list[CatalogRecord]] = {}
        for r in query_index(index_path):
            if r.usd_path:
                by.setdefault(r.category, []).append(r)
        return Library({k: tuple(v) for k, v in by.items()}, Path(index_path).parent)

    def usd(self, r: CatalogRecord) -> Path:
        return (self.root / str(r.usd_path)).resolve()

    def pick(self, category: str, room_type: str, rng: np.random.Generator,
             keep=None) -> CatalogRecord | None:
        """A random record of the category (preferring those annotated for the room type); ``keep``:
        optional predicate on records."""
        recs = [r for r in self.records.get(category, ()) if keep is None or keep(r)]
        fit = [r for r in recs if room_type in r.room_types] or list(recs)
        return fit[int(rng.integers(len(fit)))] if fit else None


# ---------------------------------------------------------------------------------------------
# room geometry


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


# ---------------------------------------------------------------------------------------------
# the robot path


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

        occ = self.base.copy()
        for m in self.blocks.values():
            occ |= m
        if extra is not None:
            occ |= extra
        dist = ndimage.distance_transform_edt(~occ) * self.cell
        free = dist >= self.radius + self.cell * 0.5
        labels, _ = ndimage.label(free, structure=np.ones((3, 3), dtype=bool))
        return labels

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
        return ndimage.distance_transform_edt(~m) * self.cell <= reach


# ---------------------------------------------------------------------------------------------
# the solver


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


class Populator:
    """Places assets into the rooms of one floor plan; holds every placed instance (all floors)."""

    def __init__(self, plan: FloorPlan, layout_usd: Path, library: Library, rules: PlacementRules,
                 rng: np.random.Generator):
        self.plan, self.library, self.rules, self.rng = plan, library, rules, rng
        self.layout = layout_pieces(layout_usd)
        self.insts: list[_Inst] = []
        self.grids: dict[int, PathGrid] = {}
        self.counter: Counter[str] = Counter()
        self.reports: list[RoomReport] = []
        self.room_ctx: dict[str, RoomContext] = {}
        self._compact = 0.0  # > 0: furniture restricted to this fraction of each category's narrowest variants

    # -- public ---------------------------------------------------------------------------------

    def populate_room(self, room: RoomModel) -> RoomReport:
        """Place furniture then objects in ``room``. When a required entry cannot be placed, the room
        is emptied again and re-arranged (up to ``room_attempts`` arrangements, each recorded with
        its reason in ``RoomReport.arrangements_rejected``); raises PlacementFailure when all fail."""
        rt = str(room.type)
        rr = self.rules.for_room(rt)
        rep = RoomReport(room.id, rt)
        self.reports.append(rep)
        ctx = room_context(self.plan, room, self.rules.setting(rt, "door_clearance"))
        grid = self.grids.get(room.floor)
        if grid is None:
            grid = self.grids[room.floor] = PathGrid(self.plan, room.floor, self.rules.setting(rt, "path_width"))
        labels = grid.components()
        live = tuple(p for p in ctx.door_points if grid.cell_label(labels, p))
        ctx = replace(ctx, door_points=live)  # doors the robot can use in the empty room
        self.room_ctx[room.id] = ctx
        n_arr = self.rules.defaults.room_attempts
        for a in range(n_arr):
            mark, counts = len(self.insts), Counter(self.counter)
            # the later half of the arrangements furnishes with ever more compact variants (a small
            # room): the narrower half of each category's variants, down to the narrowest one
            half = n_arr // 2
            self._compact = 0.5 * (1.0 - (a - half) / max(n_arr - half, 1)) if n_arr > 1 and a >= half else 0.0
            try:
                for rule in rr.furniture:
                    self._entry(rule, ctx, grid, rep, furniture=True)
                for rule in rr.objects:
                    self._entry(rule, ctx, grid, rep, furniture=False)
                return rep
            except PlacementFailure as e:
                rep.arrangements_rejected.append(str(e))
                self._rollback(mark, counts)
                rep.placed.clear()
                rep.skipped.clear()
                log.debug("%s: arrangement %d rejected: %s", room.id, a, e)
        raise PlacementFailure(f"{rep.arrangements_rejected[-1]} [{n_arr} arrangements]")

    def _rollback(self, mark: int, counts: Counter) -> None:
        """Forget the instances placed after the first ``mark`` (one room's failed arrangement)."""
        gone = {i.p.inst for i in self.insts[mark:]}
        self.insts = self.insts[:mark]
        self.counter = counts
        for g in self.grids.values():
            for k in gone & set(g.blocks):
                del g.blocks[k]

    def placements(self) -> list[Placement]:
        return [i.p for i in self.insts]

    def instance_pieces(self) -> list[ConvexPiece]:
        return [p for i in self.insts for p in i.pieces]

    # -- entries --------------------------------------------------------------------------------

    def _entry(self, rule, ctx: RoomContext, grid: PathGrid, rep: RoomReport, *, furniture: bool) -> None:
        cats = Counter(i.p.record.category for i in self.insts if i.p.room == ctx.room.id)
        if rule.probability < 1.0 and self.rng.random() >= rule.probability:
            return
        missing = [c for c in rule.requires if not cats.get(c)]
        if missing:
            if rule.count[0] > 0:
                rep.skipped.append(f"{rule.category}: requires {', '.join(missing)}")
            return
        n = int(self.rng.integers(rule.count[0], rule.count[1] + 1))
        keep = (self._compact_keep(rule.category, self._compact) if self._compact else None) if furniture else (
            lambda r: load_asset_geometry(self.library.usd(r)).rests_flat)
        for k in range(n):
            rec = self.library.pick(rule.category, str(ctx.room.type), self.rng, keep)
            if rec is None:
                if not furniture and self.library.records.get(rule.category):
                    rep.skipped.append(f"{rule.category}: no variant with a flat base (it would roll)")
                    return
                if k < rule.count[0]:
                    raise PlacementFailure(f"{ctx.room.id}: no catalog asset of category {rule.category!r}")
                return
            ok = (self._place_furniture(rule, rec, ctx, grid, rep) if furniture
                  else self._place_object(rule, rec, ctx, grid, rep))
            if ok:
                rep.placed[rule.category] = rep.placed.get(rule.category, 0) + 1
            elif k < rule.count[0]:
                own = {r: v for r, v in rep.rejected.items() if r.startswith(f"{rule.category}:")}
                worst = max(own.items(), key=lambda kv: kv[1])[0] if own else "no candidate"
                raise PlacementFailure(f"{ctx.room.id}: could not place required {rule.category} ({worst})")

    def _compact_keep(self, category: str, fraction: float):
        """Predicate on records: the variant is among the ``fraction`` (at least one) of the
        category's variants that are narrowest along their back."""
        widths = {r.id: float(g.hi[1] - g.lo[1]) for r in self.library.records.get(category, ())
                  for g in (load_asset_geometry(self.library.usd(r)),)}
        if not widths:
            return None
        order = sorted(widths.values())
        limit = order[max(1, math.ceil(len(order) * fraction)) - 1]
        return lambda r: widths.get(r.id, math.inf) <= limit + 1e-9

    def _new_id(self, category: str) -> str:
        self.counter[category] += 1
        return f"{category}_{self.counter[category]:02d}"

    def _instance(self, rec: CatalogRecord, geo: AssetGeometry, ctx: RoomContext, xy: np.ndarray, z: float,
                  yaw: float, support: str | None, clearance: float) -> _Inst:
        inst = f"{rec.category}_{self.counter[rec.category] + 1:02d}"
        R3, t = rot3(yaw), np.array([xy[0], xy[1], z])
        pieces = [p.transformed(R3, t, owner=inst) for p in geo.pieces]
        R2 = R3[:2, :2]
        fp = geo.footprint @ R2.T + xy
        gfp = geo.ground_footprint
        block = gfp @ R2.T + xy if gfp is not None else None
        zones = [s @ R2.T + xy for s in geo.swings]
        if clearance > 0:
            front = np.array([math.cos(yaw), math.sin(yaw)])
            side = np.array([-front[1], front[0]])
            c = np.array([geo.hi[0], (geo.lo[1] + geo.hi[1]) / 2]) @ R2.T + xy
            zones.append(_rect(c, side, (geo.hi[1] - geo.lo[1]) / 2, front, clearance))
        p = Placement(inst, rec, ctx.room.id, ctx.room.floor, (float(xy[0]), float(xy[1]), float(z)), float(yaw), support)
        return _Inst(p, geo, pieces, fp, block, zones, support is None)

    # -- furniture ------------------------------------------------------------------------------

    def _narrower(self, rule: FurnitureRule, rec: CatalogRecord, geo: AssetGeometry, ctx: RoomContext):
        """Another variant of the category, narrower (along its back) than ``rec`` if there is one,
        else any other: (record, geometry)."""
        width = geo.hi[1] - geo.lo[1]

        def narrower(r: CatalogRecord) -> bool:
            g = load_asset_geometry(self.library.usd(r))
            return r.id != rec.id and g.hi[1] - g.lo[1] < width - 1e-6

        new = (self.library.pick(rule.category, str(ctx.room.type), self.rng, narrower)
               or self.library.pick(rule.category, str(ctx.room.type), self.rng) or rec)
        return new, load_asset_geometry(self.library.usd(new))

    def _place_furniture(self, rule: FurnitureRule, rec: CatalogRecord, ctx: RoomContext, grid: PathGrid,
                         rep: RoomReport) -> bool:
        geo = load_asset_geometry(self.library.usd(rec))
        tries = self.rules.defaults.max_tries
        no_room = False
        for k in range(tries):
            if k and (no_room or k % max(tries // 4, 1) == 0):
                # another variant of the category: a narrower one may fit where this one did not
                rec, geo = self._narrower(rule, rec, geo, ctx)
            # a target-relative mode that keeps failing falls back to a plain wall/floor position
            fallback = k >= tries // 2 and rule.mode in ("beside", "facing", "front", "around")
            pose = self._sample_pose(rule, geo, ctx, fallback=fallback)
            no_room = pose is None
            if pose is None:
                rep.reject(f"{rule.category}: no {rule.mode} position")
                continue
            xy, yaw = pose
            inst = self._instance(rec, geo, ctx, xy, ctx.elevation + REST_GAP - geo.lo[2], yaw, None, rule.clearance)
            why = self._floor_conflict(inst, rule, ctx, geo)
            no_room = why == "outside the room"
            if why is None:
                why = self._collides(inst)
            if why is None:
                why = self._path_conflict(inst, ctx, grid)
            if why is None:
                self._accept(inst, grid)
                return True
            rep.reject(f"{rule.category}: {why}")
        return False

    def _sample_pose(self, rule: FurnitureRule, geo: AssetGeometry, ctx: RoomContext, *, fallback: bool = False):
        gap = self.rules.setting(ctx.room.type, "wall_gap")
        mode = rule.mode
        if fallback:
            mode = "wall" if mode in ("beside", "facing") else "floor"
        targets = [i for i in self.insts if i.p.room == ctx.room.id and i.p.record.category == rule.target]
        if mode in ("front", "beside", "around") and not targets:
            mode = "wall" if mode == "beside" else "floor"
        if mode in ("wall", "facing"):
            return self._wall_pose(geo, ctx, gap, targets[0] if (mode == "facing" and targets) else None,
                                   tall=not rule.tall_ok_at_window, snap=rule.snap)
        if mode == "floor":
            return self._floor_pose(geo, ctx, rule.yaw_jitter)
        t = targets[int(self.rng.integers(len(targets)))]
        tg, ty = t.geo, t.p.yaw
        R = rot2(ty)
        txy = np.asarray(t.p.position[:2])
        d = float(self.rng.uniform(*rule.distance))
        if mode == "front":
            yaw = ty + math.pi + math.radians(self.rng.uniform(-rule.yaw_jitter, rule.yaw_jitter))
            f = R @ np.array([1.0, 0.0])
            jitter = float(self.rng.uniform(-0.15, 0.15)) * (tg.hi[1] - tg.lo[1]) / 2
            anchor = R @ np.array([tg.hi[0], (tg.lo[1] + tg.hi[1]) / 2 + jitter]) + txy + f * d
            return anchor - rot2(yaw) @ np.array([geo.hi[0], (geo.lo[1] + geo.hi[1]) / 2]), yaw
        if mode == "beside":
            along = R @ np.array([0.0, 1.0])
            poses = [R @ np.array([tg.lo[0], tg.hi[1]]) + txy + along * d - R @ np.array([geo.lo[0], geo.lo[1]]),
                     R @ np.array([tg.lo[0], tg.lo[1]]) + txy - along * d - R @ np.array([geo.lo[0], geo.hi[1]])]
            if self.rng.random() < 0.5:
                poses.reverse()
            # a random side, but one where the asset is inside the room when only one is
            fits = [xy for xy in poses if convex_inside(geo.footprint @ R.T + xy, ctx.interior)]
            return (fits or poses)[0], ty
        # around: a side of the target's box, facing its center
        k = int(self.rng.integers(4))
        out_dir = [np.array([1.0, 0.0]), np.array([-1.0, 0.0]), np.array([0.0, 1.0]), np.array([0.0, -1.0])][k]
        half = np.array([(tg.hi[0] - tg.lo[0]) / 2, (tg.hi[1] - tg.lo[1]) / 2])
        cen = np.array([(tg.hi[0] + tg.lo[0]) / 2, (tg.hi[1] + tg.lo[1]) / 2])
        tang = np.array([-out_dir[1], out_dir[0]])
        span = abs(tang @ half) * 0.6
        local = cen + out_dir * abs(out_dir @ half) + tang * float(self.rng.uniform(-span, span))
        world_out = R @ out_dir
        anchor = R @ local + txy + world_out * d
        yaw = math.atan2(-world_out[1], -world_out[0])
        return anchor - rot2(yaw) @ np.array([geo.hi[0], (geo.lo[1] + geo.hi[1]) / 2]), yaw

    def _free_wall_spans(self, edge, depth: float, height: float, ctx: RoomContext, tall: bool,
                         gap: float) -> list[tuple[float, float]]:
        """Free (start, end) spans [m along the edge] of a wall edge for an against-wall asset of
        ``depth`` and ``height`` [m]: the edge minus what reaches into its band (the strip
        ``gap + depth`` deep in front of it): room-door keep-outs, windows (when ``tall`` and the
        asset rises above sill + WINDOW_SILL_MARGIN), footprints (+ min_gap) and keep-out zones of
        floor-standing assets already placed. Conservative (projections of convex outlines)."""
        a, t, L, n = edge
        band = gap + depth
        blocked: list[tuple[float, float]] = []

        def block(poly: np.ndarray, pad: float = 0.0) -> None:
            rel = np.asarray(poly) - a
            s, h = rel @ t, rel @ n
            if h.min() < band and h.max() > 0.0:
                blocked.append((float(s.min()) - pad, float(s.max()) + pad))

        for dz in ctx.door_zones:
            block(dz)
        if tall:
            for wz, sill in ctx.windows:
                if height > sill + WINDOW_SILL_MARGIN:
                    block(wz)
        min_gap = self.rules.setting(ctx.room.type, "min_gap")
        for o in self.insts:
            if o.on_floor and o.p.floor == ctx.room.floor:
                block(o.footprint, min_gap)
                for z in o.zones:
                    block(z)
        spans, cur = [], 0.0
        for lo, hi in sorted(blocked):
            if lo > cur:
                spans.append((cur, min(lo, L)))
            cur = max(cur, hi)
            if cur >= L:
                break
        if cur < L:
            spans.append((cur, L))
        return spans

    def _wall_pose(self, geo: AssetGeometry, ctx: RoomContext, gap: float, facing: _Inst | None, *,
                   tall: bool = True, snap: float = 0.0):
        """Back against a free span of a wall (see ``_free_wall_spans``), front into the room; with
        probability ``snap`` pushed to one end of the span (a corner, a door or window edge, a
        neighbour); None when no span is wide enough."""
        width = geo.hi[1] - geo.lo[1]
        need = width + 0.02
        cands = []  # (edge, span start, span end)
        for e in _edges(ctx.interior):
            for s0, s1 in self._free_wall_spans(e, geo.hi[0] - geo.lo[0], geo.hi[2] - geo.lo[2], ctx, tall, gap):
                if s1 - s0 >= need:
                    cands.append((e, s0, s1))
        if not cands:
            return None
        w = np.array([s1 - s0 - width + 0.2 for _, s0, s1 in cands])  # tight spans keep a fair chance
        if facing is not None:
            f = rot2(facing.p.yaw) @ np.array([1.0, 0.0])
            opp = np.array([-(e[3] @ f) for e, _, _ in cands])
            if (opp > 0.5).any():
                w = w * (opp > 0.5)
        (a, t, L, n), s0, s1 = cands[int(self.rng.choice(len(cands), p=w / w.sum()))]
        lo, hi = s0 + width / 2 + 0.01, s1 - width / 2 - 0.01
        if snap > 0 and self.rng.random() < snap:
            s = lo if self.rng.random() < 0.5 else hi
        else:
            s = float(self.rng.uniform(lo, hi))
        yaw = math.atan2(n[1], n[0])
        anchor = a + t * s + n * gap
        return anchor - rot2(yaw) @ np.array([geo.lo[0], (geo.lo[1] + geo.hi[1]) / 2]), yaw

    def _floor_pose(self, geo: AssetGeometry, ctx: RoomContext, jitter: float):
        lo, hi = ctx.interior.min(axis=0), ctx.interior.max(axis=0)
        for _ in range(20):
            xy = self.rng.uniform(lo, hi)
            if points_in_polygon(xy[None], ctx.interior)[0]:
                yaw = int(self.rng.integers(4)) * math.pi / 2 + math.radians(self.rng.uniform(-jitter, jitter))
                cen = rot2(yaw) @ ((geo.lo[:2] + geo.hi[:2]) / 2)
                return xy - cen, yaw
        return None

    def _floor_conflict(self, inst: _Inst, rule: FurnitureRule, ctx: RoomContext, geo: AssetGeometry) -> str | None:
        if not convex_inside(inst.footprint, ctx.interior):
            return "outside the room"
        for z in inst.zones:
            if not convex_inside(z, ctx.interior):
                return "door/drawer swing or clearance outside the room"
        for dz in ctx.door_zones:
            if convex_overlap(inst.footprint, dz):
                return "in front of a room door"
        if not rule.tall_ok_at_window:
            for wz, sill in ctx.windows:
                if geo.hi[2] - geo.lo[2] > sill + WINDOW_SILL_MARGIN and convex_overlap(inst.footprint, wz):
                    return "blocks a window"
        gap = self.rules.setting(ctx.room.type, "min_gap")
        for o in self.insts:
            if not o.on_floor or o.p.floor != inst.p.floor:
                continue
            if convex_overlap(inst.footprint, o.footprint, gap):
                return f"footprint overlaps {o.p.record.category}"
            for z in o.zones:
                if convex_overlap(inst.footprint, z):
                    return f"in the swing/clearance zone of {o.p.record.category}"
            for z in inst.zones:
                if convex_overlap(z, o.footprint):
                    return f"its swing/clearance zone hits {o.p.record.category}"
        return None

    def _collides(self, inst: _Inst) -> str | None:
        others = self.layout + self.instance_pieces()
        hits = find_penetrations(inst.pieces, others, first_only=True, exact=False, tol=-PLACE_GAP)
        if hits:
            other = hits[0].owner_b
            what = other.rsplit("/", 2)[-2] if other.startswith("/") else other.rsplit("_", 1)[0]
            return f"colliders touch {what}" if hits[0].depth < 0.001 else f"colliders penetrate {what}"
        return None

    # -- path -----------------------------------------------------------------------------------

    def _door_labels_ok(self, grid: PathGrid, ctx: RoomContext, extra: np.ndarray | None) -> tuple[bool, int]:
        """Whether the room's doors (those reachable in the empty room) share one component."""
        labels = grid.components(extra)
        got = {grid.cell_label(labels, p) for p in ctx.door_points}
        got.discard(0)
        return len(got) <= 1, (next(iter(got)) if got else 0)

    def _reach_of(self, inst: _Inst, grid: PathGrid, reach: float) -> np.ndarray:
        if inst.reach is None:
            inst.reach = grid.reach_mask(inst.footprint, reach)
        return inst.reach

    def _path_conflict(self, inst: _Inst, ctx: RoomContext, grid: PathGrid) -> str | None:
        """Why adding ``inst`` would break the robot path of its room, or of a room populated
        earlier on the same floor (a path may run through a neighbour room); None if it does not."""
        if inst.block is None:
            return None
        extra = grid.raster(inst.block)
        labels = grid.components(extra)
        for rid, rctx in self.room_ctx.items():
            if rctx.room.floor != ctx.room.floor or not rctx.door_points:
                continue
            own = rid == ctx.room.id
            live = {d for d in (grid.cell_label(labels, p) for p in rctx.door_points) if d}
            where = "" if own else f" of {rid}"
            if len(live) != 1:
                if own:
                    return "cuts the robot path between the room's doors" if live else "blocks the room door"
                return f"cuts the robot path{where}"
            lab = next(iter(live))
            reach = self.rules.setting(rctx.room.type, "reach")
            room_insts = [i for i in self.insts if i.p.room == rid and i.p.record.interactable] + (
                [inst] if own and inst.p.record.interactable else [])
            for i in room_insts:
                if not (self._reach_of(i, grid, reach) & (labels == lab)).any():
                    return f"leaves {i.p.record.category}{where} out of the robot's reach"
        return None

    def _accept(self, inst: _Inst, grid: PathGrid | None) -> None:
        self.counter[inst.p.record.category] += 1
        self.insts.append(inst)
        if grid is not None and inst.block is not None:
            grid.blocks[inst.p.inst] = grid.raster(inst.block)

    # -- objects on surfaces --------------------------------------------------------------------

    def _place_object(self, rule: ObjectRule, rec: CatalogRecord, ctx: RoomContext, grid: PathGrid,
                      rep: RoomReport) -> bool:
        geo = load_asset_geometry(self.library.usd(rec))
        if not geo.rests_flat:
            rep.reject(f"{rule.category}: no flat base (would roll off its support)")
            return False
        on = set(rule.on or rec.co_occurrence)
        supports = [(i, s) for i in self.insts if i.p.room == ctx.room.id and i.on_floor
                    and i.p.record.category in on for s in i.geo.surfaces
                    if s.z - i.geo.lo[2] + geo.hi[2] - geo.lo[2] < ctx.height - 0.05]
        if not supports:
            rep.reject(f"{rule.category}: no support surface ({', '.join(sorted(on))})")
            return False
        w = np.array([polygon_area(s.polygon) for _, s in supports])
        reach = self.rules.setting(ctx.room.type, "reach")
        labels = None
        for _ in range(self.rules.defaults.max_tries):
            sup, surf = supports[int(self.rng.choice(len(supports), p=w / w.sum()))]
            yaw = sup.p.yaw if rule.align else float(self.rng.uniform(-math.pi, math.pi))
            R2 = rot2(sup.p.yaw)
            poly = surf.polygon @ R2.T + np.asarray(sup.p.position[:2])
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            xy = self.rng.uniform(lo, hi)
            local_fp = geo.footprint @ rot2(yaw).T
            fp = local_fp + xy
            if rule.align:  # a front-facing appliance: push it to the front edge of the support
                f = R2 @ np.array([1.0, 0.0])
                xy = xy + f * (float(np.max(poly @ f)) - float(np.max(fp @ f)) - 0.03)
                fp = local_fp + xy
            # the central half of the footprint (so the center of mass) must lie on the surface;
            # overhangs are allowed where the collider check finds nothing in the way
            core = xy + 0.5 * (fp - fp.mean(axis=0)) + (fp.mean(axis=0) - xy)
            if not points_in_convex(core, poly, margin=0.005).all():
                rep.reject(f"{rule.category}: off the edge of {sup.p.record.category}")
                continue
            z = sup.p.position[2] + surf.z + REST_GAP - geo.lo[2]
            inst = self._instance(rec, geo, ctx, xy, z, yaw, sup.p.inst, 0.0)
            inst.on_floor = False
            why = self._collides(inst)
            if why is None and rec.interactable and ctx.door_points:
                if labels is None:
                    ok, lab = self._door_labels_ok(grid, ctx, None)
                    labels = (grid.components(), lab)
                lab_grid, lab = labels
                if not lab or not (grid.reach_mask(fp, reach) & (lab_grid == lab)).any():
                    why = "out of the robot's reach"
            if why is None:
                self._accept(inst, None)
                return True
            rep.reject(f"{rule.category}: {why}")
        return False


# ---------------------------------------------------------------------------------------------
# final verification


@dataclass(frozen=True)
class CheckReport:
    """Result of the final checks of a populated plan: penetrations (owner pairs, depth [m]) and
    path problems (one line each)."""

    penetrations: tuple[tuple[str, str, float], ...]
    path: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.penetrations and not self.path


def verify(pop: Populator) -> CheckReport:
    """Exact collider check of every instance against the layout and each other, and the path check
    of every populated room (doors connected, every interactable reachable)."""
    from stages.scene.collide import find_penetrations as fp

    pens: dict[tuple[str, str], float] = {}
    for i, inst in enumerate(pop.insts):
        later = [p for o in pop.insts[i + 1:] for p in o.pieces]
        for pen in fp(inst.pieces, pop.layout + later, exact=True):
            key = (pen.owner_a, pen.owner_b)
            pens[key] = max(pens.get(key, 0.0), pen.depth)
    path: list[str] = []
    for rep in pop.reports:
        room = pop.plan.room(rep.room)
        ctx = pop.room_ctx[room.id]
        grid = pop.grids[room.floor]
        labels = grid.components()
        live = {grid.cell_label(labels, p) for p in ctx.door_points} - {0}
        if len(live) > 1:
            path.append(f"{room.id}: doors not connected by a {grid.radius * 2:.2f} m path")
            continue
        if not live:
            if ctx.door_points:
                path.append(f"{room.id}: no door reachable")
            continue
        lab = next(iter(live))
        reach = pop.rules.setting(room.type, "reach")
        for inst in pop.insts:
            if inst.p.room == room.id and inst.p.record.interactable:
                if not (grid.reach_mask(inst.footprint, reach) & (labels == lab)).any():
                    path.append(f"{room.id}: {inst.p.inst} out of reach")
    return CheckReport(tuple((a, b, d) for (a, b), d in sorted(pens.items())), tuple(path))


def remove_instances(pop: Populator, ids: set[str]) -> None:
    """Drop instances (and everything resting on them) from a populator (the settle repair)."""
    drop = set(ids)
    changed = True
    while changed:
        changed = False
        for i in pop.insts:
            if i.p.support in drop and i.p.inst not in drop:
                drop.add(i.p.inst)
                changed = True
    pop.insts = [i for i in pop.insts if i.p.inst not in drop]
    for g in pop.grids.values():
        for k in list(g.blocks):
            if k in drop:
                del g.blocks[k]
