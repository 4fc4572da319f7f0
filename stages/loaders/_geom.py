"""Shared helpers of the articulated loaders (URDF, MJCF): safe XML, frames, primitives, path
containment, names and unit/up-axis conversion. Mesh files are read by ``stages.loaders._meshfiles``,
mass properties judged by ``stages.loaders._inertia``.

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

from asset_catalog.asset_model import MaterialSpec, MeshPart, Pose
from pipeline.types import ItemError

log = logging.getLogger(__name__)

MAX_XML_BYTES = 32 * 1024 * 1024
"""Largest URDF/MJCF/DAE text accepted [bytes]; larger files are rejected as oversized."""

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
