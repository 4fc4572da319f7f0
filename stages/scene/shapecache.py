"""An asset package's collision-level description (``stages.scene.assets.AssetGeometry``) kept on
disk by package content, so that a worker reads each package's USD once per job instead of once per
process.

Reading a package's shape (opening its stage, walking its colliders and joints, the convex hulls of
its pieces, its support surfaces) is most of the placement time of a scene that uses packages this
process has not used before. ``geometry(usd_path, root)`` returns the geometry from memory, else
from ``<root>/shape_v1/<content hash>.npz`` (``stages.scene.checkcache.content_hash`` of the package
folder: a changed package gets a new key, so a stale entry is never read), else reads the USD and
writes that file (atomically: several workers may share the folder). ``root`` None: memory only.
Within a process the first geometry got for a path is kept (as ``load_asset_geometry``'s own
per-process cache does), so the package folder is hashed once per process.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from stages.scene.assets import AssetGeometry, Surface, load_asset_geometry
from stages.scene.checkcache import content_hash
from stages.scene.collide import ConvexPiece

KIND = "shape_v1"  # bump when AssetGeometry or the way it is derived changes
_MEM: dict[tuple[str, str], AssetGeometry] = {}  # (usd path, cache root) -> geometry
stats = {"hits": 0, "misses": 0}  # disk entries read / written by this process


def geometry(usd_path: Path, root: Path | None = None) -> AssetGeometry:
    """The package's AssetGeometry (see the module docstring)."""
    if root is None:
        return load_asset_geometry(Path(usd_path))
    mk = (str(usd_path), str(root))
    got = _MEM.get(mk)
    if got is not None:
        return got
    usd_path = Path(usd_path)
    key = content_hash(usd_path.parent)
    f = Path(root) / KIND / f"{key}.npz"
    geo = None
    if f.is_file():
        try:
            with np.load(f, allow_pickle=False) as z:
                geo = _unpack(usd_path, z)
            stats["hits"] += 1
        except (OSError, ValueError, KeyError):
            geo = None  # torn or foreign file: read again and rewritten
    if geo is None:
        geo = load_asset_geometry(usd_path)
        f.parent.mkdir(parents=True, exist_ok=True)
        tmp = f.parent / f".{key}.{os.getpid()}.tmp.npz"
        np.savez(tmp, **_pack(geo))
        os.replace(tmp, f)
        stats["misses"] += 1
    _MEM[mk] = geo
    return geo


def _cat(arrs: list[np.ndarray], width: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows stacked (N, width), offsets (len + 1,))."""
    off = np.cumsum([0, *(len(a) for a in arrs)]).astype(np.int64)
    data = np.vstack(arrs).astype(np.float64) if arrs else np.zeros((0, width))
    return data.reshape(-1, width), off


def _split(data: np.ndarray, off: np.ndarray) -> list[np.ndarray]:
    return [data[off[i]:off[i + 1]] for i in range(len(off) - 1)]


def _pack(g: AssetGeometry) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for name in ("vertices", "normals", "edges"):
        out[f"p_{name}"], out[f"p_{name}_off"] = _cat([getattr(p, name) for p in g.pieces], 3)
    out["swings"], out["swings_off"] = _cat(list(g.swings), 2)
    out["surf"], out["surf_off"] = _cat([s.polygon for s in g.surfaces], 2)
    out["surf_z"] = np.array([s.z for s in g.surfaces], dtype=np.float64)
    out["moving"] = np.array(g.moving, dtype=bool)
    out["lo"], out["hi"], out["com"] = g.lo, g.hi, np.asarray(g.com, dtype=np.float64)
    out["scalars"] = np.array([float(g.dynamic), g.n_bodies, g.mass, float(g.neutral_joints)], dtype=np.float64)
    return out


def _unpack(usd_path: Path, z) -> AssetGeometry:
    verts = _split(z["p_vertices"], z["p_vertices_off"])
    normals = _split(z["p_normals"], z["p_normals_off"])
    edges = _split(z["p_edges"], z["p_edges_off"])
    pieces = tuple(ConvexPiece("", v, n, e, v.min(axis=0), v.max(axis=0)) for v, n, e in zip(verts, normals, edges))
    surfaces = tuple(Surface(z=float(h), polygon=p) for h, p in zip(z["surf_z"], _split(z["surf"], z["surf_off"])))
    dyn, nb, mass, neutral = (float(x) for x in z["scalars"])
    if len(z["moving"]) != len(pieces):
        raise ValueError("shape cache entry: pieces and moving flags differ in number")
    return AssetGeometry(usd_path=usd_path, pieces=pieces, moving=tuple(bool(m) for m in z["moving"]),
                         lo=np.array(z["lo"]), hi=np.array(z["hi"]), swings=tuple(_split(z["swings"], z["swings_off"])),
                         surfaces=surfaces, dynamic=bool(dyn), n_bodies=int(nb), mass=mass, com=np.array(z["com"]),
                         neutral_joints=bool(neutral))
