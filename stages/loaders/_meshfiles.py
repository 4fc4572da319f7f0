"""Mesh files of the articulated loaders (URDF, MJCF): STL, OBJ(+MTL), PLY, glTF/GLB through trimesh and
Collada (DAE) by a built-in reader, each into ``RawMesh`` pieces (see ``stages.loaders._geom``).
"""

from __future__ import annotations

import logging
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from asset_catalog.asset_model import MaterialSpec
from pipeline.types import ItemError
from stages.loaders._geom import RawMesh, check_finite_mesh, inside_catalog, read_xml, transform, weld

log = logging.getLogger(__name__)

MAX_MESH_BYTES = 512 * 1024 * 1024
"""Largest mesh file accepted [bytes]."""

_SMOOTH_ANGLE = np.radians(30.0)


def _shaded(mesh) -> RawMesh:
    """Split vertices at sharp edges (> 30 degrees) so per-vertex normals keep flat faces flat."""
    import trimesh

    m = trimesh.graph.smooth_shade(mesh, angle=_SMOOTH_ANGLE)
    return RawMesh(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64),
                   np.asarray(m.vertex_normals, float))


# ---------------------------------------------------------------------------------------- mesh files


def load_mesh_file(path: Path, *, source: Path, catalog_dir: Path | None = None) -> list[RawMesh]:
    """Triangle meshes of a mesh file (STL, OBJ(+MTL), PLY, glTF/GLB via trimesh; DAE by a built-in reader)
    in the file's own units, one RawMesh per material group. ``source`` is the URDF/MJCF naming it
    (for messages); texture files the mesh names (MTL ``map_Kd``, Collada images) must lie inside
    ``catalog_dir`` when given. Raises ItemError for missing, oversized, unreadable or empty files and
    for escaping texture paths; a missing texture only loses the texture (logged)."""
    if not path.is_file():
        raise ItemError(f"{source}: mesh file not found: {path}")
    size = path.stat().st_size
    if size > MAX_MESH_BYTES:
        raise ItemError(f"{source}: mesh file {path.name} too large ({size} bytes)")
    suffix = path.suffix.lower()
    if suffix == ".dae":
        meshes = load_dae(path, source=source, catalog_dir=catalog_dir)
    elif suffix in (".stl", ".obj", ".ply", ".glb", ".gltf", ".off"):
        meshes = _load_trimesh(path, source=source, catalog_dir=catalog_dir)
    else:
        raise ItemError(f"{source}: unsupported mesh file type {suffix!r}: {path.name}")
    if not meshes:
        raise ItemError(f"{source}: mesh file has no triangles: {path.name}")
    for m in meshes:
        check_finite_mesh(m, file=source, what=path.name)
    return meshes


def _load_trimesh(path: Path, *, source: Path, catalog_dir: Path | None) -> list[RawMesh]:
    import trimesh

    try:
        scene = trimesh.load(str(path), force="scene", process=False)
    except Exception as e:  # trimesh raises many types for bad files; keep the reason, one line
        why = " ".join(f"{type(e).__name__}: {e}".split())
        raise ItemError(f"{source}: cannot read mesh {path.name}: {why}") from None
    mtl = _mtl_textures(path, catalog_dir, source) if path.suffix.lower() == ".obj" else {}
    out = []
    for node in scene.graph.nodes_geometry:
        tf, geom_name = scene.graph[node]
        g = scene.geometry[geom_name]
        if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
            continue
        uvs = getattr(g.visual, "uv", None)
        if uvs is not None and len(uvs) != len(g.vertices):
            uvs = None
        material = _trimesh_material(g, mtl)
        if uvs is None and path.suffix.lower() == ".stl":
            raw = _shaded(g)
        else:
            raw = RawMesh(np.asarray(g.vertices, float), np.asarray(g.faces, np.int64),
                          np.asarray(g.vertex_normals, float),
                          None if uvs is None else np.asarray(uvs, float))
        raw = RawMesh(raw.vertices, raw.faces, raw.normals, raw.uvs, material)
        out.append(raw.transformed(np.asarray(tf, float)))
    return out


def _mtl_textures(obj: Path, catalog_dir: Path | None, source: Path) -> dict[str, Path]:
    """newmtl name -> absolute map_Kd path, from the MTL files an OBJ names (missing files skipped)."""
    out: dict[str, Path] = {}
    try:
        lines = obj.read_text(errors="replace").splitlines()
    except OSError:
        return out
    for line in lines:
        if not line.startswith("mtllib"):
            continue
        mtl = inside_catalog(obj.parent / line.split(None, 1)[1].strip(), catalog_dir, source=source,
                             what="MTL file")
        if not mtl.is_file():
            log.warning("%s: MTL file %s not found", obj, mtl)
            continue
        name = None
        for ml in mtl.read_text(errors="replace").splitlines():
            parts = ml.strip().split()
            if not parts:
                continue
            if parts[0] == "newmtl" and len(parts) > 1:
                name = parts[1]
            elif parts[0] == "map_Kd" and name is not None and len(parts) > 1:
                tex = inside_catalog(mtl.parent / parts[-1], catalog_dir, source=source, what="texture")
                if tex.is_file():
                    out[name] = tex
                else:
                    log.warning("%s: texture %s not found; colour only", mtl, tex)
    return out


def _trimesh_material(g, mtl: dict[str, Path]) -> MaterialSpec | None:
    mat = getattr(g.visual, "material", None)
    if mat is None:
        color = getattr(g.visual, "main_color", None)
        if color is None or getattr(g.visual, "kind", None) is None:
            return None
        c = np.asarray(color, float) / 255.0
        return MaterialSpec(name="vertex_color", base_color=tuple(c[:3]), opacity=float(c[3]))
    name = str(getattr(mat, "name", None) or "material")
    diffuse = getattr(mat, "diffuse", None)
    if diffuse is None:
        diffuse = getattr(mat, "baseColorFactor", None)
    c = np.asarray(diffuse if diffuse is not None else (204, 204, 204, 255), float)
    c = c / 255.0 if c.max() > 1.0 else c
    texture = mtl.get(name)
    rgb = (1.0, 1.0, 1.0) if texture is not None else tuple(float(v) for v in c[:3])
    return MaterialSpec(name=name, base_color=rgb, opacity=float(c[3]) if len(c) > 3 else 1.0,
                        base_color_texture=texture)


# ------------------------------------------------------------------------------------------- Collada


_DAE_NS = re.compile(r"^\{[^}]*\}")


def _strip_ns(root: ET.Element) -> None:
    for el in root.iter():
        el.tag = _DAE_NS.sub("", el.tag)


def load_dae(path: Path, *, source: Path, catalog_dir: Path | None = None) -> list[RawMesh]:
    """A small Collada 1.4/1.5 reader: <triangles> and <polylist> (fan-triangulated) with POSITION,
    NORMAL and TEXCOORD inputs, node matrices/translate/rotate/scale, <unit meter>, <up_axis>, and
    diffuse colours or image textures of the bound effects. Returns meshes in meters, Z up, one per
    primitive group."""
    root = read_xml(path)
    _strip_ns(root)
    unit = root.find("asset/unit")
    meter = float(unit.get("meter", "1")) if unit is not None else 1.0
    up = (root.findtext("asset/up_axis") or "Y_UP").strip().upper()
    sources = {el.get("id"): el for el in root.iter("source")}
    colors = _dae_materials(root, path, catalog_dir, source)
    geometries = {g.get("id"): g for g in root.iter("geometry")}
    nodes_lib = {n.get("id"): n for n in root.iter("node")}
    out: list[RawMesh] = []
    scene = root.find("scene/instance_visual_scene")
    vs = None
    if scene is not None:
        vs = next((v for v in root.iter("visual_scene")
                   if "#" + (v.get("id") or "") == scene.get("url")), None)
    vs = vs if vs is not None else root.find("library_visual_scenes/visual_scene")
    if vs is None:  # no scene: every geometry at identity
        for g in geometries.values():
            out += _dae_geometry(g, sources, {}, colors, np.eye(4), path)
    else:
        def walk(node: ET.Element, parent_t: np.ndarray, depth: int) -> None:
            if depth > 64:
                raise ItemError(f"{source}: {path.name}: Collada node hierarchy too deep")
            t = parent_t @ _dae_node_transform(node, path)
            for ig in node.findall("instance_geometry"):
                g = geometries.get((ig.get("url") or "").lstrip("#"))
                if g is None:
                    continue
                binding = {im.get("symbol"): (im.get("target") or "").lstrip("#")
                           for im in ig.iter("instance_material")}
                out.extend(_dae_geometry(g, sources, binding, colors, t, path))
            for inode in node.findall("instance_node"):
                ref = nodes_lib.get((inode.get("url") or "").lstrip("#"))
                if ref is not None:
                    walk(ref, t, depth + 1)
            for child in node.findall("node"):
                walk(child, t, depth + 1)

        for n in vs.findall("node"):
            walk(n, np.eye(4), 0)
    fix = np.diag([meter, meter, meter, 1.0])
    if up == "Y_UP":
        fix = transform(rotation=np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)) @ fix
    elif up == "X_UP":
        fix = transform(rotation=np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], float)) @ fix
    return [_apply_affine(m, fix) for m in out]


def _apply_affine(m: RawMesh, t: np.ndarray) -> RawMesh:
    """Apply a general affine 4x4 (scale allowed) to a mesh; normals use the inverse transpose."""
    a = t[:3, :3]
    v = m.vertices @ a.T + t[:3, 3]
    faces = m.faces if np.linalg.det(a) > 0 else m.faces[:, ::-1].copy()
    n = None
    if m.normals is not None:
        n = m.normals @ np.linalg.inv(a)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return RawMesh(v, faces, n, m.uvs, m.material)


def _dae_node_transform(node: ET.Element, path: Path) -> np.ndarray:
    t = np.eye(4)
    for el in node:
        vals = [float(x) for x in (el.text or "").split()] if el.tag in (
            "matrix", "translate", "rotate", "scale") else None
        if vals is None:
            continue
        if el.tag == "matrix" and len(vals) == 16:
            t = t @ np.array(vals).reshape(4, 4)
        elif el.tag == "translate" and len(vals) == 3:
            t = t @ transform(vals)
        elif el.tag == "rotate" and len(vals) == 4:
            from scipy.spatial.transform import Rotation

            ax = np.asarray(vals[:3])
            ax = ax / max(np.linalg.norm(ax), 1e-12)
            t = t @ transform(rotation=Rotation.from_rotvec(ax * np.radians(vals[3])).as_matrix())
        elif el.tag == "scale" and len(vals) == 3:
            t = t @ np.diag([*vals, 1.0])
    if not np.isfinite(t).all():
        raise ItemError(f"{path}: non-finite node transform")
    return t


def _dae_materials(root: ET.Element, path: Path, catalog_dir: Path | None, source: Path
                   ) -> dict[str, MaterialSpec]:
    """Collada material id -> MaterialSpec (name; diffuse colour, or diffuse image through
    sampler2D -> surface -> image, resolved beside the file and kept inside the catalog)."""
    images = {im.get("id"): (im.findtext("init_from") or im.findtext("init_from/ref") or "").strip()
              for im in root.iter("image")}
    effects: dict[str, tuple[tuple[float, ...], Path | None]] = {}
    for eff in root.iter("effect"):
        params = {npm.get("sid"): npm for npm in eff.iter("newparam")}
        col = eff.find(".//diffuse/color")
        rgba = (0.8, 0.8, 0.8, 1.0)
        if col is not None and col.text:
            v = [float(x) for x in col.text.split()]
            rgba = tuple((v + [1.0] * 4)[:4])
        tex_el = eff.find(".//diffuse/texture")
        texture = None
        if tex_el is not None:
            ref = tex_el.get("texture") or ""
            if ref in params:   # sampler2D -> source (surface sid) -> init_from (image id)
                src = params[ref].findtext(".//source") or ""
                ref = (params[src].findtext(".//init_from") if src in params else None) or ref
            uri = images.get(ref.strip(), "")
            if uri:
                from urllib.parse import unquote, urlparse

                rel = unquote(urlparse(uri).path if uri.startswith("file:") else uri)
                tex = inside_catalog(path.parent / rel, catalog_dir, source=source, what="Collada texture")
                if tex.is_file():
                    texture, rgba = tex, (1.0, 1.0, 1.0, rgba[3])
                else:
                    log.warning("%s: Collada texture %s not found; colour only", path, tex)
        effects[eff.get("id")] = (rgba, texture)
    out: dict[str, MaterialSpec] = {}
    for mat in root.iter("material"):
        ie = mat.find("instance_effect")
        if ie is None:
            continue
        rgba, texture = effects.get((ie.get("url") or "").lstrip("#"), ((0.8, 0.8, 0.8, 1.0), None))
        out[mat.get("id")] = MaterialSpec(name=str(mat.get("name") or mat.get("id")),
                                          base_color=tuple(float(c) for c in rgba[:3]),
                                          opacity=float(rgba[3]), base_color_texture=texture)
    return out


def _dae_array(src: ET.Element | None, path: Path) -> np.ndarray:
    if src is None:
        raise ItemError(f"{path}: Collada input names a missing <source>")
    fa = src.find("float_array")
    acc = src.find("technique_common/accessor")
    if fa is None or acc is None:
        raise ItemError(f"{path}: Collada <source> {src.get('id')!r} without float_array/accessor")
    stride = int(acc.get("stride", "1"))
    data = np.array((fa.text or "").split(), dtype=float)
    count = int(acc.get("count", str(len(data) // stride)))
    if len(data) < count * stride:
        raise ItemError(f"{path}: Collada <source> {src.get('id')!r} shorter than its accessor")
    return data[: count * stride].reshape(count, stride)


def _dae_geometry(geom: ET.Element, sources: dict, binding: dict, colors: dict, t: np.ndarray,
                  path: Path) -> list[RawMesh]:
    mesh = geom.find("mesh")
    if mesh is None:
        return []
    vertices_el = {v.get("id"): v for v in mesh.findall("vertices")}
    out = []
    for prim in list(mesh):
        if prim.tag not in ("triangles", "polylist", "polygons", "tristrips", "trifans"):
            continue
        if prim.tag != "triangles" and prim.tag != "polylist":
            raise ItemError(f"{path}: Collada <{prim.tag}> primitives are not supported")
        inputs = prim.findall("input")
        if not inputs or prim.find("p") is None:
            continue
        n_off = max(int(i.get("offset", "0")) for i in inputs) + 1
        idx = np.array((prim.find("p").text or "").split(), dtype=np.int64)
        if len(idx) % n_off:
            raise ItemError(f"{path}: Collada <p> length is not a multiple of its inputs")
        idx = idx.reshape(-1, n_off)
        if prim.tag == "polylist":
            vcount = np.array((prim.findtext("vcount") or "").split(), dtype=np.int64)
            if vcount.sum() != len(idx):
                raise ItemError(f"{path}: Collada <vcount> does not match <p>")
            starts = np.concatenate([[0], np.cumsum(vcount)[:-1]])
            tris = [(s, s + k, s + k + 1) for s, c in zip(starts, vcount) for k in range(1, c - 1)]
            corners = idx[np.array(tris, dtype=np.int64).reshape(-1)] if tris else idx[:0]
        else:
            corners = idx[: len(idx) // 3 * 3]
        pos = nrm = uv = None
        for inp in inputs:
            sem, off = inp.get("semantic"), int(inp.get("offset", "0"))
            sid = (inp.get("source") or "").lstrip("#")
            if sem == "VERTEX":
                for vi in vertices_el.get(sid, ET.Element("x")).findall("input"):
                    arr = _dae_array(sources.get((vi.get("source") or "").lstrip("#")), path)
                    if vi.get("semantic") == "POSITION":
                        pos = arr[corners[:, off]][:, :3]
                    elif vi.get("semantic") == "NORMAL" and nrm is None:
                        nrm = arr[corners[:, off]][:, :3]
            elif sem == "NORMAL":
                nrm = _dae_array(sources.get(sid), path)[corners[:, off]][:, :3]
            elif sem == "TEXCOORD" and uv is None:
                uv = _dae_array(sources.get(sid), path)[corners[:, off]][:, :2]
        if pos is None or len(pos) < 3:
            continue
        faces = np.arange(len(pos), dtype=np.int64).reshape(-1, 3)
        used = sorted({int(i.get("offset", "0")) for i in inputs})
        sym = prim.get("material")
        material = colors.get(binding.get(sym, sym)) or MaterialSpec(name=str(sym or "material"))
        raw = weld(RawMesh(pos, faces, nrm, uv, material), corners[:, used])
        out.append(_apply_affine(raw, t))
    return out
