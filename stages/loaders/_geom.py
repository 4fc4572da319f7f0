"""Shared helpers of the articulated loaders (URDF, MJCF): safe XML, frames, primitives, mesh files,
path containment, mass properties and names.

Conventions as in ``asset_catalog.asset_model``: meters, kilograms, radians; quaternions (w, x, y, z);
4x4 homogeneous transforms with column vectors (``p_parent = T @ p_child``).
"""

from __future__ import annotations

import functools
import logging
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from asset_catalog.asset_model import MassProperties, MaterialSpec, MeshPart, Pose
from pipeline.types import ItemError

log = logging.getLogger(__name__)

MAX_XML_BYTES = 32 * 1024 * 1024
"""Largest URDF/MJCF/DAE text accepted [bytes]; larger files are rejected as oversized."""

MAX_MESH_BYTES = 512 * 1024 * 1024
"""Largest mesh file accepted [bytes]."""

_SMOOTH_ANGLE = np.radians(30.0)
_FORBIDDEN_XML = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)


# ----------------------------------------------------------------------------------------------- XML


def read_xml(path: Path) -> ET.Element:
    """Parse an XML file with no DTD, no entity expansion, no external references.

    Raises ItemError (one line, naming the file) for a missing, oversized or malformed file, or one that
    declares a DOCTYPE or ENTITY (rejected outright: the formats never need them and entity expansion
    is an attack vector).
    """
    try:
        size = path.stat().st_size
    except OSError as e:
        raise ItemError(f"{path}: cannot read: {e.strerror or e}") from None
    if size > MAX_XML_BYTES:
        raise ItemError(f"{path}: file too large ({size} bytes > {MAX_XML_BYTES})")
    data = path.read_bytes()
    if _FORBIDDEN_XML.search(data):
        raise ItemError(f"{path}: XML declares a DOCTYPE or ENTITY, which is not accepted")
    try:
        return ET.fromstring(data)
    except ET.ParseError as e:
        raise ItemError(f"{path}: malformed XML: {e}") from None


def parse_floats(text: str | None, n: int | None, *, file: Path, what: str,
                 default: tuple[float, ...] | None = None) -> tuple[float, ...]:
    """Whitespace-separated numbers; ``n`` of them (if given), all finite, else ItemError naming ``what``."""
    if text is None or not text.strip():
        if default is None:
            raise ItemError(f"{file}: {what}: missing value")
        return default
    try:
        vals = tuple(float(t) for t in text.split())
    except ValueError:
        raise ItemError(f"{file}: {what}: not a list of numbers: {text.strip()!r}") from None
    if n is not None and len(vals) != n:
        raise ItemError(f"{file}: {what}: expected {n} numbers, got {len(vals)}: {text.strip()!r}")
    if not all(np.isfinite(vals)):
        raise ItemError(f"{file}: {what}: non-finite number in {text.strip()!r}")
    return vals


# -------------------------------------------------------------------------------------------- frames


def rpy_matrix(rpy: tuple[float, float, float]) -> np.ndarray:
    """URDF roll-pitch-yaw (fixed axes X, Y, Z) -> 3x3 rotation ``Rz(y) @ Ry(p) @ Rx(r)``."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("xyz", rpy).as_matrix()


def quat_matrix(q_wxyz) -> np.ndarray:
    """Unit quaternion (w, x, y, z) -> 3x3 rotation (normalised first)."""
    from scipy.spatial.transform import Rotation

    w, x, y, z = (float(v) for v in q_wxyz)
    return Rotation.from_quat([x, y, z, w]).as_matrix()


def matrix_quat(r: np.ndarray) -> tuple[float, float, float, float]:
    """3x3 rotation -> unit quaternion (w, x, y, z) with w >= 0."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(r, dtype=float)).as_quat()
    q = np.array([w, x, y, z])
    if q[0] < 0:
        q = -q
    return tuple(float(v) for v in q)


def transform(position=(0.0, 0.0, 0.0), rotation: np.ndarray | None = None) -> np.ndarray:
    """4x4 transform from a position (3,) and a 3x3 rotation."""
    m = np.eye(4)
    if rotation is not None:
        m[:3, :3] = rotation
    m[:3, 3] = position
    return m


def inverse(t: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    r = t[:3, :3]
    out = np.eye(4)
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ t[:3, 3]
    return out


def pose_of(t: np.ndarray) -> Pose:
    """Rigid 4x4 transform -> Pose (position, quaternion w x y z)."""
    return Pose(tuple(float(v) for v in t[:3, 3]), matrix_quat(t[:3, :3]))


# ------------------------------------------------------------------------------------ mesh geometry


@dataclass(frozen=True, eq=False)
class RawMesh:
    """A triangle mesh before it gets a name: vertices (N, 3) [m], faces (M, 3) int64, normals (N, 3)
    or None, uvs (N, 2) or None, and the material the mesh file itself gives (or None)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    material: MaterialSpec | None = None

    def transformed(self, t: np.ndarray) -> "RawMesh":
        """This mesh moved by the rigid 4x4 transform ``t`` (normals rotated)."""
        if np.array_equal(t, np.eye(4)):
            return self
        v = _rotate(self.vertices, t[:3, :3]) + t[:3, 3]
        n = None if self.normals is None else _rotate(self.normals, t[:3, :3])
        return RawMesh(v, self.faces, n, self.uvs, self.material)

    def scaled(self, s) -> "RawMesh":
        """This mesh scaled per axis by ``s`` (3,) (normals fixed up; a mirroring scale flips winding)."""
        s = np.broadcast_to(np.asarray(s, dtype=float), (3,))
        v = self.vertices * s
        faces = self.faces if np.prod(s) > 0 else self.faces[:, ::-1].copy()
        n = None
        if self.normals is not None:
            n = self.normals / s
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        return RawMesh(v, faces, n, self.uvs, self.material)

    def part(self, name: str, material: str | None) -> MeshPart:
        return MeshPart(name=name, vertices=np.ascontiguousarray(self.vertices, dtype=np.float64),
                        faces=np.ascontiguousarray(self.faces, dtype=np.int64),
                        normals=None if self.normals is None
                        else np.ascontiguousarray(self.normals, np.float64),
                        uvs=None if self.uvs is None else np.ascontiguousarray(self.uvs, np.float64),
                        material=material)


def _rotate(points: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``points @ r.T`` for (N, 3) points, without a BLAS call (threaded BLAS is slow for thin arrays)."""
    p = np.asarray(points, float)
    return p[:, :1] * r[:, 0] + p[:, 1:2] * r[:, 1] + p[:, 2:3] * r[:, 2]


def _shaded(mesh) -> RawMesh:
    """Split vertices at sharp edges (> 30 degrees) so per-vertex normals keep flat faces flat."""
    import trimesh

    m = trimesh.graph.smooth_shade(mesh, angle=_SMOOTH_ANGLE)
    return RawMesh(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64),
                   np.asarray(m.vertex_normals, float))


def box(half_extents) -> RawMesh:
    """Box centred at the origin with half-extents (3,) [m]: 24 vertices with flat face normals."""
    return _unit_box().scaled(np.asarray(half_extents, float))


def cylinder(radius: float, half_length: float) -> RawMesh:
    """Cylinder along +Z centred at the origin [m]: smooth sides, flat caps (32 sections)."""
    return _unit_cylinder().scaled((radius, radius, half_length))


@functools.lru_cache(maxsize=1)
def _unit_box() -> RawMesh:
    verts, faces, normals = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]
            corners = [n + a * u + b * v for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            base = len(verts)
            verts += corners
            normals += [n] * 4
            quad = [(0, 1, 2), (0, 2, 3)] if sign > 0 else [(0, 2, 1), (0, 3, 2)]
            faces += [[base + i for i in tri] for tri in quad]
    return _frozen(RawMesh(np.array(verts), np.array(faces, np.int64), np.array(normals)))


@functools.lru_cache(maxsize=1)
def _unit_cylinder(sections: int = 32) -> RawMesh:
    ang = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    ring = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(sections)])
    k = np.arange(sections)
    k1 = (k + 1) % sections
    side_v = np.vstack([ring + (0, 0, -1), ring + (0, 0, 1)])
    side_n = np.vstack([ring, ring])
    side_f = np.vstack([np.column_stack([k, k1, sections + k1]),
                        np.column_stack([k, sections + k1, sections + k])])
    verts, normals, faces = [side_v], [side_n], [side_f]
    off = 2 * sections
    for z in (-1.0, 1.0):
        cap = np.vstack([[0, 0, z], ring + (0, 0, z)])
        tri = np.column_stack([np.zeros(sections, np.int64), 1 + k, 1 + k1]) if z > 0 else \
            np.column_stack([np.zeros(sections, np.int64), 1 + k1, 1 + k])
        verts.append(cap)
        normals.append(np.tile((0.0, 0.0, z), (sections + 1, 1)))
        faces.append(tri + off)
        off += sections + 1
    return _frozen(RawMesh(np.vstack(verts), np.vstack(faces).astype(np.int64), np.vstack(normals)))


def _frozen(m: RawMesh) -> RawMesh:
    for a in (m.vertices, m.faces, m.normals):
        a.setflags(write=False)
    return m


def capsule(radius: float, half_length: float) -> RawMesh:
    """Capsule along +Z: a cylinder of length 2*half_length capped by hemispheres of ``radius`` [m]."""
    import trimesh

    m = trimesh.creation.capsule(height=2.0 * half_length, radius=radius, count=[24, 12])
    return RawMesh(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64), np.asarray(m.vertex_normals))


def ellipsoid(radii) -> RawMesh:
    """Ellipsoid centred at the origin with semi-axes (3,) [m] (a sphere when all equal)."""
    return _unit_sphere().scaled(radii)


@functools.lru_cache(maxsize=1)
def _unit_sphere() -> RawMesh:
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    v = np.asarray(m.vertices, float)
    return _frozen(RawMesh(v, np.asarray(m.faces, np.int64), v / np.linalg.norm(v, axis=1, keepdims=True)))


def box_uvs(mesh: RawMesh, repeat=(1.0, 1.0)) -> RawMesh:
    """Give a mesh without UVs box-projected UVs (per face, from its dominant normal axis), in meters
    times ``repeat``: every face gets its own three vertices (flat normals)."""
    tri = mesh.vertices[mesh.faces]                                     # (M, 3, 3)
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-20)
    axis = np.argmax(np.abs(fn), axis=1)
    planes = np.array([[1, 2], [0, 2], [0, 1]])[axis]                   # (M, 2) coordinates kept
    uv = np.take_along_axis(tri, planes[:, None, :].repeat(3, axis=1), axis=2) * np.asarray(repeat, float)
    normals = (mesh.normals[mesh.faces].reshape(-1, 3) if mesh.normals is not None
               else np.repeat(fn, 3, axis=0))
    return RawMesh(tri.reshape(-1, 3), np.arange(3 * len(tri), dtype=np.int64).reshape(-1, 3),
                   normals, uv.reshape(-1, 2), mesh.material)


def convex_hull(mesh: RawMesh) -> RawMesh:
    """The convex hull of a mesh's vertices, outward-wound, flat-shaded (mesh returned as is when its
    points span no volume)."""
    import trimesh

    try:
        hull = trimesh.convex.convex_hull(np.asarray(mesh.vertices, float))
    except Exception as e:  # qhull raises its own error types for flat or degenerate input
        log.debug("no hull: %s", e)
        return mesh
    if not hull.is_volume:
        return mesh
    return RawMesh(np.asarray(hull.vertices, float), np.asarray(hull.faces, np.int64))


def check_finite_mesh(mesh: RawMesh, *, file: Path, what: str) -> None:
    """ItemError if the mesh is empty, has NaN/inf vertices or face indices out of range."""
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise ItemError(f"{file}: {what}: empty mesh")
    if not np.isfinite(mesh.vertices).all():
        raise ItemError(f"{file}: {what}: mesh has NaN or infinite vertices")
    if mesh.faces.min() < 0 or mesh.faces.max() >= len(mesh.vertices):
        raise ItemError(f"{file}: {what}: face index out of range")


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


def weld(m: RawMesh, keys: np.ndarray | None = None) -> RawMesh:
    """Merge a corner-per-vertex mesh into shared vertices: corners with equal ``keys`` rows (K, c) int64
    (source indices of position, normal, uv) or, without keys, equal (position, normal, uv) values."""
    if keys is not None:
        keys = np.asarray(keys, np.int64).reshape(len(m.vertices), -1)
        radix = keys.max(axis=0) + 1
        if float(np.prod(radix.astype(float))) < 2.0**62:
            key = np.zeros(len(keys), np.int64)
            for col, r in zip(keys.T, radix):
                key = key * r + col
            _, first, inv = np.unique(key, return_index=True, return_inverse=True)
            return _gather(m, first, inv)
    cols = [a for a in (m.vertices, m.normals, m.uvs) if a is not None]
    key = np.ascontiguousarray(np.round(np.hstack(cols), 9))
    _, first, inv = np.unique(key.view(np.dtype((np.void, key.dtype.itemsize * key.shape[1]))).ravel(),
                              return_index=True, return_inverse=True)
    return _gather(m, first, inv)


def _gather(m: RawMesh, first: np.ndarray, inv: np.ndarray) -> RawMesh:
    return RawMesh(m.vertices[first], inv.reshape(-1)[m.faces].astype(np.int64),
                   None if m.normals is None else m.normals[first], None if m.uvs is None else m.uvs[first],
                   m.material)


# --------------------------------------------------------------------------------------------- paths


def inside_catalog(path: Path, catalog_dir: Path | None, *, source: Path, what: str) -> Path:
    """``path`` resolved; ItemError if ``catalog_dir`` is given and the path (through links) leaves it."""
    resolved = Path(path).resolve()
    if catalog_dir is not None and not resolved.is_relative_to(Path(catalog_dir).resolve()):
        raise ItemError(f"{source}: {what} {str(path)!r} escapes the catalog folder {catalog_dir}")
    return resolved


def source_defines_collision(model):
    """The model with ``collision_source = ()`` (no colliders) on links without collision geometry when
    the source gives collision geometry to some link: a URDF/MJCF that models collision leaves the other
    links non-colliding on purpose (visual-only knobs, lights, frames). A source with no collision
    geometry anywhere keeps ``None`` everywhere, so colliders are computed from the visuals."""
    from dataclasses import replace

    if not any(lk.collision_source for lk in model.links):
        return model
    return replace(model, links=tuple(lk if lk.collision_source else replace(lk, collision_source=())
                                      for lk in model.links))


# ------------------------------------------------------------------------------------------ inertia


def mass_properties(mass: float, com, tensor: np.ndarray) -> MassProperties:
    """MassProperties from a mass [kg], centre of mass (3,) [m] and a 3x3 inertia tensor about the
    centre of mass in the link frame [kg m^2] (principal axes by eigen-decomposition)."""
    tensor = 0.5 * (np.asarray(tensor, float) + np.asarray(tensor, float).T)
    vals, vecs = np.linalg.eigh(tensor)
    if np.linalg.det(vecs) < 0:
        vecs[:, 2] = -vecs[:, 2]
    return MassProperties(mass=float(mass), center_of_mass=tuple(float(c) for c in com),
                          diagonal_inertia=tuple(float(max(v, 0.0)) for v in vals),
                          principal_axes=matrix_quat(vecs))


def tensor_of(mp: MassProperties) -> np.ndarray:
    """The 3x3 inertia tensor about the centre of mass, in the link frame [kg m^2]."""
    r = quat_matrix(mp.principal_axes)
    return r @ np.diag(mp.diagonal_inertia) @ r.T


def combine_mass(parts: list[tuple[float, np.ndarray, np.ndarray]]) -> tuple[float, np.ndarray, np.ndarray]:
    """Combine (mass, com (3,), tensor about com (3,3)) in one frame -> total, by the parallel-axis rule."""
    total = sum(m for m, _, _ in parts)
    if total <= 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = sum(m * np.asarray(c) for m, c, _ in parts) / total
    tensor = np.zeros((3, 3))
    for m, c, i in parts:
        d = np.asarray(c) - com
        tensor += i + m * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return total, com, tensor


def implausible_inertia(mp: MassProperties, points: np.ndarray | None) -> str | None:
    """Why the mass properties are physically implausible, or None.

    Checks: finite, mass > 0, principal moments > 0 obeying the triangle inequality (1 % slack), and,
    where the link has geometry ``points`` (K, 3) [m], no moment larger than 4 x mass x (largest distance
    from the centre of mass to the geometry)^2 (placeholder inertias such as 1 kg m^2 on a 20 cm drawer)."""
    vals = np.array(mp.diagonal_inertia)
    if not (np.isfinite(mp.mass) and mp.mass > 0 and np.isfinite(vals).all()
            and np.isfinite(mp.center_of_mass).all()):
        return "non-finite or non-positive mass/inertia"
    if (vals <= 0).any():
        return f"non-positive principal inertia {tuple(vals)}"
    a, b, c = np.sort(vals)
    if a + b < c * 0.99:
        return f"principal inertia {tuple(vals)} violates the triangle inequality"
    if points is not None and len(points):
        r2 = float(np.max(np.sum((points - np.asarray(mp.center_of_mass)) ** 2, axis=1)))
        if vals.max() > 4.0 * mp.mass * max(r2, 1e-8):
            return (f"inertia {vals.max():.3g} kg m^2 too large for mass {mp.mass:.3g} kg "
                    f"within {np.sqrt(r2):.3g} m")
    return None


# -------------------------------------------------------------------------------------------- names


_BAD = re.compile(r"[^A-Za-z0-9_]")


class NameTable:
    """Unique USD-safe identifiers ([A-Za-z_][A-Za-z0-9_]*) for source names, in first-come order."""

    def __init__(self) -> None:
        self._used: set[str] = set()

    def add(self, raw: str | None, fallback: str) -> str:
        base = _BAD.sub("_", (raw or "").strip()) or fallback
        if not (base[0].isalpha() or base[0] == "_"):
            base = "_" + base
        name, k = base, 1
        while name in self._used:
            name = f"{base}_{k}"
            k += 1
        self._used.add(name)
        return name


def hull_mass_properties(points: np.ndarray, mass: float, com) -> MassProperties | None:
    """Mass properties of ``mass`` [kg] spread uniformly over the convex hull of ``points`` (K, 3) [m],
    expressed about ``com`` (3,) [m] (the source's centre of mass): used where a source gives a plausible
    mass but an implausible inertia. None if the points span no volume."""
    import trimesh

    try:
        hull = trimesh.convex.convex_hull(np.asarray(points, float))
    except Exception as e:  # qhull raises its own error types for flat or degenerate input
        log.debug("no hull for inertia: %s", e)
        return None
    if not hull.is_volume or hull.volume <= 1e-12:
        return None
    tensor = np.asarray(hull.moment_inertia, float) * (mass / hull.volume)   # about the hull's centroid
    d = np.asarray(com, float) - np.asarray(hull.center_mass, float)
    tensor = tensor + mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return mass_properties(mass, com, tensor)


def scale_and_up(model, meters_per_unit: float | None, up_axis: str | None):
    """The AssetModel with lengths multiplied by ``meters_per_unit`` (geometry, link poses, joint frames,
    centres of mass, prismatic limits and velocities; inertia by its square; masses kept) and, for
    ``up_axis == "Y"``, the asset turned +90 degrees about X so that source +Y becomes +Z (applied to the
    link poses in the root frame: link-local data and joint frames are unchanged)."""
    from dataclasses import replace

    from asset_catalog.asset_model import JointType, Pose

    s = float(meters_per_unit) if meters_per_unit else 1.0
    turn = up_axis == "Y"
    if s == 1.0 and not turn:
        return model

    def part(p: MeshPart) -> MeshPart:
        return replace(p, vertices=p.vertices * s)

    def pose(p: Pose, root: bool) -> Pose:
        t = transform(np.asarray(p.position) * s, quat_matrix(p.orientation))
        if turn and root:
            t = transform(rotation=np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)) @ t
        return pose_of(t)

    links = []
    for lk in model.links:
        mass = lk.mass
        if mass is not None:
            mass = replace(mass, center_of_mass=tuple(c * s for c in mass.center_of_mass),
                           diagonal_inertia=tuple(i * s * s for i in mass.diagonal_inertia))
        links.append(replace(
            lk, pose=pose(lk.pose, True), visuals=tuple(part(p) for p in lk.visuals),
            collision_source=None if lk.collision_source is None
            else tuple(part(p) for p in lk.collision_source),
            colliders=tuple(part(p) for p in lk.colliders), mass=mass))
    joints = []
    for j in model.joints:
        lin = j.type == JointType.PRISMATIC
        joints.append(replace(
            j, frame=pose(j.frame, False),
            lower=j.lower * s if lin and j.lower is not None else j.lower,
            upper=j.upper * s if lin and j.upper is not None else j.upper,
            max_velocity=j.max_velocity * s if lin and j.max_velocity is not None else j.max_velocity))
    return replace(model, links=tuple(links), joints=tuple(joints))



def judge_masses(model):
    """The AssetModel with each source-given mass judged against its link's geometry (in final units).

    Kept as is when plausible. Dropped (mass None, mass_from_source False: the annotate stage computes it)
    when non-finite or non-positive, or when mass / (convex-hull volume of the link's geometry) exceeds
    3 x the density of the annotated material (placeholder masses such as 1 kg on a 7 cm fruit; a hull
    only over-estimates the solid volume, so heavier is impossible). With a plausible mass but an
    implausible inertia (see ``implausible_inertia``), the mass and centre of mass are kept and the inertia
    is that of the mass spread over the geometry's hull.
    """
    from dataclasses import replace

    from asset_catalog.materials import MATERIAL_RULES, MaterialClass

    density = MATERIAL_RULES[MaterialClass(model.annotation.material)].density
    links = []
    for lk in model.links:
        if lk.mass is None or not lk.mass_from_source:
            links.append(lk)
            continue
        parts = list(lk.collision_source or ()) or list(lk.visuals)
        pts = np.vstack([p.vertices for p in parts]) if parts else None
        mp, why = lk.mass, None
        if not (np.isfinite(mp.mass) and mp.mass > 0 and np.isfinite(mp.center_of_mass).all()):
            mp, why = None, f"mass {mp.mass} is not positive and finite"
        elif pts is not None:
            vol = _hull_volume(pts)
            if vol > 0 and mp.mass / vol > 3.0 * density:
                mp, why = None, (f"mass {mp.mass:.4g} kg in a hull of {vol:.3g} m^3 is denser than 3 x "
                                 f"{model.annotation.material} ({density:.0f} kg/m^3)")
        if mp is None:
            log.warning("%s: link %r: source mass ignored (%s); it will be computed",
                        model.name, lk.name, why)
            links.append(replace(lk, mass=None, mass_from_source=False))
            continue
        why = implausible_inertia(mp, pts)
        if why is not None:
            hull = hull_mass_properties(pts, mp.mass, mp.center_of_mass) if pts is not None else None
            if hull is None:
                log.warning("%s: link %r: source mass ignored (%s)", model.name, lk.name, why)
                links.append(replace(lk, mass=None, mass_from_source=False))
                continue
            log.warning("%s: link %r: %s; kept mass %.4g kg, inertia from the geometry's hull",
                        model.name, lk.name, why, mp.mass)
            mp = hull
        links.append(replace(lk, mass=mp))
    return replace(model, links=tuple(links))


def _hull_volume(points: np.ndarray) -> float:
    """Volume [m^3] of the convex hull of (K, 3) points; 0 for flat or degenerate sets."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, float)
    if len(pts) < 4096:
        pts = np.unique(np.round(pts, 9), axis=0)
    try:
        return float(ConvexHull(pts).volume)
    except (QhullError, ValueError) as e:
        log.debug("no hull: %s", e)
        return 0.0
