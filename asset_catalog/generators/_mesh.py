"""Manifold -> triangle arrays: material runs, crease-aware corner normals, box-projected UVs."""

from __future__ import annotations

import numpy as np
from manifold3d import Manifold


def manifold_arrays(m: Manifold) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (N, 3) float64 [m], faces (M, 3) int64, and the manifold original id of each face (M,)
    (tracks which input solid a triangle came from). Vertices are shared as manifold shares them; two
    vertices at one position (a pinch where solids touch along an edge) stay apart, so the surface stays
    2-manifold."""
    mesh = m.to_mesh64()
    verts = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    faces = np.asarray(mesh.tri_verts, dtype=np.int64).reshape(-1, 3)
    run_index = np.asarray(mesh.run_index, dtype=np.int64) // 3
    run_ids = np.asarray(mesh.run_original_id, dtype=np.int64)
    face_ids = np.repeat(run_ids, np.diff(run_index)) if len(run_ids) else np.zeros(len(faces), np.int64)
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    return verts, faces[keep], face_ids[keep]


def face_normals(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (M, 3) and face areas (M,) [m^2]."""
    tri = verts[faces]
    cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(cr, axis=1)
    n = cr / np.maximum(area2, 1e-20)[:, None]
    return n, area2 / 2


def corner_normals(verts: np.ndarray, faces: np.ndarray, crease_deg: float = 35.0) -> np.ndarray:
    """Per-corner unit normals (M, 3, 3): smooth across edges flatter than ``crease_deg``, sharp elsewhere.

    For each corner, the area-weighted normals of the faces around its vertex whose normal lies within
    the crease angle of the corner's own face are averaged.
    """
    fn, area = face_normals(verts, faces)
    m = len(faces)
    corner_v = faces.reshape(-1)
    corner_f = np.repeat(np.arange(m), 3)
    order = np.argsort(corner_v, kind="stable")
    sv, sf = corner_v[order], corner_f[order]
    starts = np.flatnonzero(np.r_[True, sv[1:] != sv[:-1]])
    sizes = np.diff(np.r_[starts, len(sv)])
    # all ordered pairs (i, j) of corners within each vertex group
    grp = np.repeat(np.arange(len(starts)), sizes * sizes)
    base = np.repeat(starts, sizes * sizes)
    k = np.repeat(sizes, sizes * sizes)
    local = np.arange(len(grp)) - np.repeat(np.cumsum(sizes * sizes) - sizes * sizes, sizes * sizes)
    i = base + local // k
    j = base + local % k
    fi, fj = sf[i], sf[j]
    ok = np.einsum("ij,ij->i", fn[fi], fn[fj]) >= np.cos(np.radians(crease_deg)) - 1e-9
    acc = np.zeros((len(sv), 3))
    np.add.at(acc, i[ok], fn[fj[ok]] * area[fj[ok], None])
    acc = acc / np.maximum(np.linalg.norm(acc, axis=1), 1e-20)[:, None]
    bad = ~np.isfinite(acc).all(axis=1) | (np.linalg.norm(acc, axis=1) < 0.5)
    if bad.any():   # corners of zero-area triangles: the vertex's area-weighted normal, else +Z
        vn = np.zeros((len(verts), 3))
        np.add.at(vn, faces.reshape(-1), np.repeat(fn * area[:, None], 3, axis=0))
        fix = vn[sv[bad]]
        norm = np.linalg.norm(fix, axis=1)
        fix = np.where(norm[:, None] > 1e-20, fix / np.maximum(norm, 1e-20)[:, None], np.array([0.0, 0.0, 1.0]))
        acc[bad] = fix
    out = np.empty((len(sv), 3))
    out[order] = acc
    del grp
    return out.reshape(m, 3, 3)


def box_uvs(verts: np.ndarray, faces: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Per-corner UVs (M, 3, 2) by box projection along each face's dominant normal axis;
    1 UV unit = ``scale`` metres."""
    fn, _ = face_normals(verts, faces)
    dom = np.argmax(np.abs(fn), axis=1)
    tri = verts[faces] / scale
    uv = np.empty((len(faces), 3, 2))
    for axis, (a, b) in enumerate(((1, 2), (0, 2), (0, 1))):
        sel = dom == axis
        uv[sel, :, 0] = tri[sel][:, :, a]
        uv[sel, :, 1] = tri[sel][:, :, b]
    return uv


def split_corners(verts: np.ndarray, faces: np.ndarray, normals: np.ndarray, uvs: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Turn per-corner attributes into per-vertex ones by splitting vertices where corners disagree.

    Returns vertices (N', 3), faces (M, 3), normals (N', 3), uvs (N', 2)."""
    m = len(faces)
    key = np.column_stack([faces.reshape(-1, 1).astype(np.float64),
                           np.round(normals.reshape(-1, 3), 5), np.round(uvs.reshape(-1, 2), 6)])
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    new_v = verts[uniq[:, 0].astype(np.int64)]
    n = uniq[:, 1:4]
    n = n / np.maximum(np.linalg.norm(n, axis=1), 1e-20)[:, None]
    return new_v, inv.reshape(m, 3).astype(np.int64), n, uniq[:, 4:6]
