"""Mesh-format loader: OBJ (+MTL, textures), glTF/GLB (PBR), STL and PLY -> a one-link AssetModel.

Normalisation (the ``asset_model`` conventions):

- **Up axis**: glTF/GLB are Y-up by specification and are rotated +90 deg about X to Z-up
  ((x, y, z) -> (x, -z, y)); OBJ, STL and PLY are taken as Z-up. ``annotation.up_axis`` overrides both.
- **Units**: ``annotation.meters_per_unit`` scales the source; without it the source is taken in
  meters, *unless* its largest dimension exceeds ``LoadLimits.unit_guess_dimension_m`` (20) source
  units: such an asset is **rejected** (not silently rescaled) with an error telling the user to set
  ``meters_per_unit`` (a 20 m "mug" is nearly always millimetres, but guessing wrong between mm and cm
  would silently produce a 10x wrong asset; one explicit line in the annotation file is cheap).
- **Placement**: the asset is translated so that its bounding box has its bottom at z = 0 and its XY
  centre at the origin.

Materials: OBJ materials come from the MTL file (Kd, d, Ns, map_Kd, map_Bump/norm, map_Pr, map_Pm);
glTF materials from the glTF JSON (baseColor, metallicRoughness, normal, occlusion). glTF packs
occlusion (R), roughness (G) and metallic (B) into one "ORM" image; since ``MaterialSpec`` holds one
single-channel map per quantity, the loader extracts each channel (times its glTF factor) into a
content-addressed grayscale PNG in a texture cache folder; colour and normal maps keep their source
file. Texture paths never escape the catalog folder; a missing or unreadable texture fails the asset
with an ItemError naming the file. (The readers of source materials live in
``stages.loaders._mesh_materials``.)

Bad input (ItemError, one line naming the file): unreadable/corrupt file, no triangles, NaN/inf
vertices, out-of-range face indices, only zero-area triangles, absurd scale, flat (zero-volume) body.
Non-manifold meshes are accepted (the collision stage builds closed hulls from them).
"""

from __future__ import annotations

import json
import logging
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from asset_catalog.annotations import AssetAnnotation
from asset_catalog.asset_model import AssetModel, Link, MaterialSpec, MeshPart
from asset_catalog.materials import MATERIAL_RULES, MaterialClass
from pipeline.types import ItemError
from stages.loaders._mesh_materials import (
    _from_trimesh_material,
    _gltf_materials,
    _mtllib_names,
    _obj_materials,
    _parse_mtl,
    _uri_path,
)
from stages.loaders._source import LoadLimits, _one_line, _sha256_file, check_source_file

log = logging.getLogger(__name__)

DEFAULT_TEXTURE_CACHE = Path(tempfile.gettempdir()) / "agentworld_derived_textures"
"""Where derived textures (glTF ORM channels, embedded GLB images) are written, content-addressed."""

_Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0],
                          [0.0, 0.0, 0.0, 1.0]])
_GLTF_SUFFIXES = (".gltf", ".glb")
_NAME_BAD = re.compile(r"[^A-Za-z0-9_]")


# ------------------------------------------------------------------------------------------ public


def load_mesh_asset(path: Path, annotation: AssetAnnotation, *, limits: LoadLimits | None = None,
                    catalog_root: Path | None = None, texture_cache: Path | None = None) -> AssetModel:
    """Load a mesh source into a one-link, Z-up, meter-scaled ``AssetModel`` resting on z = 0.

    path: the source file; catalog_root: the catalog folder no referenced file may escape (default:
    ``path`` with ``annotation.source`` stripped off, else the source's folder); texture_cache: folder
    for derived textures (default: a shared temporary folder). Raises ItemError for bad input.
    """
    path = Path(path)
    limits = limits or LoadLimits()
    root = (catalog_root or infer_catalog_root(path, annotation)).resolve()
    cache = texture_cache or DEFAULT_TEXTURE_CACHE
    check_source_file(path, limits)
    suffix = path.suffix.lower()
    if suffix in _GLTF_SUFFIXES:
        src_materials = _gltf_materials(path, root, cache)
        up = annotation.up_axis or "Y"
    elif suffix == ".obj":
        src_materials = _obj_materials(path, root)
        up = annotation.up_axis or "Z"
    else:
        src_materials = {}
        up = annotation.up_axis or "Z"
    scene = _load_scene(path)
    raw = _scene_parts(scene, path)
    to_z_up = _Y_UP_TO_Z_UP if up == "Y" else np.eye(4)
    _check_units(raw, to_z_up, annotation, limits, path)
    mpu = annotation.meters_per_unit or 1.0
    transform = to_z_up @ np.diag([mpu, mpu, mpu, 1.0])
    parts, materials = _finish_parts(raw, transform, src_materials, annotation, cache, path)
    parts = _recentre(parts)
    _check_extent(parts, limits, path)
    _check_volume(parts, limits, path)
    return AssetModel(
        name=annotation.id, annotation=annotation,
        links=(Link(name="body", visuals=tuple(parts)),),
        materials=materials, fixed_base=bool(annotation.fixed_base),
        source_sha256=_sha256_file(path),
    )


def infer_catalog_root(path: Path, annotation: AssetAnnotation) -> Path:
    """The catalog folder: ``path`` minus the trailing ``annotation.source`` parts, else its folder."""
    src = PurePosixPath(annotation.source).parts
    p = Path(path)
    if len(p.parts) >= len(src) and tuple(p.parts[-len(src):]) == tuple(src):
        return Path(*p.parts[: len(p.parts) - len(src)]) if len(p.parts) > len(src) else Path(".")
    return p.parent


def referenced_files(path: Path, catalog_root: Path) -> tuple[Path, ...]:
    """Existing files a mesh source references inside ``catalog_root`` (MTL files, textures, glTF
    buffers and images), for cache keys. Problems are not raised here: loading reports them."""
    path = Path(path)
    root = Path(catalog_root).resolve()
    out: list[Path] = []
    suffix = path.suffix.lower()
    try:
        if suffix == ".obj":
            for mtl in _mtllib_names(path):
                mp = (path.parent / mtl).resolve()
                if mp.is_file() and mp.is_relative_to(root):
                    out.append(mp)
                    for _, tex in _parse_mtl(mp):
                        tp = (mp.parent / tex).resolve()
                        if tp.is_file() and tp.is_relative_to(root):
                            out.append(tp)
        elif suffix == ".gltf":
            doc = json.loads(path.read_text(encoding="utf-8"))
            for item in list(doc.get("buffers", [])) + list(doc.get("images", [])):
                uri = item.get("uri") if isinstance(item, dict) else None
                if uri and not uri.startswith("data:"):
                    up = (path.parent / _uri_path(uri)).resolve()
                    if up.is_file() and up.is_relative_to(root):
                        out.append(up)
    except (OSError, UnicodeDecodeError, ValueError) as e:
        log.debug("%s: references not listed: %s", path, e)
    return tuple(dict.fromkeys(out))


# ------------------------------------------------------------------------------------------ loading


@dataclass(frozen=True)
class _RawPart:
    """One geometry instance as read: vertices/normals in source units before the node transform."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    material_name: str | None
    node_transform: np.ndarray
    trimesh_material: object | None


def _load_scene(path: Path):
    import trimesh

    try:
        return trimesh.load(str(path), force="scene", process=False)
    except Exception as e:  # trimesh raises anything from IndexError to struct.error on corrupt input
        raise ItemError(f"{path}: unreadable mesh file: {_one_line(e)}") from e


def _scene_parts(scene, path: Path) -> list[_RawPart]:
    import trimesh

    parts: list[_RawPart] = []
    for node in scene.graph.nodes_geometry:
        transform, gname = scene.graph[node]
        g = scene.geometry.get(gname)
        if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
            continue
        v = np.asarray(g.vertices, dtype=np.float64)
        f = np.asarray(g.faces, dtype=np.int64)
        bad = ~np.isfinite(v).all(axis=1)
        if bad.any():
            raise ItemError(f"{path}: {int(bad.sum())} vertices are NaN or infinite (geometry {gname!r})")
        if f.min() < 0 or f.max() >= len(v):
            raise ItemError(f"{path}: face indices out of range (geometry {gname!r})")
        visual = g.visual
        uv = getattr(visual, "uv", None) if getattr(visual, "kind", None) == "texture" else None
        uv = np.asarray(uv, dtype=np.float64) if uv is not None and len(uv) == len(v) else None
        if uv is not None and not np.isfinite(uv).all():
            uv = None
        normals = _file_normals(g)
        mat = getattr(visual, "material", None)
        parts.append(_RawPart(name=str(node), vertices=v, faces=f, normals=normals, uvs=uv,
                              material_name=getattr(mat, "name", None), node_transform=np.asarray(transform),
                              trimesh_material=mat))
    if not parts:
        raise ItemError(f"{path}: no triangles (empty mesh)")
    return parts


def _file_normals(g) -> np.ndarray | None:
    """Vertex normals stored in the file, or None (they are computed later)."""
    cached = g._cache.cache.get("vertex_normals")  # trimesh keeps loaded normals in its cache
    if cached is None or len(cached) != len(g.vertices) or not np.isfinite(cached).all():
        return None
    n = np.asarray(cached, dtype=np.float64)
    norm = np.linalg.norm(n, axis=1)
    if (norm < 1e-6).any():
        return None
    return n / norm[:, None]


def _check_units(raw: list[_RawPart], to_z_up: np.ndarray, annotation: AssetAnnotation, limits: LoadLimits,
                 path: Path) -> None:
    if annotation.meters_per_unit is not None:
        return
    pts = np.concatenate([_apply(p.vertices, to_z_up @ p.node_transform) for p in raw])
    largest = float((pts.max(0) - pts.min(0)).max())
    if largest > limits.unit_guess_dimension_m:
        raise ItemError(
            f"{path}: largest dimension is {largest:.4g} units, implausible in meters (> "
            f"{limits.unit_guess_dimension_m:g}); set meters_per_unit (e.g. 0.001 for millimetres, 0.01 for "
            f"centimetres) for this asset in the annotation file")


def _finish_parts(raw: list[_RawPart], transform: np.ndarray, src_materials: dict[str, MaterialSpec],
                  annotation: AssetAnnotation, cache: Path, path: Path
                  ) -> tuple[list[MeshPart], dict[str, MaterialSpec]]:
    """Transform each part to Z-up meters, drop zero-area triangles, fill in normals and materials."""
    materials: dict[str, MaterialSpec] = {}
    key_of: dict[int, str] = {}
    parts: list[MeshPart] = []
    n_faces_total = 0
    used_names: set[str] = set()
    for rp in raw:
        m = transform @ rp.node_transform
        v = _apply(rp.vertices, m)
        f = rp.faces
        lin = m[:3, :3]
        if np.linalg.det(lin) < 0:
            f = f[:, [0, 2, 1]]
        n_faces_total += len(f)
        area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
        f = f[area > 1e-14]
        if len(f) == 0:
            continue
        normals = _transform_normals(rp.normals, lin) if rp.normals is not None else None
        if normals is None:
            normals = _computed_normals(v, f)
        mkey = _material_key(rp, src_materials, materials, key_of, annotation, cache)
        used, f = np.unique(f, return_inverse=True)  # drop vertices no face uses (USD validators flag them)
        f = f.reshape(-1, 3).astype(np.int64)
        parts.append(MeshPart(name=_unique_name(_safe_name(rp.name), used_names), vertices=v[used], faces=f,
                              normals=normals[used], uvs=rp.uvs[used] if rp.uvs is not None else None,
                              material=mkey))
    if not parts:
        raise ItemError(f"{path}: degenerate mesh: all {n_faces_total} triangles have zero area")
    return parts, materials


def _apply(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    return v @ m[:3, :3].T + m[:3, 3]


def _transform_normals(n: np.ndarray, lin: np.ndarray) -> np.ndarray:
    out = n @ np.linalg.inv(lin)  # (inverse transpose) applied to row vectors
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)


def _computed_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (N, 3); vertices no face uses get +Z."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    vn = np.zeros_like(v)
    for k in range(3):
        np.add.at(vn, f[:, k], fn)
    norm = np.linalg.norm(vn, axis=1)
    vn[norm < 1e-20] = (0.0, 0.0, 1.0)
    norm[norm < 1e-20] = 1.0
    return vn / norm[:, None]


def _recentre(parts: list[MeshPart]) -> list[MeshPart]:
    lo = np.min([p.vertices.min(0) for p in parts], axis=0)
    hi = np.max([p.vertices.max(0) for p in parts], axis=0)
    shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return [MeshPart(name=p.name, vertices=p.vertices + shift, faces=p.faces, normals=p.normals, uvs=p.uvs,
                     material=p.material) for p in parts]


def _check_extent(parts: list[MeshPart], limits: LoadLimits, path: Path) -> None:
    pts = np.concatenate([p.vertices for p in parts])
    largest = float((pts.max(0) - pts.min(0)).max())
    if largest < limits.min_dimension_m:
        raise ItemError(f"{path}: absurd scale: largest dimension {largest * 1000:.3g} mm is below "
                        f"{limits.min_dimension_m * 1000:g} mm (check meters_per_unit)")
    if largest > limits.max_dimension_m:
        raise ItemError(f"{path}: absurd scale: largest dimension {largest:.4g} m is above "
                        f"{limits.max_dimension_m:g} m (check meters_per_unit)")


def _check_volume(parts: list[MeshPart], limits: LoadLimits, path: Path) -> None:
    from scipy.spatial import ConvexHull, QhullError

    pts = np.unique(np.concatenate([p.vertices[np.unique(p.faces)] for p in parts]).round(9), axis=0)
    try:
        vol = ConvexHull(pts).volume if len(pts) >= 4 else 0.0
    except QhullError:
        vol = 0.0
    if vol <= limits.min_hull_volume_m3:
        raise ItemError(f"{path}: zero volume: the mesh is flat (hull volume {vol:.3g} m^3); a rigid body "
                        f"needs thickness")


def _safe_name(name: str) -> str:
    s = _NAME_BAD.sub("_", name).strip("_") or "mesh"
    return s if not s[0].isdigit() else f"m_{s}"


def _unique_name(name: str, used: set[str]) -> str:
    out, i = name, 1
    while out in used:
        out, i = f"{name}_{i}", i + 1
    used.add(out)
    return out


# ---------------------------------------------------------------------------------------- materials


def _material_key(rp: _RawPart, src: dict[str, MaterialSpec], out: dict[str, MaterialSpec],
                  key_of: dict[int, str], annotation: AssetAnnotation, cache: Path) -> str:
    """The key in ``out`` of this part's material, adding it on first use."""
    ident = id(rp.trimesh_material) if rp.trimesh_material is not None else -1
    if ident in key_of:
        return key_of[ident]
    spec = src.get(rp.material_name or "")
    if spec is None and rp.trimesh_material is not None:
        spec = _from_trimesh_material(rp.trimesh_material, cache)
    if spec is None:
        rule = MATERIAL_RULES[MaterialClass(annotation.material)]
        spec = MaterialSpec(name="default", base_color=rule.base_color, roughness=rule.roughness,
                            metallic=rule.metallic)
    key = _unique_name(_safe_name(spec.name), set(out))
    if key != spec.name:
        spec = _renamed(spec, key)
    out[key] = spec
    key_of[ident] = key
    return key


def _renamed(spec: MaterialSpec, name: str) -> MaterialSpec:
    from dataclasses import replace

    return replace(spec, name=name)
