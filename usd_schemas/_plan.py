"""Compute phase of the asset package writer: everything the USD layers will hold, as plain values.

No USD authoring here (pxr is used only for ``Tf.MakeValidIdentifier``); ``_author`` turns a
``PackagePlan`` into layers inside one ``Sdf.ChangeBlock``.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from asset_catalog.asset_model import (AssetModel, JointType, Link, MassProperties, MaterialSpec, MeshPart,
                                       PhysicsMaterialSpec, Pose)
from asset_catalog.materials import MATERIAL_RULES, MaterialClass, PhysicalProperties, sample_physical_properties

RESERVED_CHILDREN = ("Looks", "joints")
DEFAULT_MATERIAL = "default_material"
PHYSICS_MATERIAL = "PhysicsMaterial"


class PlanError(ValueError):
    """The model cannot be written (message names the asset and the problem)."""


@dataclass(frozen=True)
class MeshPlan:
    """A Mesh prim. points (N, 3) float32 [m]; indices (3M,) int32; normals: (K, 3) float32 unit
    vectors, per vertex through normals_indices (N,) int32 when given (indexed primvar, repeated
    values stored once), else K = N; st likewise (K, 2) float32 with st_indices; extent (2, 3)
    float32; material: prim path or None."""

    path: str
    points: np.ndarray
    indices: np.ndarray
    normals: np.ndarray | None
    st: np.ndarray | None
    extent: np.ndarray
    material: str | None
    collider: bool = False
    normals_indices: np.ndarray | None = None
    st_indices: np.ndarray | None = None
    condim: int | None = None   # colliders: MuJoCo contact dimensionality (mjc:condim), None: 3


@dataclass(frozen=True)
class BodyPlan:
    """A link Xform. translate [m] (3,); orient (w, x, y, z); rigid: has RigidBodyAPI + MassAPI;
    physics_material: path of the physics material its colliders are bound to."""

    path: str
    translate: tuple[float, float, float]
    orient: tuple[float, float, float, float]
    rigid: bool
    mass: MassProperties | None
    meshes: tuple[MeshPlan, ...]
    colliders: tuple[MeshPlan, ...]
    collider_approx: str | None
    physics_material: str = ""


@dataclass(frozen=True)
class PhysicsMaterialPlan:
    """A physics material prim (UsdPhysics + NewtonMaterialAPI) at ``path``."""

    path: str
    props: PhysicalProperties


@dataclass(frozen=True)
class JointPlan:
    """A UsdPhysics joint in USD units: positions [m], rotations (w, x, y, z), revolute limits and
    velocities in degrees, drive gains per degree for revolute joints.

    body0: prim path of the parent body, or of the asset root for a joint to the world.
    drive: (stiffness, damping, max_force or None) or None.
    """

    path: str
    usd_type: str  # PhysicsRevoluteJoint | PhysicsPrismaticJoint | PhysicsFixedJoint
    body0: str
    body1: str
    local_pos0: tuple[float, float, float]
    local_rot0: tuple[float, float, float, float]
    local_pos1: tuple[float, float, float]
    local_rot1: tuple[float, float, float, float]
    lower: float | None = None
    upper: float | None = None
    drive: tuple[float, float, float | None] | None = None
    friction: float = 0.0
    max_velocity: float | None = None
    source_name: str = ""
    armature: float = 0.0
    limit_solref: tuple[float, float] | None = None   # mjc:solreflimit (time constant [s], damping ratio)


@dataclass(frozen=True)
class TextureRef:
    """A texture file of a material: rel_path relative to the package ('./textures/x.png'),
    output: UsdUVTexture output used ('rgb', 'r', 'g', 'b'), color_space: 'sRGB' or 'raw'."""

    rel_path: str
    output: str
    color_space: str


@dataclass(frozen=True)
class MaterialPlan:
    path: str
    name: str
    base_color: tuple[float, float, float]
    opacity: float
    roughness: float
    metallic: float
    textures: dict[str, TextureRef] = field(default_factory=dict)  # role -> texture


@dataclass(frozen=True)
class PackagePlan:
    asset_id: str
    root: str
    annotation_attrs: dict[str, object]
    category: str
    articulated: bool
    bodies: tuple[BodyPlan, ...]
    joints: tuple[JointPlan, ...]
    materials: tuple[MaterialPlan, ...]
    physics: PhysicalProperties
    physics_materials: tuple[PhysicsMaterialPlan, ...]  # the asset's first, then links' own
    texture_copies: tuple[tuple[Path, str], ...]  # (source file, relative destination)
    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]


# ---------------------------------------------------------------------------------------------
# names


class _Namer:
    """Unique valid USD identifiers within one parent, in the order names are asked for."""

    def __init__(self, reserved: tuple[str, ...] = ()) -> None:
        self._used = set(reserved)

    def __call__(self, name: str) -> str:
        from pxr import Tf

        base = Tf.MakeValidIdentifier(name or "unnamed")
        cand, i = base, 1
        while cand in self._used:
            cand = f"{base}_{i}"
            i += 1
        self._used.add(cand)
        return cand


# ---------------------------------------------------------------------------------------------
# geometry


def _vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (N, 3) of a triangle mesh."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(ln > 0, n / np.maximum(ln, 1e-30), np.array([0.0, 0.0, 1.0]))


def _check_mesh(asset_id: str, link: str, part: MeshPart) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(part.vertices, dtype=np.float64)
    f = np.asarray(part.faces, dtype=np.int64)
    where = f"asset {asset_id!r}, link {link!r}, mesh {part.name!r}"
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise PlanError(f"{where}: vertices must be a non-empty (N, 3) array, got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise PlanError(f"{where}: faces must be a non-empty (M, 3) array, got shape {f.shape}")
    if not np.isfinite(v).all():
        raise PlanError(f"{where}: vertices contain NaN or inf")
    if f.min() < 0 or f.max() >= len(v):
        raise PlanError(f"{where}: face index out of range [0, {len(v)})")
    return v, f


def _mesh_plan(asset_id: str, link: str, path: str, part: MeshPart, material: str | None,
               collider: bool, condim: int | None = None) -> MeshPlan:
    v, f = _check_mesh(asset_id, link, part)
    st = None
    n = part.normals if part.normals is not None else _vertex_normals(v, f)
    normals = np.ascontiguousarray(np.asarray(n, dtype=np.float32))
    if normals.shape != v.shape:
        raise PlanError(f"asset {asset_id!r}, mesh {part.name!r}: normals shape {normals.shape} != {v.shape}")
    if not collider:
        if part.uvs is not None:
            st = np.ascontiguousarray(np.asarray(part.uvs, dtype=np.float32))
            if st.shape != (len(v), 2):
                raise PlanError(f"asset {asset_id!r}, mesh {part.name!r}: uvs shape {st.shape} != ({len(v)}, 2)")
    pts = np.ascontiguousarray(v.astype(np.float32))
    extent = np.stack([pts.min(axis=0), pts.max(axis=0)]).astype(np.float32)
    normals, n_idx = _indexed(normals)
    st, st_idx = _indexed(st)
    return MeshPlan(path=path, points=pts, indices=np.ascontiguousarray(f.reshape(-1).astype(np.int32)),
                    normals=normals, st=st, extent=extent, material=material, collider=collider,
                    normals_indices=n_idx, st_indices=st_idx, condim=condim if collider else None)


def _indexed(values: np.ndarray | None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(unique rows, per-vertex indices) if some rows repeat bit for bit, else (values, None).
    Deterministic: unique rows in the order of their bytes."""
    if values is None or len(values) < 2:
        return values, None
    rows = np.ascontiguousarray(values).view(np.dtype((np.void, values.dtype.itemsize * values.shape[1]))).ravel()
    _, first, inv = np.unique(rows, return_index=True, return_inverse=True)
    if len(first) == len(values):
        return values, None
    return np.ascontiguousarray(values[first]), np.ascontiguousarray(inv.reshape(-1).astype(np.int32))


# ---------------------------------------------------------------------------------------------
# rotations


def _quat_from_matrix(r: np.ndarray) -> tuple[float, float, float, float]:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(r).as_quat()
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    return (float(w) + 0.0, float(x) + 0.0, float(y) + 0.0, float(z) + 0.0)  # + 0.0: no negative zeros


def axis_to_x_rotation(axis: tuple[float, float, float]) -> np.ndarray:
    """A 3x3 rotation R with R @ [1, 0, 0] = axis (unit): the joint frame rotated so that USD's
    joint axis X is the model's arbitrary axis. The minimal rotation; 180 deg about Z for -X."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if not np.isfinite(n) or n < 1e-9:
        raise PlanError(f"joint axis {tuple(axis)} is not a unit vector")
    a = a / n
    x = np.array([1.0, 0.0, 0.0])
    c = float(np.dot(x, a))
    if c > 1.0 - 1e-12:
        return np.eye(3)
    if c < -1.0 + 1e-12:
        return np.diag([-1.0, -1.0, 1.0])
    k = np.cross(x, a)
    s = np.linalg.norm(k)
    k = k / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def _pose_tuple(m: np.ndarray) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    return tuple(float(t) + 0.0 for t in m[:3, 3]), _quat_from_matrix(m[:3, :3])


# ---------------------------------------------------------------------------------------------
# joints


def _joint_plans(model: AssetModel, body_paths: dict[str, str], root: str, namer: _Namer) -> list[JointPlan]:
    plans: list[JointPlan] = []
    links = {lk.name: lk for lk in model.links}
    for j in model.joints:
        for end in (j.parent, j.child):
            if end not in links:
                raise PlanError(f"asset {model.name!r}: joint {j.name!r} names unknown link {end!r}")
        t_p = links[j.parent].pose.matrix()
        t_c = links[j.child].pose.matrix()
        rot = np.eye(4)
        if j.type != JointType.FIXED:
            rot[:3, :3] = axis_to_x_rotation(j.axis)
        t_pj = j.frame.matrix() @ rot
        local0 = t_pj
        local1 = np.linalg.inv(t_c) @ t_p @ t_pj
        p0, r0 = _pose_tuple(local0)
        p1, r1 = _pose_tuple(local1)
        revolute = j.type == JointType.REVOLUTE
        scale = 180.0 / math.pi if revolute else 1.0  # rad -> deg for USD's angular values
        lower = None if j.lower is None else j.lower * scale
        upper = None if j.upper is None else j.upper * scale
        if lower is not None and upper is not None and lower > upper:
            raise PlanError(f"asset {model.name!r}: joint {j.name!r} lower limit > upper limit")
        drive = None
        if j.type != JointType.FIXED and (j.stiffness > 0 or j.damping > 0 or j.max_effort is not None):
            gain = math.pi / 180.0 if revolute else 1.0  # per rad -> per deg
            drive = (j.stiffness * gain, j.damping * gain, j.max_effort)
        usd_type = {JointType.REVOLUTE: "PhysicsRevoluteJoint", JointType.PRISMATIC: "PhysicsPrismaticJoint",
                    JointType.FIXED: "PhysicsFixedJoint"}[JointType(j.type)]
        plans.append(JointPlan(
            path=f"{root}/joints/{namer(j.name)}", usd_type=usd_type, body0=body_paths[j.parent],
            body1=body_paths[j.child], local_pos0=p0, local_rot0=r0, local_pos1=p1, local_rot1=r1,
            lower=lower, upper=upper, drive=drive, friction=float(j.friction), armature=float(j.armature),
            max_velocity=None if j.max_velocity is None else j.max_velocity * scale, source_name=j.name,
            limit_solref=None if j.type == JointType.FIXED or j.limit_solref is None
            else (float(j.limit_solref[0]), float(j.limit_solref[1]))))
    return plans


def _root_fixed_joint(model: AssetModel, body_paths: dict[str, str], root: str, namer: _Namer) -> JointPlan:
    """The joint that fixes the root link to the world. body0 is the asset's root Xform (not a
    body), so the joint frame follows the asset wherever a scene places it (UsdPhysics treats a
    non-body target as the world at that prim's transform)."""
    lk = model.links[0]
    p0, r0 = _pose_tuple(lk.pose.matrix())
    return JointPlan(path=f"{root}/joints/{namer('root_fixed')}", usd_type="PhysicsFixedJoint", body0=root,
                     body1=body_paths[lk.name], local_pos0=p0, local_rot0=r0, local_pos1=(0.0, 0.0, 0.0),
                     local_rot1=(1.0, 0.0, 0.0, 0.0), source_name="root_fixed")


# ---------------------------------------------------------------------------------------------
# materials and textures


def _file_sha(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _texture_name(src: Path, digest: str) -> str:
    from pxr import Tf

    return f"{Tf.MakeValidIdentifier(src.stem)[:48]}_{digest[:10]}{src.suffix.lower()}"


def _material_plans(model: AssetModel, root: str, used: set[str]
                    ) -> tuple[list[MaterialPlan], dict[str, str], list[tuple[Path, str]]]:
    """Material plans for the materials the meshes use, their prim paths by model key, and the
    texture copies (deterministic names: <stem>_<sha256[:10]><ext>, identical files shared)."""
    namer = _Namer((PHYSICS_MATERIAL,))
    plans: list[MaterialPlan] = []
    paths: dict[str, str] = {}
    copies: dict[str, tuple[Path, str]] = {}
    specs: list[tuple[str, MaterialSpec]] = [(k, model.materials[k]) for k in sorted(used) if k in model.materials]
    missing = sorted(k for k in used if k not in model.materials and k != DEFAULT_MATERIAL)
    if missing:
        raise PlanError(f"asset {model.name!r}: meshes use undefined material(s) {', '.join(missing)}")
    if DEFAULT_MATERIAL in used:
        rule = MATERIAL_RULES[MaterialClass(model.annotation.material)]
        specs.append((DEFAULT_MATERIAL, MaterialSpec(name=DEFAULT_MATERIAL, base_color=rule.base_color,
                                                     roughness=rule.roughness, metallic=rule.metallic)))
    for key, spec in specs:
        path = f"{root}/Looks/{namer(spec.name or key)}"
        paths[key] = path
        tex: dict[str, TextureRef] = {}
        packed = (spec.roughness_texture is not None and spec.roughness_texture == spec.metallic_texture)
        roles = (
            ("diffuseColor", spec.base_color_texture, "rgb", "sRGB"),
            ("normal", spec.normal_texture, "rgb", "raw"),
            ("roughness", spec.roughness_texture, "g" if packed else "r", "raw"),
            ("metallic", spec.metallic_texture, "b" if packed else "r", "raw"),
            ("occlusion", spec.occlusion_texture, "r", "raw"),
        )
        for role, src, output, cs in roles:
            if src is None:
                continue
            src = Path(src)
            if not src.is_file():
                raise PlanError(f"{src}: texture of material {spec.name!r} (asset {model.name!r}) not found")
            key_s = str(src.resolve())
            if key_s not in copies:
                copies[key_s] = (src, f"textures/{_texture_name(src, _file_sha(src))}")
            tex[role] = TextureRef(rel_path=f"./{copies[key_s][1]}", output=output, color_space=cs)
        plans.append(MaterialPlan(path=path, name=key, base_color=tuple(float(c) for c in spec.base_color),
                                  opacity=float(spec.opacity), roughness=float(spec.roughness),
                                  metallic=float(spec.metallic), textures=tex))
    return plans, paths, sorted(copies.values(), key=lambda c: c[1])


# ---------------------------------------------------------------------------------------------
# the plan


def _annotation_attrs(model: AssetModel, pipeline_version: str) -> dict[str, object]:
    a = model.annotation
    return {
        "agentworld:category": a.category,
        "agentworld:placement": str(a.placement.value if hasattr(a.placement, "value") else a.placement),
        "agentworld:roomTypes": [str(getattr(r, "value", r)) for r in a.room_types],
        "agentworld:materialClass": str(getattr(a.material, "value", a.material)),
        "agentworld:interactable": bool(a.interactable),
        "agentworld:coOccurrence": [str(c) for c in a.co_occurrence],
        "agentworld:sourceHash": model.source_sha256,
        "agentworld:pipelineVersion": pipeline_version,
    }


def _physics_spec(model: AssetModel) -> PhysicsMaterialSpec:
    pm = model.physics_material
    if pm is not None:
        return pm
    # No sampled material yet (the annotate stage fills it): the class's mean values, no randomness.
    p = sample_physical_properties(model.annotation.material, _MeanRng())  # type: ignore[arg-type]
    return PhysicsMaterialSpec(static_friction=p.static_friction, dynamic_friction=p.dynamic_friction,
                               restitution=p.restitution, density=p.density,
                               torsional_friction=p.torsional_friction, rolling_friction=p.rolling_friction)


def _properties(pm: PhysicsMaterialSpec) -> PhysicalProperties:
    return PhysicalProperties(density=pm.density, static_friction=pm.static_friction,
                              dynamic_friction=pm.dynamic_friction, restitution=pm.restitution,
                              torsional_friction=pm.torsional_friction, rolling_friction=pm.rolling_friction)


def contact_condim(p: PhysicalProperties) -> int | None:
    """MuJoCo's contact dimensionality for colliders of material ``p`` (``mjc:condim``, read by
    Newton's SolverMuJoCo; a contact takes the larger of its two geoms'): 6 (sliding, torsional
    and rolling friction) with rolling friction, 4 (sliding and torsional) with torsional only,
    None (MuJoCo's 3, sliding only) with neither. With 3, MuJoCo ignores the other two."""
    if p.rolling_friction > 0:
        return 6
    return 4 if p.torsional_friction > 0 else None


def _physics_material_plans(model: AssetModel, root: str, looks: set[str]
                            ) -> tuple[list[PhysicsMaterialPlan], dict[str, str]]:
    """The asset's physics material, one more per link that declares its own contact properties,
    and the material path of each link; ``looks``: names already used in Looks."""
    base = _physics_spec(model)
    plans = [PhysicsMaterialPlan(f"{root}/Looks/{PHYSICS_MATERIAL}", _properties(base))]
    namer = _Namer((PHYSICS_MATERIAL, *sorted(looks)))
    paths = {}
    for lk in model.links:
        if lk.contact is None:
            paths[lk.name] = plans[0].path
            continue
        props = _properties(lk.contact.apply(base))
        for k in ("static_friction", "dynamic_friction", "restitution", "torsional_friction", "rolling_friction"):
            v = getattr(props, k)
            if not (math.isfinite(v) and v >= 0):
                raise PlanError(f"asset {model.name!r}, link {lk.name!r}: contact {k} must be finite and >= 0, got {v}")
        plans.append(PhysicsMaterialPlan(f"{root}/Looks/{namer(f'{PHYSICS_MATERIAL}_{lk.name}')}", props))
        paths[lk.name] = plans[-1].path
    return plans, paths


class _MeanRng:
    """Stands in for a Generator where no sampling is wanted: ``uniform`` returns the midpoint."""

    @staticmethod
    def uniform(low: float, high: float) -> float:
        return 0.5 * (low + high)


def _link_plan(model: AssetModel, lk: Link, path: str, rigid: bool, mat_paths: dict[str, str],
               physics: PhysicsMaterialPlan) -> BodyPlan:
    vis_namer, col_namer = _Namer(), _Namer()
    condim = contact_condim(physics.props)
    meshes = tuple(
        _mesh_plan(model.name, lk.name, f"{path}/visuals/{vis_namer(m.name)}", m,
                   mat_paths[m.material if m.material is not None else DEFAULT_MATERIAL], False)
        for m in lk.visuals)
    colliders = tuple(
        _mesh_plan(model.name, lk.name, f"{path}/colliders/{col_namer(c.name or f'hull_{i}')}", c, None, True,
                   condim)
        for i, c in enumerate(lk.colliders))
    if rigid and lk.mass is not None and not (lk.mass.mass > 0 and np.isfinite(lk.mass.mass)):
        raise PlanError(f"asset {model.name!r}, link {lk.name!r}: mass must be positive, got {lk.mass.mass}")
    t, q = _pose_tuple(lk.pose.matrix())
    return BodyPlan(path=path, translate=t, orient=q, rigid=rigid, mass=lk.mass if rigid else None,
                    meshes=meshes, colliders=colliders,
                    collider_approx=None if lk.collider_approx is None else str(lk.collider_approx),
                    physics_material=physics.path)


def _bbox(bodies: tuple[BodyPlan, ...]) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Axis-aligned box [m] in the asset root frame over visual meshes (colliders if no visuals)."""
    pts = []
    for b in bodies:
        m = Pose(b.translate, b.orient).matrix()
        for mesh in (b.meshes or b.colliders):
            p = mesh.points.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
            pts.append(np.stack([p.min(axis=0), p.max(axis=0)]))
    if not pts:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    allp = np.concatenate(pts)
    return tuple(float(x) for x in allp.min(axis=0)), tuple(float(x) for x in allp.max(axis=0))


def plan_package(model: AssetModel, pipeline_version: str) -> PackagePlan:
    """Everything the package will contain, computed from ``model`` (raises PlanError)."""
    if not model.links:
        raise PlanError(f"asset {model.name!r}: has no links")
    asset_id = model.annotation.id
    root = f"/{asset_id}"
    names = [lk.name for lk in model.links]
    if len(set(names)) != len(names):
        raise PlanError(f"asset {model.name!r}: duplicate link names")
    used = {m.material if m.material is not None else DEFAULT_MATERIAL for lk in model.links for m in lk.visuals}
    materials, mat_paths, copies = _material_plans(model, root, used)
    link_namer = _Namer(RESERVED_CHILDREN)
    body_paths = {lk.name: f"{root}/{link_namer(lk.name)}" for lk in model.links}
    static = model.fixed_base and not model.is_articulated
    looks = {p.rsplit("/", 1)[1] for p in mat_paths.values()}
    physics, physics_of_link = _physics_material_plans(model, root, looks)
    by_path = {p.path: p for p in physics}
    bodies = tuple(_link_plan(model, lk, body_paths[lk.name], not static, mat_paths,
                              by_path[physics_of_link[lk.name]]) for lk in model.links)
    joint_namer = _Namer()
    joints = _joint_plans(model, body_paths, root, joint_namer)
    if model.fixed_base and model.is_articulated:
        joints.insert(0, _root_fixed_joint(model, body_paths, root, joint_namer))
    _check_tree(model)
    lo, hi = _bbox(bodies)
    return PackagePlan(asset_id=asset_id, root=root, annotation_attrs=_annotation_attrs(model, pipeline_version),
                       category=model.annotation.category, articulated=model.is_articulated, bodies=bodies,
                       joints=tuple(joints), materials=tuple(materials), physics=physics[0].props,
                       physics_materials=tuple(physics), texture_copies=tuple(copies), bbox_min=lo, bbox_max=hi)


def _check_tree(model: AssetModel) -> None:
    """Joints must form a tree rooted at links[0]: every other link the child of exactly one joint."""
    if not model.joints:
        if len(model.links) > 1:
            raise PlanError(f"asset {model.name!r}: {len(model.links)} links but no joints")
        return
    children = [j.child for j in model.joints]
    dup = sorted({c for c in children if children.count(c) > 1})
    if dup:
        raise PlanError(f"asset {model.name!r}: link(s) {', '.join(dup)} are the child of several joints")
    if model.links[0].name in children:
        raise PlanError(f"asset {model.name!r}: root link {model.links[0].name!r} is a joint child")
    orphans = sorted({lk.name for lk in model.links[1:]} - set(children))
    if orphans:
        raise PlanError(f"asset {model.name!r}: link(s) {', '.join(orphans)} are not connected by a joint")
    reached, frontier = {model.links[0].name}, [model.links[0].name]
    while frontier:
        parent = frontier.pop()
        for j in model.joints:
            if j.parent == parent and j.child not in reached:
                reached.add(j.child)
                frontier.append(j.child)
    cut = sorted({lk.name for lk in model.links} - reached)
    if cut:
        raise PlanError(f"asset {model.name!r}: link(s) {', '.join(cut)} are not reachable from the root link "
                        "(cyclic joints)")
