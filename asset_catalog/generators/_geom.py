"""Solid-geometry helpers over manifold3d: primitives in real sizes [m], Z up, +X front.

Every helper returns a ``manifold3d.Manifold`` (closed, oriented, watertight by construction).
Curved primitives take ``n`` = circular segments; keep it modest (16-48) so catalogs build fast.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from manifold3d import CrossSection, Manifold

Vec3 = Sequence[float]


def box(size: Vec3, center: Vec3 = (0.0, 0.0, 0.0)) -> Manifold:
    """Axis-aligned box of ``size`` (3,) [m] centred at ``center`` (3,) [m]."""
    return Manifold.cube(tuple(float(s) for s in size), True).translate(tuple(float(c) for c in center))


def box_between(lo: Vec3, hi: Vec3) -> Manifold:
    """Axis-aligned box spanning corner ``lo`` to corner ``hi`` [m]."""
    lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
    return box(hi_a - lo_a, (lo_a + hi_a) / 2)


def cylinder(radius: float, height: float, center: Vec3 = (0, 0, 0), axis: str = "z", n: int = 32,
             radius_top: float | None = None) -> Manifold:
    """Cylinder (or frustum if ``radius_top``) of ``height`` [m] along ``axis`` ("x", "y", "z"), centred."""
    m = Manifold.cylinder(float(height), float(radius), float(radius if radius_top is None else radius_top),
                          int(n), True)
    m = _orient_z_to(m, axis)
    return m.translate(tuple(float(c) for c in center))


def sphere(radius: float, center: Vec3 = (0, 0, 0), n: int = 24) -> Manifold:
    return Manifold.sphere(float(radius), int(n)).translate(tuple(float(c) for c in center))


def ellipsoid(radii: Vec3, center: Vec3 = (0, 0, 0), n: int = 24) -> Manifold:
    return Manifold.sphere(1.0, int(n)).scale(tuple(float(r) for r in radii)).translate(
        tuple(float(c) for c in center))


def rounded_box(size: Vec3, radius: float, center: Vec3 = (0, 0, 0), n: int = 12) -> Manifold:
    """Box of outer ``size`` [m] with edges rounded by ``radius`` [m] (convex hull of 8 spheres)."""
    sx, sy, sz = (float(s) for s in size)
    r = min(float(radius), sx / 2 - 1e-4, sy / 2 - 1e-4, sz / 2 - 1e-4)
    s = Manifold.sphere(r, int(n))
    corners = [s.translate((dx * (sx / 2 - r), dy * (sy / 2 - r), dz * (sz / 2 - r)))
               for dx in (-1, 1) for dy in (-1, 1) for dz in (-1, 1)]
    return Manifold.batch_hull(corners).translate(tuple(float(c) for c in center))


def hull(parts: Sequence[Manifold]) -> Manifold:
    return Manifold.batch_hull(list(parts))


def hull_points(points: np.ndarray) -> Manifold:
    """Convex hull of points (K, 3) [m]."""
    return Manifold.hull_points(np.asarray(points, dtype=np.float64))


def lathe(profile: Sequence[tuple[float, float]], n: int = 40) -> Manifold:
    """Solid of revolution about +Z of the closed polygon ``profile`` [(r, z), ...] [m] (r >= 0, CCW)."""
    pts = np.asarray(profile, dtype=np.float64)
    if _signed_area(pts) < 0:
        pts = pts[::-1]
    return Manifold.revolve(CrossSection([pts]), int(n))


def extrude_polygon(points: Sequence[tuple[float, float]], height: float) -> Manifold:
    """Prism of the polygon (x, y) [m] from z = 0 to ``height`` [m]."""
    pts = np.asarray(points, dtype=np.float64)
    if _signed_area(pts) < 0:
        pts = pts[::-1]
    return Manifold.extrude(CrossSection([pts]), float(height))


def union(parts: Sequence[Manifold]) -> Manifold:
    from manifold3d import OpType

    return Manifold.batch_boolean(list(parts), OpType.Add)


def tube_path(points: np.ndarray, radius: float, n: int = 12) -> list[Manifold]:
    """A bent rod along a polyline ``points`` (K, 3) [m]: one convex capsule-like hull per segment."""
    pts = np.asarray(points, dtype=np.float64)
    ball = Manifold.sphere(float(radius), int(n))
    return [Manifold.batch_hull([ball.translate(tuple(a)), ball.translate(tuple(b))])
            for a, b in zip(pts[:-1], pts[1:], strict=True)]


def strap_path(points: np.ndarray, normals: np.ndarray, width: float, depth: float) -> list[Manifold]:
    """A bent flat strap along a polyline ``points`` (K, 3) [m] in a plane normal to X: one convex hull
    per segment of the rectangle ``width`` (along X) by ``depth`` (along ``normals`` (K, 3), unit, in
    the plane) at each end; its sides are flat planes at x = +-width/2 of the line."""
    pts, nrm = np.asarray(points, dtype=np.float64), np.asarray(normals, dtype=np.float64)
    ex = np.array([width / 2, 0.0, 0.0])
    rect = [pts + sx * ex + sn * depth / 2 * nrm for sx in (-1, 1) for sn in (-1, 1)]  # 4 x (K, 3)
    return [hull_points(np.array([c[i] for c in rect] + [c[i + 1] for c in rect])) for i in range(len(pts) - 1)]


def _orient_z_to(m: Manifold, axis: str) -> Manifold:
    if axis == "z":
        return m
    if axis == "x":
        return m.rotate((0.0, 90.0, 0.0))
    if axis == "y":
        return m.rotate((-90.0, 0.0, 0.0))
    raise ValueError(f"axis must be x, y or z, got {axis!r}")


def _signed_area(pts: np.ndarray) -> float:
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def revolved_wall_pieces(outer: np.ndarray, inner: np.ndarray, n_wedges: int, n_bands: int) -> list[Manifold]:
    """Convex pieces approximating a thin revolved wall (bowl, mug, cup).

    outer, inner: (K, 2) profiles (r, z) [m] of the wall's outer and inner surface, sampled at the same
    parameter from bottom to rim. The wall is cut into ``n_bands`` bands along the profile and
    ``n_wedges`` wedges around Z; each piece is the hull of its band's points at the wedge's angles.
    """
    k = len(outer)
    edges = np.linspace(0, k - 1, n_bands + 1).round().astype(int)
    angles = np.linspace(0.0, 2 * np.pi, n_wedges + 1)
    pieces = []
    for b in range(n_bands):
        prof = np.vstack([outer[edges[b]:edges[b + 1] + 1], inner[edges[b]:edges[b + 1] + 1]])
        for w in range(n_wedges):
            a0, a1 = angles[w], angles[w + 1]
            pts = []
            for a in (a0, a1):
                c, s = np.cos(a), np.sin(a)
                pts.append(np.column_stack([prof[:, 0] * c, prof[:, 0] * s, prof[:, 1]]))
            pieces.append(hull_points(np.vstack(pts)))
    return pieces
