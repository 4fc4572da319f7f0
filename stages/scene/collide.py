"""Interpenetration of convex collider pieces, exact on the collision geometry (no bounding boxes as
the final check).

Each collider of an asset package is a convex hull (``physics:approximation = convexHull``); the
layout's colliders are boxes. For two convex polytopes A and B the penetration depth (the shortest
translation that separates them) is the minimum, over the separating-axis candidates (face normals
of A and of B, and cross products of an edge of A with an edge of B), of the overlap of their
projections. ``penetration_depth`` computes it exactly that way (vectorised numpy); two pieces that
touch or are apart give a depth <= 0. The scene check rejects a depth above 1 mm.

Axis-aligned boxes are only the broad phase (pairs whose boxes, grown by the tolerance, overlap).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

PENETRATION_TOL = 1e-3  # [m]


@dataclass(frozen=True, eq=False)
class ConvexPiece:
    """A convex polytope. vertices (K, 3) [m]; normals (F, 3) unit face normals (deduplicated);
    edges (E, 3) unit edge directions (deduplicated up to sign); lo, hi (3,) its bounds [m];
    owner: id of the instance (or layout element) it belongs to."""

    owner: str
    vertices: np.ndarray
    normals: np.ndarray
    edges: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def transformed(self, rot: np.ndarray, trans: np.ndarray, owner: str | None = None) -> "ConvexPiece":
        """The piece moved by p -> rot @ p + trans (rot (3, 3), trans (3,))."""
        v = self.vertices @ rot.T + trans
        return ConvexPiece(owner if owner is not None else self.owner, v, self.normals @ rot.T, self.edges @ rot.T,
                           v.min(axis=0), v.max(axis=0))


def _unique_dirs(d: np.ndarray, signed: bool) -> np.ndarray:
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    if not signed:  # canonical sign: first non-negligible component positive
        idx = np.argmax(np.abs(d) > 1e-9, axis=1)
        s = np.sign(d[np.arange(len(d)), idx])
        d = d * np.where(s == 0, 1.0, s)[:, None]
    key = np.round(d, 6)
    _, first = np.unique(key, axis=0, return_index=True)
    return d[np.sort(first)]


def convex_piece(points: np.ndarray, owner: str = "") -> ConvexPiece:
    """The convex hull of ``points`` (K, 3) [m] as a ConvexPiece (flat point sets get a 0.1 mm
    thickness so that the hull is a solid)."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, dtype=np.float64)
    try:
        hull = ConvexHull(pts)
    except QhullError:
        jitter = np.array([[0, 0, 0], [1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 1e-4]])
        pts = (pts[:, None, :] + jitter[None]).reshape(-1, 3)
        hull = ConvexHull(pts)
    v = pts[hull.vertices]
    normals = _unique_dirs(hull.equations[:, :3], signed=True)
    # feature edges: triangle edges between faces with different normals
    simp, nb = hull.simplices, hull.neighbors
    eq = np.round(hull.equations[:, :3], 6)
    edges = []
    for k in range(3):
        a, b = simp[:, (k + 1) % 3], simp[:, (k + 2) % 3]
        other = nb[:, k]
        sharp = np.any(eq != eq[other], axis=1)
        edges.append(pts[b[sharp]] - pts[a[sharp]])
    e = np.vstack(edges) if edges else np.zeros((0, 3))
    e = e[np.linalg.norm(e, axis=1) > 1e-9]
    edges_u = _unique_dirs(e, signed=False) if len(e) else np.zeros((0, 3))
    return ConvexPiece(owner, v, normals, edges_u, v.min(axis=0), v.max(axis=0))


def box_piece(lo: Sequence[float], hi: Sequence[float], owner: str = "") -> ConvexPiece:
    """An axis-aligned box lo..hi [m] as a ConvexPiece."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    eye = np.eye(3)
    return ConvexPiece(owner, c, np.vstack([eye, -eye]), eye.copy(), lo, hi)


def _min_overlap(a: ConvexPiece, b: ConvexPiece, ax: np.ndarray) -> float:
    pa, pb = a.vertices @ ax.T, b.vertices @ ax.T
    return float(np.minimum(pa.max(axis=0) - pb.min(axis=0), pb.max(axis=0) - pa.min(axis=0)).min())


def face_overlap(a: ConvexPiece, b: ConvexPiece) -> float:
    """Minimum projection overlap [m] over the face normals of a and b only: an upper bound of the
    penetration depth (cheap; a value <= tol proves the pieces penetrate by at most tol)."""
    return _min_overlap(a, b, np.vstack([a.normals, b.normals]))


def penetration_depth(a: ConvexPiece, b: ConvexPiece, *, stop_below: float = -np.inf) -> float:
    """Penetration depth [m] of two convex pieces (<= 0 when they touch or are apart): the minimum
    projection overlap over all separating-axis candidates (face normals, then edge x edge axes in
    chunks). Returns early with a value <= stop_below as soon as one axis shows that much."""
    d = face_overlap(a, b)
    if d <= stop_below or not (len(a.edges) and len(b.edges)):
        return d
    chunk = max(1, 8192 // max(len(b.edges), 1))
    for i in range(0, len(a.edges), chunk):
        c = np.cross(a.edges[i:i + chunk, None, :], b.edges[None, :, :]).reshape(-1, 3)
        n = np.linalg.norm(c, axis=1)
        ok = n > 1e-6
        if ok.any():
            d = min(d, _min_overlap(a, b, c[ok] / n[ok, None]))
            if d <= stop_below:
                return d
    return d


def boxes_overlap(a: ConvexPiece, b: ConvexPiece, margin: float = 0.0) -> bool:
    return bool(np.all(a.lo - margin <= b.hi) and np.all(b.lo - margin <= a.hi))


@dataclass(frozen=True)
class Penetration:
    """Two owners whose pieces interpenetrate by ``depth`` [m] (> tolerance)."""

    owner_a: str
    owner_b: str
    depth: float


def piece_bounds(pieces: Sequence[ConvexPiece]) -> tuple[np.ndarray, np.ndarray]:
    """(lo (N, 3), hi (N, 3)): the bounds of each piece, stacked."""
    return (np.array([p.lo for p in pieces]).reshape(-1, 3),
            np.array([p.hi for p in pieces]).reshape(-1, 3))


def find_penetrations(new: Sequence[ConvexPiece], others: Sequence[ConvexPiece], *,
                      tol: float = PENETRATION_TOL, first_only: bool = False,
                      exact: bool = True, bounds: tuple[np.ndarray, np.ndarray] | None = None) -> list[Penetration]:
    """Pieces of ``new`` that penetrate pieces of ``others`` by more than ``tol`` [m] (the depth is
    the deepest per owner pair). Pieces of the same owner are never tested against each other.

    exact=False uses the face-normal bound only (conservative: it may report a pair that an edge
    axis separates; used while sampling placements, never for the final check). bounds: the
    ``piece_bounds`` of ``others`` when the caller keeps them."""
    if not new or not others:
        return []
    olo, ohi = bounds if bounds is not None else piece_bounds(others)
    worst: dict[tuple[str, str], float] = {}
    nlo, nhi = piece_bounds(new)  # the broad phase of every new piece at once
    near = np.all(olo[None] < (nhi - tol)[:, None], axis=2) & np.all((nlo + tol)[:, None] < ohi[None], axis=2)
    for p, row in zip(new, near):
        for k in np.nonzero(row)[0]:
            q = others[k]
            if q.owner == p.owner:
                continue
            d = penetration_depth(p, q, stop_below=tol) if exact else face_overlap(p, q)
            if d > tol:
                key = (p.owner, q.owner)
                worst[key] = max(worst.get(key, 0.0), d)
                if first_only:
                    return [Penetration(p.owner, q.owner, d)]
    return [Penetration(a, b, d) for (a, b), d in sorted(worst.items())]


def all_penetrations(pieces: Sequence[ConvexPiece], *, tol: float = PENETRATION_TOL) -> list[Penetration]:
    """Every pair of different owners among ``pieces`` penetrating by more than ``tol`` [m]."""
    out: dict[tuple[str, str], float] = {}
    for i, p in enumerate(pieces):
        for pen in find_penetrations([p], pieces[i + 1:], tol=tol):
            key = tuple(sorted((pen.owner_a, pen.owner_b)))
            out[key] = max(out.get(key, 0.0), pen.depth)
    return [Penetration(a, b, d) for (a, b), d in sorted(out.items())]
