"""Placement solver: populate the rooms of a floor plan following the rules (``stages.scene.rules``).

Room by room, each furniture entry of the rules is sampled (its mode gives candidate poses: against
a wall, facing another asset, in front of / beside / around a target, free on the floor), and a
candidate is kept only if

- its 2-D footprint lies inside the room's interior (wall faces), keeps ``min_gap`` to other floor-standing
  assets and stays out of keep-out zones (room doors, windows for tall assets, the front clearances, door/drawer
  swings and stand, side and leaf zones of assets already placed), and its own zones are inside the room and
  free (with ``clear_of_swings``, its clearance also out of their swings; leaf zones are a preference);
- its colliders do not penetrate the layout's colliders or any placed asset's by more than 1 mm
  (``stages.scene.collide``, on the convex collider pieces);
- the robot path stays connected: on the floor's occupancy grid with the footprints added, the
  free space eroded by ``path_width / 2`` still joins every door of the room and the reach zone of
  every interactable placed so far.

Then objects are placed on support surfaces (tops, shelves, seats, beds) of the furniture named by
their rule, resting 1 mm above it, collision-checked the same way, and kept only if reachable and
its center of mass is over the part of its base that stands on the surface (``stages.scene.support``).
Randomness comes only from the ``numpy.random.Generator`` passed in. Room geometry and the robot-path grid live
in ``stages.scene.room``, the catalog view in ``stages.scene.library``, the final checks in ``stages.scene.verify``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
import logging
import math

import numpy as np

from asset_catalog.index import CatalogRecord
from stages.layout.floorplan import FloorPlan, RoomModel
from stages.scene.assets import AssetGeometry, leaf_zones, side_zones, stand_zones
from stages.scene.collide import ConvexPiece, find_penetrations, piece_bounds
from stages.scene.geom import (
    convex_inside, convex_overlap, edge_normals, points_in_convex, points_in_polygon, polygon_area, rot2, rot3,
)
from stages.scene.library import Library
from stages.scene.room import PathGrid, RoomContext, RoomReport, _edges, _rect, layout_pieces, room_context
from stages.scene.rules import FurnitureRule, ObjectRule, PlacementRules
from stages.scene.support import REST_GAP, tips_over

log = logging.getLogger(__name__)

PLACE_GAP = 0.0005         # [m] while sampling, a new asset keeps this gap to every collider (it rests
                           # REST_GAP above its support): touching neighbours would be pushed apart
WINDOW_SILL_MARGIN = 0.3   # [m] assets taller than a window's sill + this stay away from it
SWING_MARGIN = 0.1         # [m] a clearance kept clear of swings (clear_of_swings) spares its sides this much (a
                           # fridge leaf opened beside a counter 2-10 cm off it stands over the counter's edge)


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
    pose: tuple[np.ndarray, np.ndarray]  # (rotation (3, 3), translation (3,)) of its pieces
    footprint: np.ndarray          # world (K, 2)
    block: np.ndarray | None       # world footprint that blocks the robot, or None
    zones: list[np.ndarray]        # world keep-out zones (its swings first, clearance, stand zones)
    on_floor: bool
    swings: int = 0                  # how many of ``zones`` are door/drawer swings
    clear: np.ndarray | None = None  # world front clearance zone less SWING_MARGIN a side, or None
    reach: np.ndarray | None = None  # cached reach-zone mask on its floor's path grid
    _pieces: list[ConvexPiece] | None = None
    _normals: dict[int, np.ndarray] = field(default_factory=dict)  # id of its outline -> edge_normals

    def normals(self, poly: np.ndarray) -> np.ndarray:
        """edge_normals of its footprint or one of its zones (kept: arrays it holds, never changed)."""
        n = self._normals.get(id(poly))
        if n is None:
            n = self._normals[id(poly)] = edge_normals(poly)
        return n

    @property
    def pieces(self) -> list[ConvexPiece]:
        """The collider pieces in the world (computed when first asked: most candidates are
        rejected on their footprint before)."""
        if self._pieces is None:
            R3, t = self.pose
            self._pieces = [p.transformed(R3, t, owner=self.p.inst) for p in self.geo.pieces]
        return self._pieces


class Populator:
    """Places assets into the rooms of one floor plan; holds every placed instance (all floors)."""

    def __init__(self, plan: FloorPlan, layout_usd: Path, library: Library, rules: PlacementRules,
                 rng: np.random.Generator, shape_cache: Path | None = None):
        self.plan, self.library, self.rules, self.rng = plan, library, rules, rng
        self.shape_cache = shape_cache  # where package shapes are kept across processes (None: this one)
        self.layout = layout_pieces(layout_usd)
        self.insts: list[_Inst] = []
        self.grids: dict[int, PathGrid] = {}
        self.counter: Counter[str] = Counter()
        self.reports: list[RoomReport] = []
        self.room_ctx: dict[str, RoomContext] = {}
        self._compact = 0.0  # > 0: furniture restricted to this fraction of each category's narrowest variants
        self._leaf_on = True  # the rules' leaf zones are kept (the first half of a room's arrangements)
        self._others: tuple | None = None  # (insts, their and the layout's pieces, piece_bounds) for _collides

    # -- public ---------------------------------------------------------------------------------

    def _geo(self, rec: CatalogRecord) -> AssetGeometry:
        from stages.scene.shapecache import geometry

        return geometry(self.library.usd(rec), self.shape_cache)

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
        # the rules' leaf zones are a preference: first half as many arrangements with them, on a stream of their own
        # (a room too small for them is furnished as it was without them), then the room's arrangements without
        n_leaf, main = (max(1, n_arr // 2) if any(r.leaf for r in rr.furniture) else 0), self.rng
        for a in range(n_leaf + n_arr):
            mark, counts = len(self.insts), Counter(self.counter)
            self._leaf_on, b = a < n_leaf, max(a - n_leaf, 0)
            if a in (0, n_leaf):  # the leaf arrangements' own stream, then the room's
                self.rng = np.random.Generator(main.bit_generator.jumped()) if a < n_leaf else main
            # the later half of the arrangements furnishes with ever more compact variants (a small
            # room): the narrower half of each category's variants, down to the narrowest one
            half = n_arr // 2
            self._compact = 0.5 * (1.0 - (b - half) / max(n_arr - half, 1)) if n_arr > 1 and b >= half else 0.0
            try:
                for rule in rr.furniture:
                    self._entry(rule, ctx, grid, rep, furniture=True)
                for rule in rr.objects:
                    self._entry(rule, ctx, grid, rep, furniture=False)
                self.rng = main
                return rep
            except PlacementFailure as e:
                rep.arrangements_rejected.append(str(e))
                self._rollback(mark, counts)
                rep.placed.clear()
                rep.skipped.clear()
                log.debug("%s: arrangement %d rejected: %s", room.id, a, e)
        raise PlacementFailure(f"{rep.arrangements_rejected[-1]} [{n_leaf + n_arr} arrangements]")

    def _rollback(self, mark: int, counts: Counter) -> None:
        """Forget the instances placed after the first ``mark`` (one room's failed arrangement)."""
        gone, self.insts, self.counter = {i.p.inst for i in self.insts[mark:]}, self.insts[:mark], counts
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
        keep = (self._compact_keep(rule, self._compact) if self._compact else (lambda r: rule.fits(r, self._geo(r)))
                ) if furniture else (lambda r: self._geo(r).rests_flat and rule.fits(r, self._geo(r)))
        for k in range(n):
            rec = self.library.pick(rule.category, str(ctx.room.type), self.rng, keep)
            if rec is None:
                if not furniture and self.library.records.get(rule.category):
                    rep.skipped.append(f"{rule.category}: no variant with a flat base (it would roll) that fits")
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

    def _compact_keep(self, rule, fraction: float):
        """Predicate on records: the variant fits the rule (``rule.fits``) and is among the
        ``fraction`` (at least one) of the category's fitting variants that are narrowest along their back."""
        widths = {r.id: float(g.hi[1] - g.lo[1]) for r in self.library.records.get(rule.category, ())
                  for g in (self._geo(r),) if rule.fits(r, g)}
        if not widths:
            return lambda r: False
        order = sorted(widths.values())
        limit = order[max(1, math.ceil(len(order) * fraction)) - 1]
        return lambda r: widths.get(r.id, math.inf) <= limit + 1e-9

    def _new_id(self, category: str) -> str:
        self.counter[category] += 1
        return f"{category}_{self.counter[category]:02d}"

    def _instance(self, rec: CatalogRecord, geo: AssetGeometry, ctx: RoomContext, xy: np.ndarray, z: float,
                  yaw: float, support: str | None, clearance: float, stand=(0.0, 0.0), free=(0.0, 0.0),
                  leaf=(0.0, None)) -> _Inst:
        inst = f"{rec.category}_{self.counter[rec.category] + 1:02d}"
        R3, t = rot3(yaw), np.array([xy[0], xy[1], z])
        R2 = R3[:2, :2]
        fp = geo.footprint @ R2.T + xy
        gfp = geo.ground_footprint
        block = gfp @ R2.T + xy if gfp is not None else None
        zones, clear = [s @ R2.T + xy for s in geo.swings], None
        if clearance > 0:
            front = np.array([math.cos(yaw), math.sin(yaw)])
            side = np.array([-front[1], front[0]])
            c = np.array([geo.hi[0], (geo.lo[1] + geo.hi[1]) / 2]) @ R2.T + xy
            zones.append(_rect(c, side, (geo.hi[1] - geo.lo[1]) / 2, front, clearance))
            clear = _rect(c, side, max((geo.hi[1] - geo.lo[1]) / 2 - SWING_MARGIN, 0.05), front, clearance)
        zones += [z @ R2.T + xy for z in stand_zones(geo, stand[0], clearance, stand[1]) + side_zones(geo, *free)
                  + leaf_zones(geo, *leaf)]
        p = Placement(inst, rec, ctx.room.id, ctx.room.floor, (float(xy[0]), float(xy[1]), float(z)), float(yaw), support)
        return _Inst(p, geo, (R3, t), fp, block, zones, support is None, swings=len(geo.swings), clear=clear)

    # -- furniture ------------------------------------------------------------------------------

    def _narrower(self, rule: FurnitureRule, rec: CatalogRecord, geo: AssetGeometry, ctx: RoomContext):
        """Another variant of the category that fits the rule, narrower (along its back) than ``rec`` if
        there is one, else any other: (record, geometry)."""
        width = geo.hi[1] - geo.lo[1]

        def narrower(r: CatalogRecord) -> bool:
            g = self._geo(r)
            return r.id != rec.id and g.hi[1] - g.lo[1] < width - 1e-6 and rule.fits(r, g)

        new = (self.library.pick(rule.category, str(ctx.room.type), self.rng, narrower) or self.library.pick(
            rule.category, str(ctx.room.type), self.rng, lambda r: rule.fits(r, self._geo(r))) or rec)
        return new, self._geo(new)

    def _place_furniture(self, rule: FurnitureRule, rec: CatalogRecord, ctx: RoomContext, grid: PathGrid,
                         rep: RoomReport) -> bool:
        geo = self._geo(rec)
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
            inst = self._instance(rec, geo, ctx, xy, ctx.elevation + REST_GAP - geo.lo[2], yaw, None, rule.clearance,
                                  rule.stand, (rule.side[0] * (-1) ** k * (k < tries // 2), rule.side[1]),
                                  (rule.leaf * self._leaf_on, k if rule.leaf_door == "one" else None))
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
                         gap: float, outlines=False) -> list[tuple[float, float]]:
        """Free (start, end) spans [m along the edge] of a wall edge for an against-wall asset of
        ``depth`` and ``height`` [m]: the edge minus what reaches into its band (the strip
        ``gap + depth`` deep in front of it): room-door keep-outs, windows (when ``tall`` and the
        asset rises above sill + WINDOW_SILL_MARGIN), footprints (+ min_gap) and keep-out zones of
        floor-standing assets already placed. Conservative (projections of convex outlines).
        outlines: ``_wall_outlines(height, ctx, tall)`` when the caller has it."""
        a, t, L, n = edge
        band = gap + depth
        if outlines is False:
            outlines = self._wall_outlines(height, ctx, tall)
        blocked: list[tuple[float, float]] = []
        if outlines is not None:  # every outline projected on the edge (s) and its normal (h) at once
            pts, starts, pad = outlines
            rel = pts - a
            s, h = rel @ t, rel @ n
            hmin, hmax = np.minimum.reduceat(h, starts), np.maximum.reduceat(h, starts)
            lo, hi = np.minimum.reduceat(s, starts) - pad, np.maximum.reduceat(s, starts) + pad
            hit = (hmin < band) & (hmax > 0.0)
            blocked = list(zip(lo[hit].tolist(), hi[hit].tolist()))
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

    def _wall_outlines(self, height: float, ctx: RoomContext, tall: bool):
        """(vertices of every outline _free_wall_spans keeps out, stacked; index of each outline's
        first vertex; its pad [m]), or None when there is none."""
        polys: list[np.ndarray] = list(ctx.door_zones)
        pads: list[float] = [0.0] * len(polys)
        if tall:
            for wz, sill in ctx.windows:
                if height > sill + WINDOW_SILL_MARGIN:
                    polys.append(wz)
                    pads.append(0.0)
        min_gap = self.rules.setting(ctx.room.type, "min_gap")
        for o in self.insts:
            if o.on_floor and o.p.floor == ctx.room.floor:
                polys.append(o.footprint)
                pads.append(min_gap)
                polys += o.zones
                pads += [0.0] * len(o.zones)
        pads = [pd for pd, p in zip(pads, polys) if len(p)]
        polys = [np.asarray(p) for p in polys if len(p)]
        if not polys:
            return None
        return np.vstack(polys), np.cumsum([0, *(len(p) for p in polys[:-1])]), np.asarray(pads)

    def _wall_pose(self, geo: AssetGeometry, ctx: RoomContext, gap: float, facing: _Inst | None, *,
                   tall: bool = True, snap: float = 0.0):
        """Back against a free span of a wall (see ``_free_wall_spans``), front into the room; with
        probability ``snap`` pushed to one end of the span (a corner, a door or window edge, a
        neighbour); None when no span is wide enough."""
        width = geo.hi[1] - geo.lo[1]
        need = width + 0.02
        cands = []  # (edge, span start, span end)
        outlines = self._wall_outlines(geo.hi[2] - geo.lo[2], ctx, tall)
        for e in _edges(ctx.interior):
            for s0, s1 in self._free_wall_spans(e, geo.hi[0] - geo.lo[0], geo.hi[2] - geo.lo[2], ctx, tall, gap,
                                                outlines):
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
        fp = inst.footprint
        nf = inst.normals(fp)
        for dz in ctx.door_zones:
            if convex_overlap(fp, dz, normals=(nf, None)):
                return "in front of a room door"
        if not rule.tall_ok_at_window:
            for wz, sill in ctx.windows:
                if geo.hi[2] - geo.lo[2] > sill + WINDOW_SILL_MARGIN and convex_overlap(fp, wz, normals=(nf, None)):
                    return "blocks a window"
        gap = self.rules.setting(ctx.room.type, "min_gap")
        for o in self.insts:
            if not o.on_floor or o.p.floor != inst.p.floor:
                continue
            if convex_overlap(fp, o.footprint, gap, normals=(nf, o.normals(o.footprint))):
                return f"footprint overlaps {o.p.record.category}"
            for z in o.zones:
                if convex_overlap(fp, z, normals=(nf, o.normals(z))):
                    return f"in the swing/clearance zone of {o.p.record.category}"
            for z in inst.zones:
                if convex_overlap(z, o.footprint, normals=(inst.normals(z), o.normals(o.footprint))):
                    return f"its swing/clearance zone hits {o.p.record.category}"
            if rule.clear_of_swings and inst.clear is not None and any(
                    convex_overlap(inst.clear, z, normals=(inst.normals(inst.clear), o.normals(z)))
                    for z in o.zones[:o.swings]):
                return f"its clearance is in a door swing of {o.p.record.category}"
        return None

    def _collides(self, inst: _Inst) -> str | None:
        key, old = tuple(self.insts), self._others
        n = len(old[0]) if old else 0
        if old is None or len(key) < n or any(a is not b for a, b in zip(key, old[0])):
            old, n = ((), self.layout, piece_bounds(self.layout)), 0
        if len(key) > n or old is not self._others:  # instances appended: only theirs stacked anew
            new = [p for i in key[n:] for p in i.pieces]
            lo, hi = piece_bounds(new)
            self._others = (key, old[1] + new, (np.concatenate([old[2][0], lo]), np.concatenate([old[2][1], hi])))
        _, others, bounds = self._others
        hits = find_penetrations(inst.pieces, others, first_only=True, exact=False, tol=-PLACE_GAP, bounds=bounds)
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
            at_door = labels == next(iter(live))
            reach = self.rules.setting(rctx.room.type, "reach")
            room_insts = [i for i in self.insts if i.p.room == rid and i.p.record.interactable] + (
                [inst] if own and inst.p.record.interactable else [])
            for i in room_insts:
                if not (self._reach_of(i, grid, reach) & at_door).any():
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
        geo = self._geo(rec)
        if not geo.rests_flat:
            rep.reject(f"{rule.category}: no flat base (would roll off its support)")
            return False
        on = set(rule.on or rec.co_occurrence)
        supports = [(i, s) for i in self.insts if i.p.room == ctx.room.id and i.on_floor
                    and i.p.record.category in on for s in i.geo.surfaces
                    if s.z - i.geo.lo[2] + geo.hi[2] - geo.lo[2] < ctx.height - 0.05
                    and (not rule.inside or s.z < i.geo.hi[2] - 0.05)]   # inside: under the support's top
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
            # overhangs are allowed where the collider check finds nothing in the way and the center
            # of mass stays over the feet that stand on the surface (``tips_over``)
            core = xy + 0.5 * (fp - fp.mean(axis=0)) + (fp.mean(axis=0) - xy)
            if not points_in_convex(core, poly, margin=0.005).all():
                rep.reject(f"{rule.category}: off the edge of {sup.p.record.category}")
                continue
            z = sup.p.position[2] + surf.z + REST_GAP - geo.lo[2]
            inst = self._instance(rec, geo, ctx, xy, z, yaw, sup.p.inst, 0.0)
            inst.on_floor = False
            why = self._collides(inst) or tips_over(inst, sup)
            if why is None and rec.interactable and ctx.door_points:
                if labels is None:
                    ok, lab = self._door_labels_ok(grid, ctx, None)
                    labels = (lab, grid.components() == lab)
                lab, at_door = labels
                if not lab or not (grid.reach_mask(fp, reach) & at_door).any():
                    why = "out of the robot's reach"
            if why is None:
                self._accept(inst, None)
                return True
            rep.reject(f"{rule.category}: {why}")
        return False
