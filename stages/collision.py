"""Collision stage: convex colliders for every link of an AssetModel.

Per link, from ``collision_source`` if the source has one, else from the visuals:

1. all meshes of the link are concatenated and welded by position (so a surface split by material or
   by UV seams is one piece again) and split into connected *pieces*; pieces much smaller than the
   link (``min_piece_fraction`` of its largest dimension) are dropped when there are many of them;
2. each piece is judged: its *solidity* is solid volume / convex-hull volume, exact for a watertight
   piece, else estimated on a voxel grid (surface voxels plus the enclosed voxels that a flood fill
   from outside does not reach, ``voxel_resolution`` along the largest side). A near-convex piece
   (solidity >= ``convexity_threshold``) gets one hull; a concave one (a bowl, a mug, a shelf) is
   decomposed with CoACD into at most ``max_hulls_per_piece`` hulls (the link's ``max_hulls``
   shared among its pieces by hull volume), each its own MeshPart, so a cavity stays open;
3. when a link has more than ``max_pieces`` significant pieces, CoACD runs once over the whole link
   (at most ``max_hulls`` hulls), keeping the collider count bounded.

``annotation.collider`` overrides the choice: ``hull`` one hull of the whole link, ``coacd`` CoACD
on every piece, ``none`` no colliders. Flat pieces (a plane, a sheet) are thickened to
``min_thickness_m`` so their hull has volume. Hulls with more than ``max_hull_vertices`` vertices
are reduced by farthest-point sampling. Collider names say how they were made: ``hull_<i>`` (one
hull of a piece or link) and ``coacd_<i>`` (a CoACD part). Deterministic for a given ``rng`` state:
every CoACD seed is drawn from it in a fixed order.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from asset_catalog.annotations import ColliderKind
from asset_catalog.asset_model import AssetModel, ColliderApprox, Link, MeshPart
from pipeline.types import ItemError

log = logging.getLogger(__name__)


class CollisionConfig(BaseModel):
    """Parameters of the collider choice and of CoACD (see the module docstring).

    convexity_threshold: solidity at or above which a piece gets a single hull [-];
    voxel_resolution: voxels along the largest side for the solidity of open meshes [-];
    max_pieces: more significant pieces than this -> one CoACD run over the link;
    min_piece_fraction: pieces smaller than this fraction of the link's largest dimension are
    dropped when the link has more than ``max_pieces`` pieces [-];
    max_hulls_per_piece / max_hulls: CoACD hull budgets per piece / per whole-link run;
    max_hull_vertices: larger hulls are reduced to this many vertices;
    min_thickness_m: flat pieces are thickened to this [m];
    coacd_*: CoACD's concavity threshold, sampling resolution, preprocess (manifold) resolution and
    MCTS search size (defaults favour speed: CoACD's cost grows steeply with ``coacd_resolution``
    and the MCTS size; these keep a mug or bowl to seconds on one core).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    convexity_threshold: float = Field(default=0.9, gt=0.0, le=1.0)
    voxel_resolution: int = Field(default=40, ge=8, le=256)
    max_pieces: int = Field(default=24, ge=1)
    min_piece_fraction: float = Field(default=0.05, ge=0.0, lt=1.0)
    max_hulls_per_piece: int = Field(default=10, ge=1)
    max_hulls: int = Field(default=32, ge=1)
    max_hull_vertices: int = Field(default=64, ge=8)
    min_thickness_m: float = Field(default=0.002, gt=0.0)
    coacd_threshold: float = Field(default=0.15, gt=0.0, le=1.0)
    coacd_resolution: int = Field(default=200, ge=50)
    coacd_preprocess_resolution: int = Field(default=25, ge=10)
    coacd_mcts_iterations: int = Field(default=10, ge=1)
    coacd_mcts_depth: int = Field(default=1, ge=1)
    coacd_mcts_nodes: int = Field(default=4, ge=1)


@dataclass(frozen=True)
class _Piece:
    """A connected piece of a link's mesh: vertices (N, 3) [m], faces (M, 3), closed or not."""

    vertices: np.ndarray
    faces: np.ndarray
    watertight: bool


def compute_colliders(model: AssetModel, cfg: CollisionConfig, rng: np.random.Generator) -> AssetModel:
    """The model with ``colliders`` and ``collider_approx`` filled in on every link (see module doc)."""
    kind = ColliderKind(model.annotation.collider)
    links = tuple(_link_colliders(lk, kind, cfg, rng, model.name) for lk in model.links)
    return model.replace_links(links)


def collider_kind(model: AssetModel) -> str:
    """Summary of how a model's colliders were made: ``none``, ``hull`` (one hull per link),
    ``hulls`` (several whole-piece hulls) or ``coacd`` (a CoACD decomposition somewhere)."""
    cols = [c for lk in model.links for c in lk.colliders]
    if not cols:
        return "none"
    if any(c.name.startswith("coacd_") for c in cols):
        return "coacd"
    return "hull" if all(len(lk.colliders) <= 1 for lk in model.links) else "hulls"


# ------------------------------------------------------------------------------------------- links


def _link_colliders(link: Link, kind: ColliderKind, cfg: CollisionConfig, rng: np.random.Generator,
                    asset: str) -> Link:
    if kind == ColliderKind.NONE:
        return replace(link, colliders=(), collider_approx=None)
    source = link.collision_source if link.collision_source is not None else link.visuals
    if not source:
        return replace(link, colliders=(), collider_approx=None)
    verts, faces = _concat(source)
    if kind == ColliderKind.HULL:
        hulls = [_hull(verts, cfg)]
        return _with(link, hulls, ["hull"])
    pieces = _pieces(verts, faces, cfg)
    if len(pieces) > cfg.max_pieces:
        log.info("%s/%s: %d pieces > max_pieces=%d: one CoACD run over the link", asset, link.name,
                 len(pieces), cfg.max_pieces)
        parts = _coacd(verts, faces, cfg, cfg.max_hulls, rng)
        return _with(link, parts, ["coacd"] * len(parts))
    hulls: list[np.ndarray] = []
    how: list[str] = []
    budgets = _hull_budgets(pieces, cfg)
    for piece, budget in zip(pieces, budgets, strict=True):
        if kind == ColliderKind.AUTO and _solidity(piece, cfg) >= cfg.convexity_threshold:
            hulls.append(_hull(piece.vertices, cfg))
            how.append("hull")
        else:
            parts = _coacd(piece.vertices, piece.faces, cfg, budget, rng)
            hulls.extend(parts)
            how.extend(["coacd"] * len(parts))
    return _with(link, hulls, how)


def _hull_budgets(pieces: list[_Piece], cfg: CollisionConfig) -> list[int]:
    """CoACD hull budget of each piece: the link's ``max_hulls`` shared by hull volume, at least 2 and at
    most ``max_hulls_per_piece`` (a tea set's saucer gets fewer hulls than its teapot)."""
    vols = np.array([_hull_volume(p.vertices) for p in pieces])
    share = vols / vols.sum() if vols.sum() > 0 else np.full(len(pieces), 1.0 / len(pieces))
    return [int(np.clip(np.ceil(cfg.max_hulls * s), 2, cfg.max_hulls_per_piece)) for s in share]


def _with(link: Link, hull_points: list[np.ndarray], how: list[str]) -> Link:
    import trimesh

    parts: list[MeshPart] = []
    for i, (pts, h) in enumerate(zip(hull_points, how, strict=True)):
        hull = trimesh.convex.convex_hull(pts)
        parts.append(MeshPart(name=f"{h}_{i}", vertices=np.asarray(hull.vertices, dtype=np.float64),
                              faces=np.asarray(hull.faces, dtype=np.int64)))
    approx = ColliderApprox.HULL if len(parts) == 1 and how[0] == "hull" else ColliderApprox.DECOMPOSITION
    return replace(link, colliders=tuple(parts), collider_approx=approx)


def _concat(parts: tuple[MeshPart, ...]) -> tuple[np.ndarray, np.ndarray]:
    vs, fs, off = [], [], 0
    for p in parts:
        vs.append(np.asarray(p.vertices, dtype=np.float64))
        fs.append(np.asarray(p.faces, dtype=np.int64) + off)
        off += len(p.vertices)
    return np.concatenate(vs), np.concatenate(fs)


def _pieces(verts: np.ndarray, faces: np.ndarray, cfg: CollisionConfig) -> list[_Piece]:
    """Connected pieces of the welded mesh, largest first; small ones dropped if there are many."""
    import trimesh

    mesh = trimesh.Trimesh(verts, faces, process=True)  # merges duplicate vertices (welds UV seams)
    mesh.merge_vertices(digits_vertex=6)
    comps = mesh.split(only_watertight=False)
    if len(comps) == 0:
        comps = [mesh]
    size = float(mesh.extents.max())
    comps = sorted(comps, key=lambda c: -float(c.extents.max()))
    if len(comps) > cfg.max_pieces:
        kept = [c for c in comps if float(c.extents.max()) >= cfg.min_piece_fraction * size]
        comps = kept or comps[:1]
    return [_Piece(np.asarray(c.vertices, dtype=np.float64), np.asarray(c.faces, dtype=np.int64),
                   bool(c.is_watertight)) for c in comps]


# ------------------------------------------------------------------------------------------- hulls


def _hull(points: np.ndarray, cfg: CollisionConfig) -> np.ndarray:
    """Vertices (K, 3) of a closed convex hull of ``points``: flat sets thickened, big hulls reduced."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.unique(np.asarray(points, dtype=np.float64).round(9), axis=0)
    pts = _thicken_if_flat(pts, cfg.min_thickness_m)
    try:
        hv = pts[ConvexHull(pts).vertices]
    except QhullError as e:
        raise ItemError(f"convex hull failed: {' '.join(str(e).split())[:200]}") from e
    if len(hv) > cfg.max_hull_vertices:
        hv = hv[_farthest_points(hv, cfg.max_hull_vertices)]
    return hv


def _thicken_if_flat(pts: np.ndarray, thickness: float) -> np.ndarray:
    """Points of a (nearly) flat set offset by +-thickness/2 along its normal, else unchanged."""
    centred = pts - pts.mean(0)
    if len(pts) >= 3:
        _, s, vt = np.linalg.svd(centred, full_matrices=False)
        extent = np.ptp(centred @ vt[-1]) if len(s) == 3 else 0.0
    else:
        vt, extent = np.eye(3), 0.0
    if len(pts) >= 4 and extent >= thickness:
        return pts
    normal = vt[-1] if len(pts) >= 3 else np.array([0.0, 0.0, 1.0])
    if len(pts) < 3:  # a segment or point: make a small box around it
        offsets = np.concatenate([np.eye(3), -np.eye(3)]) * thickness / 2
        pts = np.concatenate([pts + d for d in offsets])
    return np.concatenate([pts + normal * thickness / 2, pts - normal * thickness / 2])


def _farthest_points(pts: np.ndarray, k: int) -> np.ndarray:
    """Indices of ``k`` points by farthest-point sampling, deterministic (starts at the point farthest
    from the centroid)."""
    d = np.linalg.norm(pts - pts.mean(0), axis=1)
    chosen = [int(np.argmax(d))]
    dist = np.linalg.norm(pts - pts[chosen[0]], axis=1)
    for _ in range(k - 1):
        i = int(np.argmax(dist))
        chosen.append(i)
        dist = np.minimum(dist, np.linalg.norm(pts - pts[i], axis=1))
    return np.array(sorted(chosen))


def _hull_volume(points: np.ndarray) -> float:
    from scipy.spatial import ConvexHull, QhullError

    try:
        return float(ConvexHull(points).volume)
    except (QhullError, ValueError):
        return 0.0


def _solidity(piece: _Piece, cfg: CollisionConfig) -> float:
    """Solid volume / hull volume of a piece in [0, 1] (exact if watertight, voxel estimate if not)."""
    import trimesh

    hull_vol = _hull_volume(piece.vertices)
    if hull_vol <= 0.0:
        return 1.0  # flat: one (thickened) hull
    mesh = trimesh.Trimesh(piece.vertices, piece.faces, process=False)
    if piece.watertight:
        return float(min(1.0, abs(mesh.volume) / hull_vol))
    return _voxel_solidity(mesh, hull_vol, cfg.voxel_resolution)


def _voxel_solidity(mesh, hull_vol: float, resolution: int) -> float:
    """Solidity of an open mesh: (surface + enclosed voxels) / hull voxels on the same grid."""
    from scipy import ndimage
    from scipy.spatial import ConvexHull, Delaunay

    pitch = float(mesh.extents.max()) / resolution
    lo = mesh.bounds[0] - pitch
    shape = np.ceil((mesh.extents + 2 * pitch) / pitch).astype(int) + 1
    occ = np.zeros(shape, dtype=bool)
    pts = _surface_samples(mesh, pitch / 2)
    idx = np.floor((pts - lo) / pitch).astype(int)
    idx = np.clip(idx, 0, shape - 1)
    occ[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    solid = ndimage.binary_fill_holes(occ)
    centres = np.stack(np.nonzero(np.ones(shape, dtype=bool)), axis=1) * pitch + lo + pitch / 2
    used = mesh.vertices[np.unique(mesh.faces)]
    hull_pts = used[ConvexHull(used).vertices]
    in_hull = Delaunay(hull_pts).find_simplex(centres) >= 0  # point location: cheap for any hull size
    hull_cells = int(np.count_nonzero(in_hull | occ.ravel()))
    return float(min(1.0, np.count_nonzero(solid) / max(hull_cells, 1)))


def _surface_samples(mesh, spacing: float) -> np.ndarray:
    """Points on every triangle, at most ``spacing`` apart (barycentric grid per triangle)."""
    v = mesh.vertices[mesh.faces]  # (M, 3, 3)
    edge = np.max(np.linalg.norm(v[:, [1, 2, 0]] - v, axis=2), axis=1)
    n = np.clip(np.ceil(edge / spacing).astype(int), 1, 64)
    out = [mesh.vertices]
    for k in np.unique(n):
        sel = v[n == k]
        a, b = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
        keep = a + b <= k
        w1, w2 = a[keep] / k, b[keep] / k
        w0 = 1.0 - w1 - w2
        out.append((w0[None, :, None] * sel[:, None, 0] + w1[None, :, None] * sel[:, None, 1]
                    + w2[None, :, None] * sel[:, None, 2]).reshape(-1, 3))
    return np.concatenate(out)


# ------------------------------------------------------------------------------------------- CoACD


def _coacd(verts: np.ndarray, faces: np.ndarray, cfg: CollisionConfig, max_hulls: int,
           rng: np.random.Generator) -> list[np.ndarray]:
    """CoACD convex parts (each a (K, 3) point set) of a mesh; the seed is drawn from ``rng``."""
    import coacd

    coacd.set_log_level("error")
    seed = int(rng.integers(0, 2**31 - 1))
    mesh = coacd.Mesh(np.ascontiguousarray(verts, dtype=np.float64),
                      np.ascontiguousarray(faces, dtype=np.int32))
    parts = coacd.run_coacd(
        mesh, threshold=cfg.coacd_threshold, max_convex_hull=max_hulls, preprocess_mode="auto",
        preprocess_resolution=cfg.coacd_preprocess_resolution, resolution=cfg.coacd_resolution,
        mcts_nodes=cfg.coacd_mcts_nodes, mcts_iterations=cfg.coacd_mcts_iterations,
        mcts_max_depth=cfg.coacd_mcts_depth, seed=seed)
    hulls = [_hull(np.asarray(v, dtype=np.float64), cfg) for v, _ in parts if len(v) >= 1]
    if not hulls:
        hulls = [_hull(verts, cfg)]
    return hulls
