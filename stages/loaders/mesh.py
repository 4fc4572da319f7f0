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
with an ItemError naming the file.

Bad input (ItemError, one line naming the file): unreadable/corrupt file, no triangles, NaN/inf
vertices, out-of-range face indices, only zero-area triangles, absurd scale, flat (zero-volume) body.
Non-manifold meshes are accepted (the collision stage builds closed hulls from them).
"""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import os
import re
import struct
import tempfile
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path, PurePosixPath

import numpy as np

from asset_catalog.annotations import AssetAnnotation
from asset_catalog.asset_model import AssetModel, Link, MaterialSpec, MeshPart
from asset_catalog.materials import MATERIAL_RULES, MaterialClass
from pipeline.types import ItemError
from stages.loaders import LoadLimits, check_source_file

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


def _sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _one_line(e: BaseException) -> str:
    msg = " ".join(str(e).split()) or type(e).__name__
    return msg[:300]


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


def _from_trimesh_material(mat, cache: Path) -> MaterialSpec | None:
    """A MaterialSpec from a trimesh material whose source could not be matched by name (PIL images
    are written to the texture cache)."""
    name = getattr(mat, "name", None) or "material"
    base = getattr(mat, "baseColorFactor", None)
    if base is None:
        base = getattr(mat, "diffuse", None)
    color = (0.8, 0.8, 0.8)
    opacity = 1.0
    if base is not None:
        b = np.asarray(base, dtype=np.float64)
        b = b / 255.0 if b.max() > 1.0 else b
        color = tuple(float(x) for x in b[:3])
        opacity = float(b[3]) if len(b) > 3 else 1.0
    img = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
    tex = _cache_pil(img, cache) if img is not None else None
    rough = getattr(mat, "roughnessFactor", None)
    metal = getattr(mat, "metallicFactor", None)
    return MaterialSpec(name=name, base_color=color if tex is None else (1.0, 1.0, 1.0), opacity=opacity,
                        roughness=0.5 if rough is None else float(rough),
                        metallic=0.0 if metal is None else float(metal), base_color_texture=tex)


def _cache_bytes(data: bytes, suffix: str, cache: Path) -> Path:
    cache.mkdir(parents=True, exist_ok=True)
    out = cache / f"{hashlib.sha256(data).hexdigest()[:32]}{suffix}"
    if not out.exists():
        tmp = out.with_name(out.name + f".{os.getpid()}.{id(data)}.tmp")
        tmp.write_bytes(data)
        tmp.replace(out)
    return out


def _cache_pil(img, cache: Path) -> Path:
    buf = BytesIO()
    img.save(buf, format="PNG")
    return _cache_bytes(buf.getvalue(), ".png", cache)


def _check_texture(base: Path, ref: str, root: Path, referrer: Path, what: str) -> Path:
    """The resolved path of texture ``ref`` (relative to ``base``), inside ``root``, existing and
    decodable; else ItemError naming the referring file and the texture as written."""
    from PIL import Image, UnidentifiedImageError

    p = (base / ref).resolve()
    if not p.is_relative_to(root):
        raise ItemError(f"{referrer}: {what} '{ref}' escapes the catalog folder")
    if not p.is_file():
        raise ItemError(f"{referrer}: {what} '{ref}' not found (looked for {p})")
    try:
        with Image.open(p) as im:
            im.verify()
    except (UnidentifiedImageError, OSError, SyntaxError) as e:
        raise ItemError(f"{referrer}: {what} '{ref}' is unreadable: {_one_line(e)}") from e
    return p


# --- OBJ / MTL

_MTL_MAPS = {"map_kd": "base", "map_bump": "normal", "bump": "normal", "norm": "normal", "map_pr": "rough",
             "map_pm": "metal"}


def _mtllib_names(obj: Path) -> list[str]:
    names: list[str] = []
    with obj.open("r", encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.startswith("mtllib"):
                rest = line[6:].strip()
                if rest:
                    names.append(rest.replace("\\", "/"))
    return names


def _strip_map_options(tokens: list[str]) -> str:
    """The file name of an MTL ``map_*`` statement, after options such as ``-bm 1.0`` or ``-s 1 1 1``."""
    i = 0
    while i < len(tokens) and tokens[i].startswith("-"):
        i += 1
        while i < len(tokens) - 1 and (_is_number(tokens[i]) or tokens[i] in ("on", "off")):
            i += 1
        if i < len(tokens) - 1 and len(tokens[i]) == 1 and tokens[i - 1] == "-imfchan":
            i += 1
    return " ".join(tokens[i:]).replace("\\", "/")


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _parse_mtl(mtl: Path) -> list[tuple[str, str]]:
    """(statement, texture file) pairs of an MTL file's texture maps."""
    out: list[tuple[str, str]] = []
    for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
        tokens = line.split()
        if tokens and tokens[0].lower() in _MTL_MAPS and len(tokens) > 1:
            out.append((tokens[0].lower(), _strip_map_options(tokens[1:])))
    return out


def _obj_materials(obj: Path, root: Path) -> dict[str, MaterialSpec]:
    """MaterialSpecs of every material in the OBJ's MTL libraries; textures checked."""
    specs: dict[str, MaterialSpec] = {}
    for lib in _mtllib_names(obj):
        mtl = (obj.parent / lib)
        if not mtl.resolve().is_relative_to(root):
            raise ItemError(f"{obj}: material library '{lib}' escapes the catalog folder")
        if not mtl.is_file():
            raise ItemError(f"{obj}: material library '{lib}' not found")
        specs.update(_read_mtl(mtl, root))
    return specs


def _read_mtl(mtl: Path, root: Path) -> dict[str, MaterialSpec]:
    specs: dict[str, MaterialSpec] = {}
    cur: dict | None = None

    def close() -> None:
        if cur is not None:
            specs[cur["name"]] = _mtl_spec(cur)

    for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        key = tokens[0].lower()
        if key == "newmtl":
            close()
            cur = {"name": " ".join(tokens[1:]) or "material"}
        elif cur is None:
            continue
        elif key in ("kd", "d", "ns", "pr", "pm", "tr") and len(tokens) > 1:
            try:
                cur[key] = [float(t) for t in tokens[1:4]]
            except ValueError:
                raise ItemError(f"{mtl}: bad number in '{line.strip()}'") from None
        elif key in _MTL_MAPS and len(tokens) > 1:
            tex = _strip_map_options(tokens[1:])
            cur[_MTL_MAPS[key]] = _check_texture(mtl.parent, tex, root, mtl, "texture")
    close()
    return specs


def _mtl_spec(m: dict) -> MaterialSpec:
    kd = m.get("kd")
    color = tuple(float(np.clip(x, 0, 1)) for x in (kd + kd[:1] * 2)[:3]) if kd else (0.8, 0.8, 0.8)
    if "base" in m and not kd:
        color = (1.0, 1.0, 1.0)
    opacity = m["d"][0] if "d" in m else (1.0 - m["tr"][0] if "tr" in m else 1.0)
    if "pr" in m:
        rough = m["pr"][0]
    elif "ns" in m:
        rough = float(np.sqrt(2.0 / (max(m["ns"][0], 0.0) + 2.0)))  # Blinn-Phong exponent -> roughness
    else:
        rough = 0.5
    return MaterialSpec(name=m["name"], base_color=color, opacity=float(np.clip(opacity, 0, 1)),
                        roughness=float(np.clip(rough, 0.0, 1.0)),
                        metallic=float(np.clip(m["pm"][0], 0, 1)) if "pm" in m else 0.0,
                        base_color_texture=m.get("base"), normal_texture=m.get("normal"),
                        roughness_texture=m.get("rough"), metallic_texture=m.get("metal"))


# --- glTF / GLB


def _uri_path(uri: str) -> str:
    from urllib.parse import unquote

    return unquote(uri).replace("\\", "/")


def _read_gltf_json(path: Path) -> tuple[dict, bytes | None]:
    """The glTF JSON document and, for GLB, the binary chunk."""
    data = path.read_bytes()
    try:
        if path.suffix.lower() == ".glb":
            if len(data) < 20 or data[:4] != b"glTF":
                raise ItemError(f"{path}: not a GLB file (bad header)")
            jlen, jtype = struct.unpack_from("<II", data, 12)
            doc = json.loads(data[20:20 + jlen].decode("utf-8"))
            off = 20 + jlen
            binary = None
            if off + 8 <= len(data):
                blen, _ = struct.unpack_from("<II", data, off)
                binary = data[off + 8: off + 8 + blen]
            return doc, binary
        return json.loads(data.decode("utf-8")), None
    except (ValueError, UnicodeDecodeError, struct.error) as e:
        raise ItemError(f"{path}: unreadable glTF JSON: {_one_line(e)}") from e


def _gltf_materials(path: Path, root: Path, cache: Path) -> dict[str, MaterialSpec]:
    """MaterialSpecs by glTF material name; external buffers/images checked; ORM channels split."""
    doc, binary = _read_gltf_json(path)
    for buf in doc.get("buffers", []):
        uri = buf.get("uri")
        if uri and not uri.startswith("data:"):
            bp = path.parent / _uri_path(uri)
            if not bp.resolve().is_relative_to(root):
                raise ItemError(f"{path}: buffer '{uri}' escapes the catalog folder")
            if not bp.is_file():
                raise ItemError(f"{path}: buffer '{uri}' not found")
    images = [_gltf_image(doc, i, path, root, binary, cache) for i in range(len(doc.get("images", [])))]
    textures = doc.get("textures", [])

    def tex_image(info: dict | None) -> Path | None:
        if not info or "index" not in info:
            return None
        try:
            t = textures[info["index"]]
        except (IndexError, TypeError):
            raise ItemError(f"{path}: texture index {info.get('index')} out of range") from None
        src = t.get("source")
        if src is None:
            src = t.get("extensions", {}).get("KHR_texture_basisu", {}).get("source")
        if src is None or not 0 <= src < len(images):
            raise ItemError(f"{path}: texture {info['index']} has no usable image")
        return images[src]

    specs: dict[str, MaterialSpec] = {}
    names = [m.get("name") for m in doc.get("materials", [])]
    for m in doc.get("materials", []):
        name = m.get("name")
        if not name or names.count(name) > 1:
            continue  # ambiguous by name: built from trimesh's copy instead
        specs[name] = _gltf_spec(m, tex_image, cache, path)
    return specs


def _gltf_image(doc: dict, i: int, path: Path, root: Path, binary: bytes | None, cache: Path) -> Path | None:
    img = doc["images"][i]
    uri = img.get("uri")
    if uri and uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1])
        except (ValueError, IndexError) as e:
            raise ItemError(f"{path}: image {i}: bad data URI") from e
        return _checked_cached_image(data, path, f"embedded image {i}", cache)
    if uri:
        if uri.lower().endswith(".ktx2"):
            return None  # KTX2 (basisu) images are used only through a PNG/JPEG fallback
        return _check_texture(path.parent, _uri_path(uri), root, path, "texture")
    bv = img.get("bufferView")
    if bv is None or binary is None:
        raise ItemError(f"{path}: image {i} has neither a URI nor an embedded buffer view")
    view = doc["bufferViews"][bv]
    off = int(view.get("byteOffset", 0))
    data = binary[off: off + int(view["byteLength"])]
    return _checked_cached_image(data, path, f"embedded image {i}", cache)


def _checked_cached_image(data: bytes, path: Path, what: str, cache: Path) -> Path:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(BytesIO(data)) as im:
            fmt = (im.format or "PNG").lower()
            im.verify()
    except (UnidentifiedImageError, OSError, SyntaxError) as e:
        raise ItemError(f"{path}: {what} is unreadable: {_one_line(e)}") from e
    return _cache_bytes(data, ".jpg" if fmt == "jpeg" else f".{fmt}", cache)


def _gltf_spec(m: dict, tex_image, cache: Path, path: Path) -> MaterialSpec:
    pbr = m.get("pbrMetallicRoughness", {})
    base = [float(x) for x in pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])]
    metallic = float(pbr.get("metallicFactor", 1.0))
    rough = float(pbr.get("roughnessFactor", 1.0))
    mr = tex_image(pbr.get("metallicRoughnessTexture"))
    occ = tex_image(m.get("occlusionTexture"))
    rough_tex = _channel(mr, 1, rough, cache, path) if mr is not None else None
    metal_tex = _channel(mr, 2, metallic, cache, path) if mr is not None and metallic > 0.0 else None
    occ_tex = _channel(occ, 0, 1.0, cache, path) if occ is not None else None
    opacity = base[3] if m.get("alphaMode", "OPAQUE") != "OPAQUE" else 1.0
    return MaterialSpec(name=m.get("name") or "material", base_color=tuple(base[:3]), opacity=opacity,
                        roughness=rough, metallic=metallic,
                        base_color_texture=tex_image(pbr.get("baseColorTexture")),
                        normal_texture=tex_image(m.get("normalTexture")), roughness_texture=rough_tex,
                        metallic_texture=metal_tex, occlusion_texture=occ_tex)


def _channel(image: Path, channel: int, factor: float, cache: Path, path: Path) -> Path:
    """One channel (0 R, 1 G, 2 B) of ``image`` times ``factor`` as a grayscale PNG in the cache."""
    from PIL import Image

    key = hashlib.sha256(f"{_sha256_file(image)}:{channel}:{factor!r}".encode()).hexdigest()[:32]
    out = cache / f"{key}.png"
    if out.exists():
        return out
    try:
        with Image.open(image) as im:
            bands = im.convert("RGB").split()
    except OSError as e:
        raise ItemError(f"{path}: texture '{image}' is unreadable: {_one_line(e)}") from e
    band = bands[channel]
    if factor != 1.0:
        band = band.point(lambda x: int(round(min(255.0, x * factor))))
    buf = BytesIO()
    band.save(buf, format="PNG")
    cache.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + f".{os.getpid()}.{id(buf)}.tmp")
    tmp.write_bytes(buf.getvalue())
    tmp.replace(out)
    return out
