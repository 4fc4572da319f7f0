"""3-D architecture of a plan: walls with openings cut by manifold3d booleans, floor slabs with
stairwell openings, ceilings, a roof, stairs with solid steps, railings and window panes.

Every element carries a visual triangle mesh (manifold3d result) and its collider as disjoint
axis-aligned boxes whose union is the same solid (exact convex decomposition, computed
analytically: walls minus openings in the wall plane, slabs minus stairwells in plan).
Units: meters, Z up; floor i's walking surface at z = i * floor_height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stages.layout.geom2d import Rect, rects_minus
from stages.layout.model import HousePlan, Stair, Wall

COLORS: dict[str, tuple[float, float, float]] = {
    "wall": (0.86, 0.83, 0.76),
    "floor": (0.58, 0.42, 0.28),
    "ceiling": (0.96, 0.96, 0.95),
    "roof": (0.55, 0.33, 0.27),
    "stairs": (0.45, 0.31, 0.2),
    "railing": (0.25, 0.25, 0.28),
    "window": (0.62, 0.8, 0.95),
}
CUT = 0.01  # [m] how far cutting solids reach past the faces they cut (robust booleans)


@dataclass(frozen=True)
class Box3:
    """Axis-aligned box lo (3,) .. hi (3,) [m]."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    @property
    def volume(self) -> float:
        return float(np.prod(np.subtract(self.hi, self.lo)))


@dataclass(frozen=True, eq=False)
class Element:
    """One architectural element.

    name: prim name (unique in its group); group: parent path below the floor ("Walls",
    "Rooms/<room id>", "Stairs", ...) or "" for house-level elements; floor: floor index or None;
    label: semantic class (wall, floor, ceiling, roof, stairs, railing, window); room: room id or None;
    vertices (N, 3) float64 [m]; faces (M, 3) int32 (CCW from outside); colliders: boxes [m];
    color: linear RGB; opacity [0, 1].
    """

    name: str
    group: str
    floor: int | None
    label: str
    room: str | None
    vertices: np.ndarray
    faces: np.ndarray
    colliders: tuple[Box3, ...]
    color: tuple[float, float, float]
    opacity: float = 1.0


def _cube(b: Box3):
    import manifold3d as m3

    size = tuple(float(h - lo) for lo, h in zip(b.lo, b.hi, strict=True))
    return m3.Manifold.cube(size).translate(tuple(float(v) for v in b.lo))


def solid_mesh(boxes: list[Box3], holes: list[Box3] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of (union of boxes) minus (union of holes), by manifold3d booleans."""
    import manifold3d as m3

    solid = _cube(boxes[0]) if len(boxes) == 1 else m3.Manifold.batch_boolean([_cube(b) for b in boxes],
                                                                               m3.OpType.Add)
    if holes:
        cut = _cube(holes[0]) if len(holes) == 1 else m3.Manifold.batch_boolean([_cube(b) for b in holes],
                                                                                 m3.OpType.Add)
        solid = solid - cut
    mesh = solid.to_mesh64()
    v = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    f = np.asarray(mesh.tri_verts, dtype=np.int32)
    return np.round(v, 6), f


def _mesh(boxes: list[Box3], holes: list[Box3] = (), meshes: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``solid_mesh(boxes, holes)``, or an empty mesh ((0, 3) vertices, (0, 3) faces) when ``meshes``
    is off (colliders only: no manifold3d needed)."""
    if not meshes:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32)
    return solid_mesh(boxes, holes)


def _xy_box(r: Rect, z0: float, z1: float) -> Box3:
    return Box3((r.x0 / 100, r.y0 / 100, z0), (r.x1 / 100, r.y1 / 100, z1))


def _wall_element(plan: HousePlan, w: Wall, z: float, meshes: bool = True) -> list[Element]:
    fl = plan.floors[w.floor]
    h = plan.ceiling_height
    ops = [o for o in fl.openings if o.wall == w.id]
    a0, a1 = w.along
    c0, c1 = w.across
    # decomposition in the wall plane: along [mm], height [mm]
    hmm = round(h * 1000)
    outer = Rect(a0 * 10, 0, a1 * 10, hmm)
    holes2 = [Rect((o.center - o.width // 2) * 10, round(o.z0 * 1000), (o.center + o.width // 2) * 10,
                   round(o.z1 * 1000)) for o in ops]
    pieces = rects_minus([outer], holes2) if holes2 else [outer]

    def to3(along0: float, along1: float, across0: float, across1: float, z0: float, z1: float) -> Box3:
        if w.horizontal:
            return Box3((along0, across0, z0), (along1, across1, z1))
        return Box3((across0, along0, z0), (across1, along1, z1))

    colliders = tuple(to3(p.x0 / 1000, p.x1 / 1000, c0 / 100, c1 / 100, z + p.y0 / 1000, z + p.y1 / 1000)
                      for p in pieces)
    cut = [to3((o.center - o.width // 2) / 100, (o.center + o.width // 2) / 100, c0 / 100 - CUT, c1 / 100 + CUT,
               z + (o.z0 if o.z0 > 0 else -CUT), z + o.z1) for o in ops]
    v, f = _mesh([to3(a0 / 100, a1 / 100, c0 / 100, c1 / 100, z, z + h)], cut, meshes)
    out = [Element(w.id, "Walls", w.floor, "wall", None, v, f, colliders, COLORS["wall"])]
    for o in ops:
        if o.kind != "window":
            continue
        mid = (c0 + c1) / 200
        pane = to3((o.center - o.width // 2) / 100, (o.center + o.width // 2) / 100, mid - 0.01, mid + 0.01,
                   z + o.z0, z + o.z1)
        pv, pf = _mesh([pane], meshes=meshes)
        out.append(Element(o.id, "Windows", w.floor, "window", o.rooms[0], pv, pf, (pane,), COLORS["window"], 0.35))
    return out


def _slab_pieces(rects: tuple[Rect, ...], holes: list[Rect], z0: float, z1: float) -> tuple[list[Box3], list[Box3]]:
    """(collider boxes, visual cutting boxes) of room rects minus stairwell holes between z0 and z1."""
    pieces = rects_minus(list(rects), holes) if holes else list(rects)
    cols = [_xy_box(p, z0, z1) for p in pieces]
    cuts = [_xy_box(hh, z0 - CUT, z1 + CUT) for hh in holes if any(hh.intersects(r) for r in rects)]
    return cols, cuts


def _room_elements(plan: HousePlan, f: int, z: float, meshes: bool = True) -> list[Element]:
    out = []
    down = [r for s in plan.stairs_to(f) for r in s.opening]      # stairwell in this floor's slab
    up = [r for s in plan.stairs_from(f) for r in s.opening]       # stairwell in the ceiling above
    for room in plan.floors[f].rooms:
        grp = f"Rooms/{room.id}"
        z0, z1 = z - plan.slab_thickness, z
        cols, cuts = _slab_pieces(room.rects, down, z0, z1)
        if cols:
            v, fa = _mesh([_xy_box(r, z0, z1) for r in room.rects], cuts, meshes)
            out.append(Element("Floor", grp, f, "floor", room.id, v, fa, tuple(cols), COLORS["floor"]))
        c0, c1 = z + plan.ceiling_height, z + plan.ceiling_height + plan.ceiling_thickness
        if c1 > c0:
            cols, cuts = _slab_pieces(room.rects, up, c0, c1)
            if cols:
                v, fa = _mesh([_xy_box(r, c0, c1) for r in room.rects], cuts, meshes)
                out.append(Element("Ceiling", grp, f, "ceiling", room.id, v, fa, tuple(cols), COLORS["ceiling"]))
    return out


def _stair_elements(plan: HousePlan, s: Stair, meshes: bool = True) -> list[Element]:
    z = s.floor * plan.floor_height
    steps = [_xy_box(r, z, z + n * s.rise) for r, n in s.treads]
    v, f = _mesh(steps, meshes=meshes)
    out = [Element(s.id, "Stairs", s.floor, "stairs", None, v, f, tuple(steps), COLORS["stairs"])]
    from stages.layout.model import RAIL_HEIGHT

    bal = [_xy_box(r, z + n * s.rise, z + n * s.rise + RAIL_HEIGHT) for r, n in s.balustrades]
    if bal:
        v, f = _mesh(bal, meshes=meshes)
        out.append(Element(f"{s.id}_balustrade", "Railings", s.floor, "railing", None, v, f, tuple(bal),
                           COLORS["railing"]))
    zt = z + plan.floor_height
    rails = [_xy_box(r, zt, zt + RAIL_HEIGHT) for r in s.rails]
    if rails:
        v, f = _mesh(rails, meshes=meshes)
        out.append(Element(f"{s.id}_railing", "Railings", s.floor + 1, "railing", None, v, f, tuple(rails),
                           COLORS["railing"]))
    return out


def build_geometry(plan: HousePlan, *, meshes: bool = True) -> list[Element]:
    """All elements of the house, floor by floor, then the roof. ``meshes`` off: the elements carry
    their colliders and empty meshes (no manifold3d booleans: physics-only consumers, faster)."""
    out: list[Element] = []
    for fl in plan.floors:
        z = fl.index * plan.floor_height
        out.extend(_room_elements(plan, fl.index, z, meshes))
        for w in fl.walls:
            out.extend(_wall_element(plan, w, z, meshes))
        for s in plan.stairs_from(fl.index):
            out.extend(_stair_elements(plan, s, meshes))
    top = len(plan.floors) * plan.floor_height
    roof = _xy_box(plan.footprint, top - plan.slab_thickness, top)
    v, f = _mesh([roof], meshes=meshes)
    out.append(Element("Roof", "", None, "roof", None, v, f, (roof,), COLORS["roof"]))
    return out
