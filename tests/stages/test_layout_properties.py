"""Property tests of sampled house plans, checked on the public JSON model (``FloorPlan``) with code
independent of the planner's own checks.

Per room mix: CI runs ``CI_SEEDS`` seeds; the slow-marked variant runs 1,000 seeds per mix
(``pytest -m slow tests/stages/test_layout_properties.py``).
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from asset_catalog.annotations import RoomType as R
from stages.layout.build import plan_house
from stages.layout.floorplan import FloorPlan, to_floor_plan
from stages.layout.spec import LayoutSpec

MIXES: dict[str, LayoutSpec] = {
    "studio": LayoutSpec(rooms={R.BEDROOM: 1}),
    "flat3": LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 1}),
    "house5": LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 2, R.BATHROOM: 1}),
    "twostorey6": LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 3, R.BATHROOM: 1}, floors=2),
    "threestorey7": LayoutSpec(rooms={R.LIVING_ROOM: 1, R.KITCHEN: 1, R.BEDROOM: 3, R.BATHROOM: 2}, floors=3),
}
CI_SEEDS = 100
FULL_SEEDS = 1000
PROBE = 0.3    # [m] beyond the wall face
CLEAR = 0.6    # [m] clear depth in front of a door
EPS = 1e-6


def _inside(poly, x: float, y: float) -> bool:
    """Ray casting point-in-polygon (strict enough for probes away from edges)."""
    inside = False
    n = len(poly)
    for i in range(n):
        (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % n]
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def _inside_mask(poly, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Vectorized ray casting over arrays of points."""
    inside = np.zeros(np.broadcast(x, y).shape, dtype=bool)
    n = len(poly)
    for i in range(n):
        (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % n]
        if y0 == y1:
            continue
        cross = ((y0 > y) != (y1 > y)) & (x < x0 + (y - y0) * (x1 - x0) / (y1 - y0))
        inside ^= cross
    return inside


def _area(poly) -> float:
    p = np.asarray(poly)
    return 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def _overlap(a, b) -> bool:
    return min(a[2], b[2]) - max(a[0], b[0]) > EPS and min(a[3], b[3]) - max(a[1], b[1]) > EPS


def problems(fp: FloorPlan, grids) -> list[str]:
    """Isolated rooms, overlapping rooms, doors into walls or outside, blocked clearances."""
    out = []
    x0, y0, x1, y1 = fp.footprint
    for fl, grid in zip(fp.floors, grids, strict=True):
        # rooms: CCW, inside the footprint, areas add up, no cell center in two rooms
        total = 0.0
        for r in fl.rooms:
            a = _area(r.polygon)
            if a <= 0:
                out.append(f"{r.id}: polygon not counter-clockwise")
            total += a
            if any(not (x0 - EPS <= x <= x1 + EPS and y0 - EPS <= y <= y1 + EPS) for x, y in r.polygon):
                out.append(f"{r.id}: outside the footprint")
        if abs(total - (x1 - x0) * (y1 - y0)) > 1e-3:
            out.append(f"floor {fl.index}: room areas {total:.3f} != footprint")
        xs = np.arange(x0 + 0.025, x1 - 0.01, 0.1)  # off the 5 cm plan grid
        ys = np.arange(y0 + 0.025, y1 - 0.01, 0.1)
        count = np.zeros((ys.size, xs.size), dtype=np.int32)
        for r in fl.rooms:
            count += _inside_mask(r.polygon, xs[None, :], ys[:, None])
        if count.max() > 1:
            out.append(f"floor {fl.index}: overlapping rooms")
        if count.min() < 1:
            out.append(f"floor {fl.index}: footprint not covered by rooms")
        # connectivity through doors
        g = nx.Graph()
        g.add_nodes_from(r.id for r in fl.rooms)
        g.add_edges_from(d.rooms for d in fl.doors if not d.exterior)
        if not nx.is_connected(g):
            out.append(f"floor {fl.index}: isolated rooms {[sorted(c) for c in nx.connected_components(g)]}")
        polys = {r.id: r.polygon for r in fl.rooms}
        walls = {w.id: w for w in fl.walls}
        for d in fl.doors:
            w = walls[d.wall]
            if d.width < 0.8:
                out.append(f"{d.id}: width {d.width} < 0.8")
            nxv, nyv = d.normal
            half_t = w.thickness / 2
            p, q = d.position
            a = (p - nxv * (half_t + PROBE), q - nyv * (half_t + PROBE))
            b = (p + nxv * (half_t + PROBE), q + nyv * (half_t + PROBE))
            if not _inside(polys[d.rooms[0]], *a):
                out.append(f"{d.id}: side 0 not in {d.rooms[0]}")
            if d.rooms[1] is None:
                if x0 < b[0] < x1 and y0 < b[1] < y1:
                    out.append(f"{d.id}: entrance does not lead outside")
            elif not _inside(polys[d.rooms[1]], *b):
                out.append(f"{d.id}: side 1 not in {d.rooms[1]}")
            # the door lies within its wall, and its clearance zones meet no other wall or stair
            horiz = abs(nxv) < 0.5
            hw = d.width / 2
            along = (w.box[0], w.box[2]) if horiz else (w.box[1], w.box[3])
            c = p if horiz else q
            if c - hw < along[0] - EPS or c + hw > along[1] + EPS:
                out.append(f"{d.id}: opening leaves wall {w.id}")
            lo_depth, hi_depth = CLEAR, CLEAR
            if d.rooms[1] is None:  # the entrance: only the inside (away from the normal) matters
                if (nyv if horiz else nxv) > 0:
                    hi_depth = 0.0
                else:
                    lo_depth = 0.0
            if horiz:
                zone = (p - hw, w.box[1] - lo_depth, p + hw, w.box[3] + hi_depth)
            else:
                zone = (w.box[0] - lo_depth, q - hw, w.box[2] + hi_depth, q + hw)
            for o in fl.walls:
                if o.id != w.id and _overlap(zone, o.box):
                    out.append(f"{d.id}: clearance meets wall {o.id}")
            for s in fp.stairs:
                boxes = s.footprint if s.floor_from == fl.index else s.opening if s.floor_to == fl.index else ()
                if any(_overlap(zone, b) for b in boxes):
                    out.append(f"{d.id}: clearance meets {s.id}")
            if not grid.is_traversable(p, q):
                out.append(f"{d.id}: not traversable for the robot")
        for wd in fl.windows:
            if not walls[wd.wall].exterior:
                out.append(f"{wd.id}: window in an interior wall")
    # floors joined by stairs whose ends are traversable
    for s in fp.stairs:
        if not (0.15 <= s.rise <= 0.19 and s.run >= 0.25):
            out.append(f"{s.id}: rise {s.rise} run {s.run}")
        if not grids[s.floor_from].is_traversable(*s.bottom) or not grids[s.floor_to].is_traversable(*s.top):
            out.append(f"{s.id}: an end is not traversable")
    if {s.floor_to for s in fp.stairs} != set(range(1, len(fp.floors))):
        out.append("a floor is not reached by stairs")
    return out


def _run(name: str, seeds: range) -> dict[str, int]:
    spec = MIXES[name]
    stats = {"l_rooms": 0, "plans": 0}
    for seed in seeds:
        house, grids = plan_house(spec, seed)
        fp = to_floor_plan(house, spec, seed, grids)
        probs = problems(fp, grids)
        assert not probs, f"{name} seed {seed}: {probs[:5]}"
        stats["plans"] += 1
        stats["l_rooms"] += sum(r.shape == "l" for f in fp.floors for r in f.rooms)
    return stats


@pytest.mark.parametrize("name", list(MIXES))
def test_plans_valid_ci_subset(name: str) -> None:
    stats = _run(name, range(CI_SEEDS))
    assert stats["plans"] == CI_SEEDS


@pytest.mark.slow
@pytest.mark.parametrize("name", list(MIXES))
def test_plans_valid_1000_seeds(name: str) -> None:
    stats = _run(name, range(FULL_SEEDS))
    assert stats["plans"] == FULL_SEEDS
    if name not in ("studio",):
        assert stats["l_rooms"] > 0, "no L-shaped room in 1,000 plans"
