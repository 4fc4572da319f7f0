"""2-D helpers for placement: convex hulls, polygon tests, oriented transforms. Lengths [m]."""

from __future__ import annotations

import math

import numpy as np


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """(K, 2) CCW convex hull of (N, 2) points; fewer than 3 distinct or collinear points come back
    as they are (deduplicated)."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.unique(np.round(np.asarray(points, dtype=np.float64), 9), axis=0)
    if len(pts) < 3:
        return pts
    try:
        return pts[ConvexHull(pts).vertices]  # 2-D hull vertices come counter-clockwise
    except QhullError:
        return pts


def polygon_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return float(0.5 * (np.dot(x, _next(y)) - np.dot(y, _next(x))))


def convex_overlap(a: np.ndarray, b: np.ndarray, gap: float = 0.0,
                   normals: tuple[np.ndarray | None, np.ndarray | None] = (None, None)) -> bool:
    """Whether two convex polygons (CCW, (K, 2)) come closer than ``gap`` [m] (SAT on edge normals).
    normals: the ``edge_normals`` of a and of b where the caller keeps them (None: computed)."""
    for poly, n in zip((a, b), normals):
        if n is None:
            n = edge_normals(poly)
        pa, pb = a @ n.T, b @ n.T
        if np.any(pa.min(axis=0) >= pb.max(axis=0) + gap) or np.any(pb.min(axis=0) >= pa.max(axis=0) + gap):
            return False
    return True


def _next(poly: np.ndarray) -> np.ndarray:
    """The polygon's vertices shifted by one (np.roll(poly, -1, axis=0), without its overhead)."""
    return np.concatenate((poly[1:], poly[:1]))


def _unit_normals(poly: np.ndarray, inward: bool) -> np.ndarray:
    """(K, 2) unit normals of a polygon's edges (vertex k to k + 1): inward for a CCW polygon when
    ``inward``, else outward (the arithmetic of np.linalg.norm, elementwise)."""
    e = _next(poly) - poly
    n = np.empty_like(e)
    if inward:
        n[:, 0], n[:, 1] = -e[:, 1], e[:, 0]
    else:
        n[:, 0], n[:, 1] = e[:, 1], -e[:, 0]
    n /= np.maximum(np.sqrt(n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1])[:, None], 1e-12)
    return n


def edge_normals(poly: np.ndarray) -> np.ndarray:
    """(K, 2) outward unit normals of a CCW polygon's edges (vertex k to k + 1)."""
    return _unit_normals(poly, inward=False)


def points_in_polygon(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(N,) bool: points (N, 2) strictly inside a simple polygon (K, 2) (even-odd rule)."""
    x, y = pts[:, 0:1], pts[:, 1:2]
    x0, y0 = poly[:, 0][None], poly[:, 1][None]
    nxt = _next(poly)
    x1, y1 = nxt[:, 0][None], nxt[:, 1][None]
    cond = (y0 > y) != (y1 > y)
    xs = x0 + (y - y0) * (x1 - x0) / np.where(y1 == y0, 1e-300, y1 - y0)
    return (np.count_nonzero(cond & (x < xs), axis=1) % 2) == 1


def convex_inside(inner: np.ndarray, outer: np.ndarray) -> bool:
    """Whether convex polygon ``inner`` lies inside simple polygon ``outer`` (all its vertices inside
    and no vertex of ``outer`` strictly inside it)."""
    if not points_in_polygon(inner, outer).all():
        return False
    return not points_in_convex(outer, inner, margin=1e-6).any()


def points_in_convex(pts: np.ndarray, poly: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """(N,) bool: points at least ``margin`` [m] inside a CCW convex polygon."""
    n = _unit_normals(poly, inward=True)
    d = np.einsum("nkd,kd->nk", pts[:, None, :] - poly[None], n)
    return np.all(d > margin, axis=1)


def shrink_convex(poly: np.ndarray, d: float) -> np.ndarray | None:
    """A CCW convex polygon offset inward by d [m] (None if it vanishes)."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([-e[:, 1], e[:, 0]], axis=1)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    c = np.einsum("kd,kd->k", poly, n) + d  # half-planes n.x >= c
    verts = []
    k = len(poly)
    for i in range(k):
        a1, b1 = n[i - 1], c[i - 1]
        a2, b2 = n[i], c[i]
        det = a1[0] * a2[1] - a1[1] * a2[0]
        if abs(det) < 1e-12:
            continue
        verts.append(np.array([(b1 * a2[1] - b2 * a1[1]) / det, (a1[0] * b2 - a2[0] * b1) / det]))
    if len(verts) < 3:
        return None
    v = np.array(verts)
    ok = np.all(np.einsum("kd,jd->kj", v, n) >= c[None] - 1e-9, axis=1)
    v = v[ok]
    if len(v) < 3:
        return None
    h = convex_hull_2d(v)
    return h if len(h) >= 3 and polygon_area(h) > 1e-8 else None


def rot2(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def rot3(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
